#include "server/log.hpp"

#include <cmath>
#include <memory>
#include <string>

#include "fmt/format.h"
#include "protocol/text.hpp"
#include "spdlog/pattern_formatter.h"
#include "spdlog/sinks/stdout_color_sinks.h"
#include "spdlog/spdlog.h"

namespace mtlod::server {
namespace {

LogFormat g_format = LogFormat::kText;

// text as the body of a JSON string: protocol::printable leaves valid UTF-8 without control
// characters, so only quotes and backslashes need escaping.
void append_json_string(std::string_view text, spdlog::memory_buf_t& out) {
  const std::string safe = protocol::printable(text);
  for (const char c : safe) {
    if (c == '"' || c == '\\') out.push_back('\\');
    out.push_back(c);
  }
}

// %* in a pattern: the message as the body of a JSON string.
class JsonMessage final : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg& msg, const std::tm&, spdlog::memory_buf_t& dest) override {
    append_json_string(std::string_view(msg.payload.data(), msg.payload.size()), dest);
  }
  std::unique_ptr<custom_flag_formatter> clone() const override { return std::make_unique<JsonMessage>(); }
};

// %& in a pattern: the message as it is (JSON members the caller wrote).
class RawMembers final : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg& msg, const std::tm&, spdlog::memory_buf_t& dest) override {
    dest.append(msg.payload.data(), msg.payload.data() + msg.payload.size());
  }
  std::unique_ptr<custom_flag_formatter> clone() const override { return std::make_unique<RawMembers>(); }
};

constexpr const char* kTextPattern = "%Y-%m-%dT%H:%M:%S.%e %^%l%$ %v";
constexpr const char* kJsonTime = R"({"time":"%Y-%m-%dT%H:%M:%S.%e","level":"%l",)";

// Members of the extraction lines go through their own logger, whose pattern does not wrap them in
// "msg". spdlog keeps a formatter per sink, so it has a sink of its own; console sinks share one
// lock, so lines of the two loggers never interleave.
std::shared_ptr<spdlog::logger> g_events;

}  // namespace

bool parse_log_format(std::string_view name, LogFormat& format) {
  if (name == "text")
    format = LogFormat::kText;
  else if (name == "json")
    format = LogFormat::kJson;
  else
    return false;
  return true;
}

void setup_logging(LogFormat format) {
  g_format = format;
  auto main = spdlog::default_logger();
  g_events =
      std::make_shared<spdlog::logger>("events", std::make_shared<spdlog::sinks::stdout_color_sink_mt>());
  g_events->set_level(main->level());
  if (format == LogFormat::kText) {
    spdlog::set_pattern(kTextPattern);
    g_events->set_pattern(kTextPattern);
    return;
  }
  auto plain = std::make_unique<spdlog::pattern_formatter>();
  plain->add_flag<JsonMessage>('*').set_pattern(std::string(kJsonTime) + R"("msg":"%*"})");
  main->set_formatter(std::move(plain));
  auto members = std::make_unique<spdlog::pattern_formatter>();
  members->add_flag<RawMembers>('&').set_pattern(std::string(kJsonTime) + "%&}");
  g_events->set_formatter(std::move(members));
}

void log_extraction(std::uint64_t connection, std::uint64_t id, bool gaze, const protocol::MeshReply& reply) {
  if (!g_events || !g_events->should_log(spdlog::level::info)) return;
  const protocol::StageTimings& t = reply.timings;
  const char* type = gaze ? "gaze" : "extract";
  if (g_format == LogFormat::kText) {
    g_events->info(
        "conn={} id={} {} model={} triangles={} bytes={} max_error={:.4g} us: queue={} map={} occupancy={} "
        "dt={} labels={} refine={} encode={} total={}",
        connection, id, type, reply.model, reply.triangles, reply.bytes, reply.max_error, t.queue_us,
        t.map_us, t.occupancy_us, t.dt_us, t.labels_us, t.refine_us, t.encode_us, t.total_us);
    return;
  }
  spdlog::memory_buf_t model;
  append_json_string(reply.model, model);
  // JSON has no inf or NaN.
  const std::string max_error =
      std::isfinite(reply.max_error) ? fmt::format("{:.4g}", reply.max_error) : "null";
  g_events->info(
      R"("conn":{},"id":{},"type":"{}","model":"{}","triangles":{},"bytes":{},"max_error":{},)"
      R"("us":{{"queue":{},"map":{},"occupancy":{},"dt":{},"labels":{},"refine":{},"encode":{},"total":{}}})",
      connection, id, type, std::string_view(model.data(), model.size()), reply.triangles, reply.bytes,
      max_error, t.queue_us, t.map_us, t.occupancy_us, t.dt_us, t.labels_us, t.refine_us, t.encode_us,
      t.total_us);
}

}  // namespace mtlod::server

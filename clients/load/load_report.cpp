// mtlod-load's report (see load_report.hpp).
#include "clients/load/load_report.hpp"

#include <fstream>
#include <string>
#include <vector>

#include "fmt/format.h"
#include "nlohmann/json.hpp"

namespace mtlod::clients {
namespace {

double ms(std::uint64_t us) {
  return us / 1000.0;
}

nlohmann::ordered_json latency_json(const LatencyHistogram& h) {
  return {{"p50", ms(h.value_at_percentile(50))},
          {"p90", ms(h.value_at_percentile(90))},
          {"p99", ms(h.value_at_percentile(99))},
          {"p999", ms(h.value_at_percentile(99.9))},
          {"max", ms(h.max())},
          {"mean", h.mean() / 1000.0},
          {"min", ms(h.min())}};
}

// Means per mesh reply of the server's stages, and its total's percentiles.
nlohmann::ordered_json server_json(const LoadTotals& r) {
  const double mean_div = std::max<double>(1, static_cast<double>(r.ok));
  const auto& s = r.stage_sums;
  return {{"queue", s.queue_us / mean_div},
          {"map", s.map_us / mean_div},
          {"occupancy", s.occupancy_us / mean_div},
          {"dt", s.dt_us / mean_div},
          {"labels", s.labels_us / mean_div},
          {"refine", s.refine_us / mean_div},
          {"encode", s.encode_us / mean_div},
          {"total", s.total_us / mean_div},
          {"total_p50", r.server_total_us.value_at_percentile(50)},
          {"total_p99", r.server_total_us.value_at_percentile(99)}};
}

// Each scene: its file and its instance count.
nlohmann::ordered_json scenes_json(const LoadOptions& o) {
  nlohmann::ordered_json scenes = nlohmann::ordered_json::array();
  for (std::size_t i = 0; i < o.scene_files.size(); ++i)
    scenes.push_back({{"file", o.scene_files[i]}, {"instances", o.scenes[i].size()}});
  return scenes;
}

// "models bunny,dragon", "scenes a.json (3 instances), b.json (10 instances)", or both.
std::string describe_views(const LoadOptions& o) {
  std::vector<std::string> parts, scenes;
  if (!o.models.empty()) parts.push_back(fmt::format("models {}", fmt::join(o.models, ",")));
  for (std::size_t i = 0; i < o.scene_files.size(); ++i)
    scenes.push_back(fmt::format("{} ({} instances)", o.scene_files[i], o.scenes[i].size()));
  if (!scenes.empty()) parts.push_back(fmt::format("scenes {}", fmt::join(scenes, ", ")));
  return fmt::format("{}", fmt::join(parts, ", "));
}

nlohmann::ordered_json report_json(const LoadOptions& o, const clients::ExtractFlags& flags,
                                   const LoadTotals& r, const LoadRunEnd& end) {
  const double elapsed_s = end.elapsed_s;
  const double mean_div = std::max<double>(1, static_cast<double>(r.ok));
  nlohmann::ordered_json report = {
      {"mode", o.open_loop() ? "open" : "closed"},
      {"models", o.models},
      {"scenes", scenes_json(o)},
      {"connections", o.connections},
      {"rate_rps", o.rate},
      {"mix", o.mix},
      {"budget", flags.budget ? nlohmann::json(*flags.budget) : nlohmann::json(nullptr)},
      {"duration_s", o.duration_s},
      {"elapsed_s", elapsed_s},
      {"sent", r.sent},
      {"requests", r.ok + r.errors + r.superseded},
      {"ok", r.ok},
      {"errors", r.errors},
      {"superseded", r.superseded},
      {"errors_by_code", r.errors_by_code},
      {"unsent", end.unsent},
      {"lost", end.lost},
      {"reconnects", end.reconnects},
      {"retried", end.retried},
      {"gave_up", end.gave_up},
      {"throughput_rps", r.ok / std::max(elapsed_s, 1e-9)},
      {"latency_ms", latency_json(r.latency_us)},
      {"bytes", r.bytes},
      {"bytes_per_s", r.bytes / std::max(elapsed_s, 1e-9)},
      {"mean_triangles", r.triangles / mean_div},
      {"server_us", server_json(r)},
      {"decode", o.decode ? nlohmann::ordered_json{{"payloads", r.decoded},
                                                   {"errors", r.decode_errors},
                                                   {"first_error", r.first_decode_error},
                                                   {"ms", latency_json(r.decode_us)}}
                          : nlohmann::ordered_json(nullptr)},
  };
  nlohmann::ordered_json instances = nlohmann::ordered_json::object();
  for (const auto& [name, i] : r.instances) {
    instances[name] = {{"ok", i.ok}, {"first_reply_s", i.first_ns / 1e9}, {"last_reply_s", i.last_ns / 1e9}};
  }
  report["instances"] = std::move(instances);
  return report;
}

void print_report(const LoadOptions& o, const LoadTotals& r, const LoadRunEnd& end) {
  const double elapsed_s = end.elapsed_s;
  const double throughput = r.ok / std::max(elapsed_s, 1e-9);
  const double mean_div = std::max<double>(1, static_cast<double>(r.ok));
  fmt::print("{} loop, {} connection(s), {}, {:.1f} s{}\n", o.open_loop() ? "open" : "closed", o.connections,
             describe_views(o), elapsed_s,
             o.open_loop() ? fmt::format(", {:.0f} requests/s offered", o.rate) : "");
  fmt::print("  requests  sent {}  mesh {}  errors {}  superseded {}  unsent {}  lost {}\n", r.sent, r.ok,
             r.errors, r.superseded, end.unsent, end.lost);
  for (const auto& [code, n] : r.errors_by_code) fmt::print("    {:<20} {}\n", code, n);
  if (end.reconnects || end.gave_up) {
    fmt::print("  reconnects {}, requests sent again {}, streams that gave up {}\n", end.reconnects,
               end.retried, end.gave_up);
  }
  if (r.instances.size() > 1) {
    for (const auto& [name, i] : r.instances) {
      fmt::print("    {:<28} {:>8} meshes  {:.1f}..{:.1f} s\n", name, i.ok, i.first_ns / 1e9,
                 i.last_ns / 1e9);
    }
  }
  fmt::print("  throughput {:.1f} meshes/s, {:.2f} MB/s, {:.0f} triangles and {:.0f} bytes per mesh\n",
             throughput, r.bytes / std::max(elapsed_s, 1e-9) / 1e6, r.triangles / mean_div,
             r.bytes / mean_div);
  const auto& h = r.latency_us;
  fmt::print("  latency ms  p50 {:.2f}  p90 {:.2f}  p99 {:.2f}  p99.9 {:.2f}  max {:.2f}  mean {:.2f}\n",
             ms(h.value_at_percentile(50)), ms(h.value_at_percentile(90)), ms(h.value_at_percentile(99)),
             ms(h.value_at_percentile(99.9)), ms(h.max()), h.mean() / 1000.0);
  const auto& s = r.stage_sums;
  fmt::print(
      "  server µs (mean)  queue {:.0f}  map {:.0f}  occupancy {:.0f}  dt {:.0f}  labels {:.0f}  refine "
      "{:.0f}  "
      "encode {:.0f}  total {:.0f}\n",
      s.queue_us / mean_div, s.map_us / mean_div, s.occupancy_us / mean_div, s.dt_us / mean_div,
      s.labels_us / mean_div, s.refine_us / mean_div, s.encode_us / mean_div, s.total_us / mean_div);
  if (o.decode) {
    const auto& d = r.decode_us;
    fmt::print("  decoded {} payloads, {} failed; client decode ms  p50 {:.2f}  p99 {:.2f}  max {:.2f}\n",
               r.decoded, r.decode_errors, ms(d.value_at_percentile(50)), ms(d.value_at_percentile(99)),
               ms(d.max()));
  }
  if (r.decode_errors) fmt::print(stderr, "mtlod-load: a payload did not decode: {}\n", r.first_decode_error);
}

}  // namespace

Status report_load(const LoadOptions& options, const clients::ExtractFlags& flags, const LoadTotals& totals,
                   const LoadRunEnd& end) {
  const nlohmann::ordered_json report = report_json(options, flags, totals, end);
  print_report(options, totals, end);
  if (options.json_file.empty()) return Ok{};
  std::ofstream out(options.json_file);
  out << report.dump(2) << "\n";
  if (!out) return make_error(ErrorCode::kIoError, fmt::format("{}: write failed", options.json_file));
  return Ok{};
}

}  // namespace mtlod::clients

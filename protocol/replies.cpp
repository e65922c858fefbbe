// Reply serialisation and the clients' lenient reply parser (PROTOCOL.md, "Replies").
#include "protocol/replies.hpp"

#include <algorithm>
#include <array>
#include <string_view>
#include <type_traits>
#include <utility>
#include <variant>

#include "fmt/format.h"
#include "nlohmann/json.hpp"
#include "protocol/frame.hpp"

namespace mtlod::protocol {
namespace {

using nlohmann::json;

// A reply's `codec`; absent from servers that had one codec: Draco.
core::codec::Codec codec_from(const json& j) {
  return enum_from_name<core::codec::Codec>(kCodecNames, j.value("codec", std::string("draco")))
      .value_or(core::codec::Codec::kDraco);
}

json limits_json(const Limits& l) {
  return {{"max_frame_bytes", l.max_frame_bytes},
          {"max_connections", l.max_connections},
          {"max_in_flight", l.max_in_flight},
          {"max_grid", l.max_grid},
          {"max_budget", l.max_budget},
          {"max_foci", l.max_foci},
          {"max_instances", l.max_instances},
          {"idle_timeout_ms", l.idle_timeout_ms},
          {"read_timeout_ms", l.read_timeout_ms},
          {"first_frame_timeout_ms", l.first_frame_timeout_ms},
          {"max_connections_per_address", l.max_connections_per_address},
          {"max_memory_bytes", l.max_memory_bytes}};
}

Limits limits_from(const json& j) {
  Limits l;
  l.max_frame_bytes = j.value("max_frame_bytes", l.max_frame_bytes);
  l.max_connections = j.value("max_connections", l.max_connections);
  l.max_in_flight = j.value("max_in_flight", l.max_in_flight);
  l.max_grid = j.value("max_grid", l.max_grid);
  l.max_budget = j.value("max_budget", l.max_budget);
  l.max_foci = j.value("max_foci", l.max_foci);
  l.max_instances = j.value("max_instances", l.max_instances);
  l.idle_timeout_ms = j.value("idle_timeout_ms", l.idle_timeout_ms);
  l.read_timeout_ms = j.value("read_timeout_ms", l.read_timeout_ms);
  l.first_frame_timeout_ms = j.value("first_frame_timeout_ms", l.first_frame_timeout_ms);
  l.max_connections_per_address = j.value("max_connections_per_address", l.max_connections_per_address);
  l.max_memory_bytes = j.value("max_memory_bytes", l.max_memory_bytes);
  return l;
}

json summary_json(const ModelSummary& m) {
  return {{"name", m.name},
          {"vertices", m.vertices},
          {"input_triangles", m.input_triangles},
          {"root_triangles", m.root_triangles},
          {"nodes", m.nodes},
          {"memory_bytes", m.memory_bytes},
          {"max_error", m.max_error},
          {"version", m.version}};
}

ModelSummary summary_from(const json& j) {
  ModelSummary m;
  m.name = j.value("name", "");
  m.vertices = j.value("vertices", std::uint64_t{0});
  m.input_triangles = j.value("input_triangles", std::uint64_t{0});
  m.root_triangles = j.value("root_triangles", std::uint64_t{0});
  m.nodes = j.value("nodes", std::uint64_t{0});
  m.memory_bytes = j.value("memory_bytes", std::uint64_t{0});
  m.max_error = j.value("max_error", 0.0);
  m.version = j.value("version", std::uint64_t{1});
  return m;
}

json timings_json(const StageTimings& t) {
  return {{"queue", t.queue_us},   {"map", t.map_us},       {"occupancy", t.occupancy_us},
          {"dt", t.dt_us},         {"labels", t.labels_us}, {"refine", t.refine_us},
          {"encode", t.encode_us}, {"total", t.total_us}};
}

StageTimings timings_from(const json& j) {
  StageTimings t;
  t.queue_us = j.value("queue", std::uint64_t{0});
  t.map_us = j.value("map", std::uint64_t{0});
  t.occupancy_us = j.value("occupancy", std::uint64_t{0});
  t.dt_us = j.value("dt", std::uint64_t{0});
  t.labels_us = j.value("labels", std::uint64_t{0});
  t.refine_us = j.value("refine", std::uint64_t{0});
  t.encode_us = j.value("encode", std::uint64_t{0});
  t.total_us = j.value("total", std::uint64_t{0});
  return t;
}

ErrorKind error_kind_from(const std::string& code) {
  for (int k = 0; k <= static_cast<int>(ErrorKind::kInternal); ++k) {
    if (code == to_string(static_cast<ErrorKind>(k))) return static_cast<ErrorKind>(k);
  }
  return ErrorKind::kInternal;
}

}  // namespace

const char* reply_type_name(const Reply& reply) {
  return kReplyTypeNames[reply.index()];
}

namespace {

// One writer and one reader per reply type, found by overload: to_json visits the writers and
// parse_reply's table is built from the variant's alternatives, so a reply type without either
// does not compile.
json write(const HelloReply& r) {
  return {{"version", r.version},
          {"server", r.server},
          {"limits", limits_json(r.limits)},
          {"instance", r.instance},
          {"auth_required", r.auth_required},
          {"codec", enum_name(kCodecNames, r.codec)}};
}
HelloReply read(std::type_identity<HelloReply>, const json& j) {
  return HelloReply{j.value("version", 0),
                    j.value("server", ""),
                    limits_from(j.value("limits", json::object())),
                    j.value("instance", ""),
                    j.value("auth_required", false),
                    codec_from(j)};
}

json write(const ModelsReply& r) {
  json models = json::array();
  for (const ModelSummary& m : r.models) models.push_back(summary_json(m));
  return {{"models", models}};
}
ModelsReply read(std::type_identity<ModelsReply>, const json& j) {
  ModelsReply r;
  for (const json& m : j.value("models", json::array())) r.models.push_back(summary_from(m));
  return r;
}

json write(const ModelInfoReply& r) {
  json m = summary_json(r.model);
  m["bounds_min"] = r.bounds_min;
  m["bounds_max"] = r.bounds_max;
  m["min_error"] = r.min_error;
  m["normals"] = r.normals;
  m["colors"] = r.colors;
  return m;
}
ModelInfoReply read(std::type_identity<ModelInfoReply>, const json& j) {
  ModelInfoReply r;
  r.model = summary_from(j);
  r.bounds_min = j.value("bounds_min", r.bounds_min);
  r.bounds_max = j.value("bounds_max", r.bounds_max);
  r.min_error = j.value("min_error", 0.0);
  r.normals = j.value("normals", false);
  r.colors = j.value("colors", false);
  return r;
}

json delta_json(const MeshDelta& d) {
  return {{"reset", d.reset},
          {"payload_bytes", d.payload_bytes},
          // The name of protocol version 1's first servers, when Draco was the only codec: kept for
          // their clients.
          {"draco_bytes", d.payload_bytes},
          {"added", d.added},
          {"removed", d.removed}};
}
MeshDelta delta_from(const json& d) {
  return MeshDelta{d.value("reset", false),
                   d.value("payload_bytes", d.value("draco_bytes", std::uint64_t{0})),
                   d.value("added", std::uint64_t{0}), d.value("removed", std::uint64_t{0})};
}

// The counts a mesh reply and each of a scene's instances share (MeshReply, InstanceMesh), and
// their delta.
template <class Mesh>
json mesh_json(const Mesh& r) {
  json m = {{"model", r.model},
            {"triangles", r.triangles},
            {"vertices", r.vertices},
            {"max_error", r.max_error},
            {"bytes", r.bytes}};
  if (r.delta) m["delta"] = delta_json(*r.delta);
  return m;
}
template <class Mesh>
void read_mesh(const json& j, Mesh& r) {
  r.model = j.value("model", "");
  r.triangles = j.value("triangles", std::uint64_t{0});
  r.vertices = j.value("vertices", std::uint64_t{0});
  r.max_error = j.value("max_error", 0.0);
  r.bytes = j.value("bytes", std::uint64_t{0});
  if (j.contains("delta")) r.delta = delta_from(j["delta"]);
}

json write(const MeshReply& r) {
  json m = mesh_json(r);
  m["codec"] = enum_name(kCodecNames, r.codec);
  m["superseded"] = r.superseded;
  m["timings_us"] = timings_json(r.timings);
  m["memory"] = {{"session_bytes", r.session_bytes}, {"scratch_bytes", r.scratch_bytes}};
  if (r.focus) m["focus"] = *r.focus;
  m["model_version"] = r.model_version;
  if (r.model_changed) m["model_changed"] = true;
  if (!r.instances.empty()) {
    json instances = json::array();
    for (const InstanceMesh& i : r.instances) instances.push_back(mesh_json(i));
    m["instances"] = std::move(instances);
    m["within_budget"] = r.within_budget;
  }
  return m;
}
MeshReply read(std::type_identity<MeshReply>, const json& j) {
  MeshReply r;
  read_mesh(j, r);
  r.codec = codec_from(j);
  r.superseded = j.value("superseded", std::uint64_t{0});
  const json memory = j.value("memory", json::object());
  r.session_bytes = memory.value("session_bytes", std::uint64_t{0});
  r.scratch_bytes = memory.value("scratch_bytes", std::uint64_t{0});
  if (j.contains("focus")) r.focus = j["focus"].get<std::array<double, 2>>();
  r.model_version = j.value("model_version", std::uint64_t{0});
  r.model_changed = j.value("model_changed", false);
  for (const json& i : j.value("instances", json::array())) read_mesh(i, r.instances.emplace_back());
  r.within_budget = j.value("within_budget", true);
  r.timings = timings_from(j.value("timings_us", json::object()));
  return r;
}

json write(const ErrorReply& r) {
  return {{"code", to_string(r.code)}, {"message", r.message}};
}
ErrorReply read(std::type_identity<ErrorReply>, const json& j) {
  return ErrorReply{error_kind_from(j.value("code", "")), j.value("message", "")};
}

json write(const CancelReply& r) {
  return {{"target", r.target}, {"cancelled", r.cancelled}};
}
CancelReply read(std::type_identity<CancelReply>, const json& j) {
  return CancelReply{j.value("target", std::uint64_t{0}), j.value("cancelled", false)};
}

json write(const StatsReply& r) {
  json counters = json::object();
  for (const auto& [name, value] : r.counters) counters[name] = value;
  return {{"counters", counters}};
}
StatsReply read(std::type_identity<StatsReply>, const json& j) {
  StatsReply r;
  const json counters = j.value("counters", json::object());  // items() must not outlive it
  for (const auto& [name, value] : counters.items())
    r.counters.emplace_back(name, value.is_number() ? value.get<double>() : 0.0);
  return r;
}

json write(const Pong&) {
  return json::object();
}
Pong read(std::type_identity<Pong>, const json&) {
  return {};
}

json write(const ReloadReply& r) {
  json models = json::array();
  for (const ModelReload& m : r.models) {
    json entry = {{"name", m.name}, {"change", m.change}, {"version", m.version}};
    if (!m.message.empty()) entry["message"] = m.message;
    models.push_back(std::move(entry));
  }
  return {{"models", models}};
}
ReloadReply read(std::type_identity<ReloadReply>, const json& j) {
  ReloadReply r;
  for (const json& m : j.value("models", json::array())) {
    r.models.push_back(ModelReload{m.value("name", ""), m.value("change", ""),
                                   m.value("version", std::uint64_t{0}), m.value("message", "")});
  }
  return r;
}

}  // namespace

std::string to_json(const Reply& reply, std::optional<std::uint64_t> id) {
  json j = std::visit([](const auto& r) { return write(r); }, reply);
  j["type"] = reply_type_name(reply);
  if (id) j["id"] = *id;
  // Replace, never throw: a reply may quote client bytes, and a throw here would escape the server.
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

Result<ParsedReply> parse_reply(std::string_view text) {
  using Reader = Reply (*)(const json&);
  static constexpr auto kReaders = []<std::size_t... I>(std::index_sequence<I...>) {
    return std::array<Reader, sizeof...(I)>{+[](const json& j) -> Reply {
      return read(std::type_identity<std::variant_alternative_t<I, Reply>>{}, j);
    }...};
  }
  (std::make_index_sequence<std::variant_size_v<Reply>>{});
  try {
    const json j = json::parse(text.begin(), text.end());
    ParsedReply out{std::nullopt, Pong{}};
    if (j.contains("id") && j["id"].is_number_unsigned()) out.id = j["id"].get<std::uint64_t>();
    const std::string type = j.value("type", "");
    const auto* name = std::find(kReplyTypeNames.begin(), kReplyTypeNames.end(), std::string_view(type));
    if (name == kReplyTypeNames.end())
      return make_error(ErrorCode::kCorrupt, fmt::format("unknown reply type '{}'", type));
    out.reply = kReaders[static_cast<std::size_t>(name - kReplyTypeNames.begin())](j);
    return out;
  } catch (const json::exception& e) {
    return make_error(ErrorCode::kCorrupt, fmt::format("reply does not parse: {}", e.what()));
  }
}

Result<DeltaPayload> split_delta_payload(const MeshDelta& delta, std::span<const std::uint8_t> payload) {
  // Counts come from the network: check them against the payload before any multiplication.
  const std::uint64_t size = payload.size();
  if (delta.payload_bytes > size || delta.added > size / 4 || delta.removed > size / 4 ||
      delta.payload_bytes + 4 * (delta.added + delta.removed) != size) {
    return make_error(
        ErrorCode::kInvalidArgument,
        fmt::format("delta payload of {} bytes does not hold a {}-byte mesh, {} added and {} removed ids",
                    size, delta.payload_bytes, delta.added, delta.removed));
  }
  if ((delta.added == 0) != (delta.payload_bytes == 0)) {
    return make_error(ErrorCode::kInvalidArgument, fmt::format("delta with {} added ids has a {}-byte mesh",
                                                               delta.added, delta.payload_bytes));
  }
  DeltaPayload out;
  out.mesh = payload.first(static_cast<std::size_t>(delta.payload_bytes));
  auto read_ids = [&](std::size_t offset, std::uint64_t count, std::vector<std::uint32_t>& ids) {
    ids.resize(static_cast<std::size_t>(count));
    for (std::size_t i = 0; i < ids.size(); ++i) ids[i] = read_u32_le(payload.data() + offset + 4 * i);
  };
  read_ids(static_cast<std::size_t>(delta.payload_bytes), delta.added, out.added_ids);
  read_ids(static_cast<std::size_t>(delta.payload_bytes + 4 * delta.added), delta.removed, out.removed_ids);
  return out;
}

Result<std::vector<std::span<const std::uint8_t>>> split_scene_payload(
    const MeshReply& reply, std::span<const std::uint8_t> payload) {
  std::vector<std::span<const std::uint8_t>> parts;
  std::uint64_t at = 0;
  for (const InstanceMesh& instance : reply.instances) {
    if (instance.bytes > payload.size() - at) break;
    parts.push_back(payload.subspan(static_cast<std::size_t>(at), static_cast<std::size_t>(instance.bytes)));
    at += instance.bytes;
  }
  if (parts.size() != reply.instances.size() || at != payload.size()) {
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("scene payload of {} bytes does not hold its {} instances' parts",
                                  payload.size(), reply.instances.size()));
  }
  return parts;
}

void append_delta_ids(std::span<const std::uint32_t> added_ids, std::span<const std::uint32_t> removed_ids,
                      std::vector<std::uint8_t>& payload) {
  std::size_t at = payload.size();
  payload.resize(at + 4 * (added_ids.size() + removed_ids.size()));
  for (const auto ids : {added_ids, removed_ids}) {
    for (const std::uint32_t id : ids) {
      write_u32_le(id, &payload[at]);
      at += 4;
    }
  }
}

}  // namespace mtlod::protocol

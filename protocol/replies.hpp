// Server replies (PROTOCOL.md, "Replies"): structs, JSON for the server to send, and a parser for
// clients. Clients read replies leniently (unknown fields are ignored) so that a newer server with
// extra fields still talks to an older client.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "core/result.hpp"
#include "protocol/errors.hpp"
#include "protocol/messages.hpp"

namespace mtlod::protocol {

struct HelloReply {
  int version = kProtocolVersion;
  std::string server;
  Limits limits;
  // Which server process answered: "<name>@<random hex>", new at every start, so a client behind a
  // load balancer can tell replicas, and a restarted replica from its previous run, apart.
  std::string instance;
  // The server wants an access token in hello (mtlod-server --auth-tokens).
  bool auth_required = false;
  core::codec::Codec codec = core::codec::Codec::kDraco;  // the connection's, for extracts naming none
};

struct ModelSummary {
  std::string name;
  std::uint64_t vertices = 0;
  std::uint64_t input_triangles = 0;  // the full-resolution mesh
  std::uint64_t root_triangles = 0;   // the coarsest mesh
  std::uint64_t nodes = 0;
  std::uint64_t memory_bytes = 0;  // resident size of the loaded model
  double max_error = 0;            // model units
  std::uint64_t version = 1;       // of this model's file in this server process, from 1
};

struct ModelsReply {
  std::vector<ModelSummary> models;
};

struct ModelInfoReply {
  ModelSummary model;
  std::array<double, 3> bounds_min{};
  std::array<double, 3> bounds_max{};
  double min_error = 0;  // smallest non-zero triangle error, model units
  bool normals = false;
  bool colors = false;
};

// Microseconds spent per stage of one extraction.
struct StageTimings {
  std::uint64_t queue_us = 0;      // waiting for a worker
  std::uint64_t map_us = 0;        // vertices to grid cells
  std::uint64_t occupancy_us = 0;  // rasterising the occupancy grid
  std::uint64_t dt_us = 0;         // distance transform(s)
  std::uint64_t labels_us = 0;     // labels and allowed errors
  std::uint64_t refine_us = 0;     // selective refinement of the MT
  std::uint64_t encode_us = 0;     // Draco
  std::uint64_t total_us = 0;      // from frame received to reply ready
};

// A delta reply (PROTOCOL.md, "Delta replies"): the payload holds the mesh of the triangles new to
// the client in the reply's codec (payload_bytes), then their MT triangle ids in the mesh's face
// order, then the ids the client drops: 32-bit little-endian each.
struct MeshDelta {
  bool reset = false;               // the client clears its mesh first (the first delta, or another model)
  std::uint64_t payload_bytes = 0;  // the mesh part
  std::uint64_t added = 0;
  std::uint64_t removed = 0;
};

// A delta payload cut into its parts. Fails when the sizes do not add up to the payload's.
struct DeltaPayload {
  std::span<const std::uint8_t> mesh;  // empty when nothing was added
  std::vector<std::uint32_t> added_ids;
  std::vector<std::uint32_t> removed_ids;
};
Result<DeltaPayload> split_delta_payload(const MeshDelta& delta, std::span<const std::uint8_t> payload);
// The server's side: appends the ids to a payload holding the mesh part.
void append_delta_ids(std::span<const std::uint32_t> added_ids, std::span<const std::uint32_t> removed_ids,
                      std::vector<std::uint8_t>& payload);

// One instance's mesh in a scene's reply (PROTOCOL.md, "Scenes"): the fields of a single model's,
// for its part of the payload.
struct InstanceMesh {
  std::string model;
  std::uint64_t triangles = 0;
  std::uint64_t vertices = 0;
  double max_error = 0;     // model units
  std::uint64_t bytes = 0;  // this instance's part of the payload
  std::optional<MeshDelta> delta;
};

// Header of an extract or gaze result; the encoded mesh follows as the frame's payload.
struct MeshReply {
  std::string model;
  std::uint64_t triangles = 0;
  std::uint64_t vertices = 0;
  double max_error = 0;     // largest error of a triangle in the cut, model units
  std::uint64_t bytes = 0;  // payload size
  core::codec::Codec codec = core::codec::Codec::kDraco;  // of the payload (of its mesh part, for a delta)
  std::optional<std::array<double, 2>> focus;             // the focus this mesh reflects (gaze replies)
  std::uint64_t superseded = 0;                           // gaze updates replaced by this one before they ran
  std::uint64_t session_bytes = 0;                        // memory the connection's cut holds on the server
  std::uint64_t scratch_bytes = 0;  // memory the worker that ran it holds for this model
  StageTimings timings;
  std::optional<MeshDelta> delta;   // set when the extract asked for delta replies
  std::uint64_t model_version = 0;  // the version of the model this cut was taken from
  // The model's file changed since this connection's previous cut: this cut starts afresh from the
  // new version (a delta reply then resets the client's mesh).
  bool model_changed = false;
  // A scene's meshes, one per instance in the request's order; the payload is their parts one after
  // the other (split_scene_payload). triangles, vertices and bytes are then the sums, max_error the
  // largest, model empty.
  std::vector<InstanceMesh> instances;
  bool within_budget = true;  // false when even the coarsest meshes exceed the request's budget
};

// A scene reply's payload cut into the instances' parts. Fails when the sizes do not add up.
Result<std::vector<std::span<const std::uint8_t>>> split_scene_payload(const MeshReply& reply,
                                                                       std::span<const std::uint8_t> payload);

struct ErrorReply {
  ErrorKind code = ErrorKind::kInternal;
  std::string message;
};

struct CancelReply {
  std::uint64_t target = 0;
  bool cancelled = false;  // false: it had already started or finished
};

struct StatsReply {
  std::vector<std::pair<std::string, double>> counters;  // name → value, in the server's order
};

struct Pong {};

// What a reload did to one model.
struct ModelReload {
  std::string name;
  std::string change;         // "loaded", "replaced", "removed", "unchanged", "failed" or "pending"
  std::uint64_t version = 0;  // the version served afterwards (0: none)
  std::string message;        // why, for "failed" and "pending"
};
struct ReloadReply {
  std::vector<ModelReload> models;
};

using Reply = std::variant<HelloReply, ModelsReply, ModelInfoReply, MeshReply, ErrorReply, CancelReply,
                           StatsReply, Pong, ReloadReply>;

// The reply types' names on the wire, in the variant's order.
inline constexpr std::array<const char*, 9> kReplyTypeNames{
    "hello", "models", "model_info", "mesh", "error", "cancel", "stats", "pong", "reloaded"};
static_assert(kReplyTypeNames.size() == std::variant_size_v<Reply>);

// The JSON header of a reply; `id` is the request's id (absent only when the request had none).
std::string to_json(const Reply& reply, std::optional<std::uint64_t> id);

struct ParsedReply {
  std::optional<std::uint64_t> id;
  Reply reply;
};

// For clients: errors are kCorrupt with the reason.
Result<ParsedReply> parse_reply(std::string_view json);

// The reply type's name on the wire ("mesh", "error", ...).
const char* reply_type_name(const Reply& reply);

}  // namespace mtlod::protocol

// The messages of the mtlod protocol as plain structs (PROTOCOL.md, "Messages"). Requests are what
// a client sends; replies are what the server answers. Units are in the field names.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "core/codec/cut_encoder.hpp"
#include "core/codec/draco_encode.hpp"
#include "core/view/criteria.hpp"
#include "core/view/distance_transform.hpp"

namespace mtlod::protocol {

inline constexpr int kProtocolVersion = 1;

// Limits a server enforces and states in its hello reply.
struct Limits {
  std::uint32_t max_frame_bytes = 1u << 20;  // JSON + payload of one client frame
  std::uint32_t max_connections = 256;
  std::uint32_t max_in_flight = 8;                 // extractions queued or running per connection
  std::uint32_t max_grid = 4096;                   // grid width and height
  std::uint32_t max_budget = 5'000'000;            // triangles per extraction
  std::uint32_t max_foci = 16;                     // focus points plus neglect regions
  std::uint32_t max_instances = 1024;              // model instances per scene
  std::uint32_t idle_timeout_ms = 300'000;         // a connection with no request for this long is closed
  std::uint32_t read_timeout_ms = 10'000;          // a frame started must arrive within this time
  std::uint32_t first_frame_timeout_ms = 5'000;    // a new connection's first frame must arrive by then
  std::uint32_t max_connections_per_address = 64;  // connections one client address may hold (0: no cap)
  // Worker scratch plus sessions; 0 when not stated (the server then derives it from the machine).
  std::uint64_t max_memory_bytes = 0;
};

using Matrix4 = std::array<double, 16>;  // column-major, as OpenGL and GLM store them

// The names on the wire of the core enumerations a request chooses from, in enumerator order: adding
// an enumerator in core fails these assertions until its name is added here.
inline constexpr std::array<const char*, 2> kErrorUnitNames{"model", "pixels"};
static_assert(kErrorUnitNames.size() == core::view::kErrorUnitsCount);
inline constexpr std::array<const char*, 4> kFalloffNames{"step", "linear", "smoothstep", "foveal"};
static_assert(kFalloffNames.size() == core::view::kFalloffLawCount);
inline constexpr std::array<const char*, 5> kDistanceMetricNames{"chamfer-5-7-11", "chamfer-3-4",
                                                                 "city-block", "chessboard", "euclidean"};
static_assert(kDistanceMetricNames.size() == core::view::kDistanceMetricCount);
inline constexpr std::array<const char*, 2> kCodecNames{"draco", "meshopt"};
static_assert(kCodecNames.size() == core::codec::kCodecCount);
inline constexpr std::array<const char*, 2> kDracoMethodNames{"edgebreaker", "sequential"};
static_assert(kDracoMethodNames.size() == core::codec::kDracoMethodCount);
// The unit of a request's distance thresholds exists on the wire only: core works in pixels.
enum class DistanceUnit : std::uint8_t { kPixels, kChamfer };
inline constexpr std::array<const char*, 2> kDistanceUnitNames{"pixels", "chamfer"};

// The enumerator named `name` in `names`, or nullopt.
template <class Enum, std::size_t N>
std::optional<Enum> enum_from_name(const std::array<const char*, N>& names, std::string_view name) {
  for (std::size_t i = 0; i < N; ++i) {
    if (name == names[i]) return static_cast<Enum>(i);
  }
  return std::nullopt;
}
template <class Enum, std::size_t N>
const char* enum_name(const std::array<const char*, N>& names, Enum value) {
  return names[static_cast<std::size_t>(value)];
}

// A point in normalised viewport coordinates (0,0 top left, 1,1 bottom right).
struct Point {
  double x = 0.5;
  double y = 0.5;
  bool operator==(const Point&) const = default;
};

// One criterion in use: allowed error e·f within `distance` of its seeds.
struct Region {
  double distance = 0;        // threshold d, in `Criteria::units`
  double factor = 0;          // f (< 1 refines, > 1 coarsens)
  std::vector<Point> points;  // the seeds of a point-seeded criterion (core::view::Seeds::kPoints)
  bool operator==(const Region&) const = default;
};

// A criterion on the wire: its key in `criteria`, what its distance is measured to (PROTOCOL.md's
// table), the defaults of `distance` and `factor`, and the factor's range. One entry per
// core::view::Criterion, in its order.
struct CriterionWire {
  const char* name;
  const char* measured_to;
  double distance;
  double factor;
  double factor_min;
  double factor_max;
};
inline constexpr std::array<CriterionWire, 4> kCriterionWire{{
    {"silhouette", "the model's outline", 2, 0, 0, 1},
    {"focus", "the focus points", 20, 0.25, 0, 1},
    {"neglect", "the regions of neglect", 50, 4, 1, 1e6},
    {"screen_edge", "the screen's edge", 32, 2, 1, 1e6},
}};
static_assert(kCriterionWire.size() == core::view::kCriterionCount);

constexpr const CriterionWire& wire(core::view::Criterion c) {
  return kCriterionWire[static_cast<std::size_t>(c)];
}
// A criterion with its defaults and no points.
inline Region default_region(core::view::Criterion c) {
  return Region{wire(c).distance, wire(c).factor, {}};
}

struct Criteria {
  core::view::PerCriterion<std::optional<Region>> regions;  // unset: the criterion is off
  core::view::FalloffLaw falloff = core::view::FalloffLaw::kStep;
  core::view::DistanceMetric distance = core::view::DistanceMetric::kChamfer5711;
  DistanceUnit units = DistanceUnit::kPixels;
  bool internal_silhouettes = false;  // depth discontinuities seed the silhouette distance too
  double frustum_factor = 8;          // allowed error multiplier outside the view (1 = off)
  double backface_factor = 1;         // allowed error multiplier for back faces (1 = off)
  double hidden_factor = 1;           // allowed error multiplier behind the visible surface (1 = off)
};

// The region a gaze moves (core::view::kGazeCriterion), made with its defaults and one point at the
// viewport's centre when the criteria have none: gazes, the gaze client and the load tester move
// its first point.
inline Region& gaze_region(Criteria& criteria) {
  std::optional<Region>& region = criteria.regions[core::view::kGazeCriterion];
  if (!region) region = default_region(core::view::kGazeCriterion);
  if (region->points.empty()) region->points.emplace_back();
  return *region;
}

// How finely either codec stores positions (on a grid over the box) and normals (octahedral).
struct Quantization {
  int position_bits = 14;
  int normal_bits = 10;
};
struct DracoSettings {
  // Unset: edgebreaker for extract (smallest payload), sequential for gaze (lowest latency), the
  // defaults chosen from tests/bench/bench_pipeline (tests/bench/BENCHMARKS.md, "Draco").
  std::optional<core::codec::DracoMethod> method;
  int speed = 10;  // 0 best ratio .. 10 fastest; 10 is also no larger than 5-8 (bench_pipeline)
  // Unset: entropy-coded attributes for extract, raw quantized values for gaze (about 15 % more
  // bytes, half of Draco's encoding time at 50k triangles).
  std::optional<bool> entropy_coding;
};

struct Hello {
  int version = kProtocolVersion;
  std::string client;
  std::string token;  // access token (mtlod-server --auth-tokens); empty: none
  // The connection's codec for extracts that name none; unset: keep the connection's (Draco at first).
  std::optional<core::codec::Codec> codec;
};
struct ListModels {};
struct ModelInfo {
  std::string model;
};
// One placed model of a scene: `matrix` takes the model's coordinates to the world's (affine,
// invertible, finite).
struct Instance {
  std::string model;
  Matrix4 matrix{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  bool operator==(const Instance&) const = default;
};

struct Extract {
  std::string model;  // empty for a scene
  // A scene (PROTOCOL.md, "Scenes"): set instead of `model`. One camera, criteria and budget for the
  // whole picture; the reply carries one mesh per instance.
  std::vector<Instance> instances;
  // A scene the server loaded, by name ("scene": "room"): the server fills `instances` from it.
  std::string scene_name;
  Matrix4 view{};
  Matrix4 projection{};
  std::array<std::uint32_t, 2> viewport{800, 600};  // pixels
  std::array<std::uint32_t, 2> grid{256, 256};      // distance-transform cells
  double error = 0;                                 // the bound e
  core::view::ErrorUnits error_unit = core::view::ErrorUnits::kModel;
  Criteria criteria;
  std::optional<std::uint32_t> budget;  // at most this many triangles
  bool normals = true;                  // every model has normals (stored, or computed at load)
  std::optional<bool> colors;           // unset: the model's colours when it has them
  bool labels = false;
  // The payload's codec; unset: the connection's (hello). What a codec cannot carry (labels, finer
  // positions) is refused: codec_refusal, from core::codec::kCodecTraits.
  std::optional<core::codec::Codec> codec;
  Quantization quantization;
  DracoSettings draco;
  // Replies (this one and the gazes that follow) carry what changed since the connection's previous
  // mesh, by MT triangle id, instead of the whole cut (PROTOCOL.md, "Delta replies"). Needs the
  // sequential coder, which keeps the order of faces.
  bool delta = false;
};
// A new gaze point for the connection's latest extract (the first point of gaze_region): the newest
// gaze replaces a queued one.
struct Gaze {
  double x = 0.5;
  double y = 0.5;
  std::optional<double> distance;  // replaces the first focus's threshold when given
  std::optional<double> factor;    // replaces the first focus's factor when given
};
struct Cancel {
  std::uint64_t target = 0;  // id of the request to cancel
};
struct Stats {};
struct Ping {};
// Reloads the served models from their files now (as SIGHUP does); needs an admin token
// (mtlod-server --admin-tokens).
struct Reload {
  std::string token;
};

using Request = std::variant<Hello, ListModels, ModelInfo, Extract, Gaze, Cancel, Stats, Ping, Reload>;

// The request types' names on the wire, in the variant's order: parse.cpp, the server's counters and
// the error message for an unknown type all read this table.
inline constexpr std::array<const char*, 9> kRequestTypeNames{
    "hello", "list_models", "model_info", "extract", "gaze", "cancel", "stats", "ping", "reload"};
static_assert(kRequestTypeNames.size() == std::variant_size_v<Request>);

inline const char* request_type_name(const Request& request) {
  return kRequestTypeNames[request.index()];
}

}  // namespace mtlod::protocol

// The per-request pipeline, stage by stage, on real models: map → occupancy → distance transforms →
// allowed error → refinement → Draco. Counters give microseconds per stage, the cut's size and the
// payload's bits per triangle. Run: build/release/tests/mtlod_bench_pipeline
// (MTLOD_BENCH_DRAGON=path overrides the dragon, default ../shared/meshes or build/models).
#include <benchmark/benchmark.h>
#include <meshoptimizer.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <numeric>
#include <random>
#include <string>

#include "core/build/mt_builder.hpp"
#include "core/codec/draco_decode.hpp"
#include "core/codec/draco_encode.hpp"
#include "core/codec/index_encode.hpp"
#include "core/codec/meshopt_decode.hpp"
#include "core/codec/meshopt_encode.hpp"
#include "core/codec/vertex_encode.hpp"
#include "core/cut/cut_delta.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "core/model/bounds.hpp"
#include "core/view/occupancy_levels.hpp"
#include "core/view/view_extract.hpp"
#include "protocol/camera.hpp"
#include "protocol/view_request.hpp"
#include "tests/bench/bench_support.hpp"

namespace {

using mtlod::bench::quantile;
using mtlod::bench::refined;

using namespace mtlod;
namespace fs = std::filesystem;

struct Model {
  core::model::Mt mt;
  std::unique_ptr<core::view::OccupancyLevels> levels;
  std::array<double, 3> lo{}, hi{};
};

fs::path find_mesh(const char* env, std::initializer_list<fs::path> candidates) {
  if (const char* path = std::getenv(env)) return path;
  for (const fs::path& p : candidates) {
    if (fs::exists(p)) return p;
  }
  return {};
}

// The MT file MTLOD_BENCH_MT names, mapped as the server maps it, once per process; nullptr when
// the variable is unset or the file does not open.
const Model* model_file() {
  static std::unique_ptr<Model> slot;
  static bool tried = false;
  if (tried) return slot.get();
  tried = true;
  const char* path = std::getenv("MTLOD_BENCH_MT");
  if (!path) return nullptr;
  auto mt = core::io::read_mt_file(path);
  if (!mt) return nullptr;
  slot = std::make_unique<Model>();
  slot->mt = std::move(*mt);
  auto levels = core::view::OccupancyLevels::make(slot->mt);
  if (!levels) return slot.reset(), nullptr;
  slot->levels = std::move(*levels);
  const core::model::Bounds box = core::model::bounds_of(slot->mt.positions);
  slot->lo = core::model::to_double(box.lo);
  slot->hi = core::model::to_double(box.hi);
  return slot.get();
}

// Loads and builds once per process; nullptr when the mesh is not there.
const Model* model(const std::string& name) {
  static std::map<std::string, std::unique_ptr<Model>> cache;
  if (auto it = cache.find(name); it != cache.end()) return it->second.get();
  const fs::path shared = MTLOD_SHARED_MESHES_DIR, models = MTLOD_MODELS_DIR;
  const fs::path path =
      name == "dragon"
          ? find_mesh("MTLOD_BENCH_DRAGON", {shared / "dragon-vrip-871k.ply", models / "dragon-871k.ply"})
          : find_mesh("MTLOD_BENCH_BUNNY", {models / "bunny.ply", shared / "bunny-npm-3k.ply"});
  auto& slot = cache[name];
  if (path.empty()) return nullptr;
  auto mesh = core::io::load_mesh(path);
  if (!mesh) return nullptr;
  auto mt = core::build::build_mt(mesh->mesh);
  if (!mt) return nullptr;
  slot = std::make_unique<Model>();
  slot->mt = std::move(*mt);
  slot->levels = core::view::OccupancyLevels::make(slot->mt).value();  // in memory: cannot fail
  const core::model::Bounds box = core::model::bounds_of(slot->mt.positions);
  slot->lo = core::model::to_double(box.lo);
  slot->hi = core::model::to_double(box.hi);
  return slot.get();
}

// A front view, 800×600 screen, 256² grid, silhouette (2 px, f = 0.1) and a focus at the centre.
// (With f = 0 the dragon's cut stays above 230k triangles: every contour triangle at full resolution.)
protocol::Extract request_for(const Model& m, double error_px) {
  protocol::Extract e;
  protocol::look_at_camera(protocol::frame_bounds(m.lo, m.hi), 800.0 / 600.0, e.view, e.projection);
  e.grid = {256, 256};
  e.error = error_px;
  e.error_unit = core::view::ErrorUnits::kScreenPixels;
  e.criteria.regions[core::view::Criterion::kSilhouette] = protocol::Region{2, 0.1, {}};
  e.criteria.regions[core::view::Criterion::kFocus] = protocol::Region{40, 0.25, {{0.5, 0.5}}};
  return e;
}

std::size_t static_cut_size(const Model& m, double error_px) {
  core::view::ViewExtractor x(m.mt, *m.levels);
  core::cut::Refiner r(m.mt);
  core::cut::CutMesh cut;
  core::view::ViewRequest v = protocol::to_view_request(request_for(m, error_px), false);
  v.dynamic = false;
  x.map(v), x.occupancy(), x.distance_transforms(), x.allowed_error(), x.refine(r, cut);
  return cut.triangle_count();
}

// The pixel error whose static cut has about `target` triangles (bisection on a log scale).
double error_for_size(const Model& m, std::size_t target) {
  double lo = 0.01, hi = 1000;
  for (int i = 0; i < 30; ++i) {
    const double mid = std::sqrt(lo * hi);
    (static_cast<double>(static_cut_size(m, mid)) > target ? lo : hi) = mid;
  }
  return hi;
}

using Clock = std::chrono::steady_clock;
double us_since(Clock::time_point& t) {
  const auto now = Clock::now();
  const double us = std::chrono::duration<double, std::micro>(now - t).count();
  t = now;
  return us;
}

// Args: model (0 bunny, 1 dragon), target triangles, Draco mode (0, 5, 10 = edgebreaker speed; -1 sequential;
// -2 sequential with raw attribute values), normals (1: sent, 10-bit octahedral, the default).
void BM_Request(benchmark::State& state) {
  const Model* m = model(state.range(0) == 0 ? "bunny" : "dragon");
  if (!m) return state.SkipWithError("mesh not found");
  const auto target = static_cast<std::size_t>(state.range(1));
  const double error_px = error_for_size(*m, target);
  core::view::ViewRequest view = protocol::to_view_request(request_for(*m, error_px), false);
  view.dynamic = false;
  core::codec::DracoOptions draco;
  draco.method =
      state.range(2) < 0 ? core::codec::DracoMethod::kSequential : core::codec::DracoMethod::kEdgebreaker;
  draco.speed = state.range(2) < 0 ? 10 : static_cast<int>(state.range(2));
  draco.entropy_coding = state.range(2) != -2;
  draco.normals = state.range(3) != 0;
  const std::span<const float> normals = draco.normals ? m->mt.normals : std::span<const float>();
  core::view::ViewExtractor extractor(m->mt, *m->levels);
  core::cut::Refiner refiner(m->mt);
  core::cut::CutMesh cut;
  core::codec::DracoEncoder encoder;
  std::vector<std::uint8_t> payload;
  double t_map = 0, t_occ = 0, t_dt = 0, t_labels = 0, t_refine = 0, t_encode = 0, occupancy_triangles = 0;
  for (auto _ : state) {
    auto t = Clock::now();
    extractor.map(view);
    t_map += us_since(t);
    occupancy_triangles = static_cast<double>(extractor.occupancy());
    t_occ += us_since(t);
    extractor.distance_transforms();
    t_dt += us_since(t);
    extractor.allowed_error();
    t_labels += us_since(t);
    refined(extractor.refine(refiner, cut));
    t_refine += us_since(t);
    auto stats = encoder.encode({m->mt.positions, normals, {}, cut.triangles}, draco, payload);
    t_encode += us_since(t);
    benchmark::DoNotOptimize(stats);
  }
  const auto avg = benchmark::Counter::kAvgIterations;
  state.counters["map_us"] = benchmark::Counter(t_map, avg);
  state.counters["occupancy_us"] = benchmark::Counter(t_occ, avg);
  state.counters["occupancy_tris"] = occupancy_triangles;
  state.counters["dt_us"] = benchmark::Counter(t_dt, avg);
  state.counters["labels_us"] = benchmark::Counter(t_labels, avg);
  state.counters["refine_us"] = benchmark::Counter(t_refine, avg);
  state.counters["encode_us"] = benchmark::Counter(t_encode, avg);
  state.counters["before_encode_us"] = benchmark::Counter(t_map + t_occ + t_dt + t_labels + t_refine, avg);
  state.counters["triangles"] = static_cast<double>(cut.triangle_count());
  state.counters["bits_per_tri"] = 8.0 * payload.size() / std::max<std::size_t>(1, cut.triangle_count());
  state.counters["error_px"] = error_px;
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(cut.triangle_count()));
}

void request_args(benchmark::internal::Benchmark* b) {
  for (int normals : {0, 1}) {
    for (int draco : {-1, 0, 5, 10}) b->Args({0, 3674, draco, normals});  // the bunny whole: 3,674 triangles
    for (int size : {10'000, 50'000, 200'000}) {
      for (int draco : {-2, -1, 0, 5, 10}) b->Args({1, size, draco, normals});
    }
  }
  b->ArgNames({"model", "triangles", "draco", "normals"})->Unit(benchmark::kMillisecond);
}
BENCHMARK(BM_Request)->Apply(request_args);

// The cut BM_Codec and BM_IndexEncode encode (see BM_Codec), refined once.
const core::cut::CutMesh& codec_cut(const Model& m) {
  static core::cut::CutMesh cut;
  if (cut.triangles.empty()) {
    core::view::ViewRequest view =
        protocol::to_view_request(request_for(m, error_for_size(m, 50'000)), false);
    view.dynamic = false;
    core::view::ViewExtractor extractor(m.mt, *m.levels);
    core::cut::Refiner refiner(m.mt);
    extractor.map(view), extractor.occupancy(), extractor.distance_transforms(), extractor.allowed_error();
    refined(extractor.refine(refiner, cut));
  }
  return cut;
}

// The codecs side by side on one cut: the dragon's static front view of about 50k triangles
// (BM_Request's). The time is the encoding alone; counters give the payload's bytes per triangle
// and the C++ decoder's time (Draco's decoder, decode_meshopt). Args: codec (0 Draco edgebreaker
// speed 10, 1 Draco sequential, 2 Draco sequential with raw attribute values, 3 meshopt with the
// triangles reordered for a vertex cache, 4 meshopt in the cut's order, as deltas need), normals
// (1: 10-bit octahedral).
void BM_Codec(benchmark::State& state) {
  const Model* m = model("dragon");
  if (!m) return state.SkipWithError("mesh not found");
  const core::cut::CutMesh& cut = codec_cut(*m);
  const int codec = static_cast<int>(state.range(0));
  const bool normals = state.range(1) != 0;
  const core::codec::DracoInput input{
      m->mt.positions, normals ? m->mt.normals : std::span<const float>(), {}, cut.triangles};
  core::codec::DracoOptions draco;
  draco.method = codec == 0 ? core::codec::DracoMethod::kEdgebreaker : core::codec::DracoMethod::kSequential;
  draco.entropy_coding = codec != 2;
  draco.normals = normals;
  core::codec::MeshoptOptions meshopt;
  meshopt.normals = normals;
  meshopt.keep_triangle_order = codec == 4;
  core::codec::DracoEncoder draco_encoder;
  core::codec::MeshoptEncoder meshopt_encoder;
  std::vector<std::uint8_t> payload;
  for (auto _ : state) {
    const bool ok = codec < 3 ? draco_encoder.encode(input, draco, payload).ok()
                              : meshopt_encoder.encode(input, meshopt, payload).ok();
    if (!ok) return state.SkipWithError("encoding failed");
  }
  // Decoding, timed apart (a client's cost), a few times for a steadier figure.
  constexpr int kDecodes = 5;
  auto t = Clock::now();
  for (int i = 0; i < kDecodes; ++i) {
    const bool ok =
        codec < 3 ? core::codec::decode_draco(payload).ok() : core::codec::decode_meshopt(payload).ok();
    if (!ok) return state.SkipWithError("decoding failed");
  }
  state.counters["decode_us"] = us_since(t) / kDecodes;
  state.counters["triangles"] = static_cast<double>(cut.triangle_count());
  state.counters["bytes_per_tri"] =
      static_cast<double>(payload.size()) / static_cast<double>(cut.triangle_count());
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(cut.triangle_count()));
}
BENCHMARK(BM_Codec)
    ->ArgsProduct({{0, 1, 2, 3, 4}, {0, 1}})
    ->ArgNames({"codec", "normals"})
    ->Unit(benchmark::kMillisecond);

// The end of a stream encoder's benchmark: the last stream written must be the library's bytes;
// counters time_per_<unit> (the encoding's time over `count` items) and bytes_per_<unit>.
void report_stream(benchmark::State& state, const std::vector<std::uint8_t>& expected,
                   const std::vector<std::uint8_t>& written, std::size_t size, std::size_t count,
                   const std::string& unit) {
  if (size != expected.size() || !std::equal(expected.begin(), expected.end(), written.begin()))
    return state.SkipWithError("the streams differ");
  state.counters["time_per_" + unit] =
      benchmark::Counter(static_cast<double>(count),
                         benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.counters["bytes_per_" + unit] = static_cast<double>(size) / static_cast<double>(count);
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(count));
}

// The triangles stream of BM_Codec's meshopt payloads alone: meshoptimizer's index encoder (index
// codec version 1) against ours, which writes the same bytes. The triangles are the payload's own, as
// the payload decodes, so numbered and ordered as MeshoptEncoder hands them over. Args: encoder (0
// meshopt_encodeIndexBuffer, 1 encode_index_stream_v1), order (0 reordered spatially as codec 3,
// 1 the cut's order as codec 4). Counters: time_per_tri (the encoding's time over the triangles),
// bytes_per_tri.
void BM_IndexEncode(benchmark::State& state) {
  const Model* m = model("dragon");
  if (!m) return state.SkipWithError("mesh not found");
  const core::cut::CutMesh& cut = codec_cut(*m);
  const bool ours = state.range(0) == 1;
  core::codec::MeshoptOptions options;
  options.keep_triangle_order = state.range(1) == 1;
  std::vector<std::uint8_t> payload;
  if (!core::codec::MeshoptEncoder()
           .encode({m->mt.positions, {}, {}, cut.triangles, {}}, options, payload)
           .ok())
    return state.SkipWithError("encoding failed");
  auto decoded = core::codec::decode_meshopt(payload);
  if (!decoded) return state.SkipWithError("decoding failed");
  const std::vector<std::uint32_t>& indices = decoded->mesh.triangles;
  const std::size_t triangles = indices.size() / 3;
  std::vector<std::uint8_t> stream(
      core::codec::index_stream_bound(indices.size(), decoded->mesh.vertex_count()));
  meshopt_encodeIndexVersion(1);
  std::vector<std::uint8_t> expected(stream.size());
  expected.resize(
      meshopt_encodeIndexBuffer(expected.data(), expected.size(), indices.data(), indices.size()));
  std::size_t size = 0;
  for (auto _ : state) {
    size = ours ? core::codec::encode_index_stream_v1(indices, stream)
                : meshopt_encodeIndexBuffer(stream.data(), stream.size(), indices.data(), indices.size());
    benchmark::DoNotOptimize(stream.data());
  }
  report_stream(state, expected, stream, size, triangles, "tri");
}
BENCHMARK(BM_IndexEncode)
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->ArgNames({"encoder", "order"})
    ->Unit(benchmark::kMicrosecond);

// The vertex streams of BM_Codec's meshopt payloads with normals (codec 3) alone: meshoptimizer's
// vertex encoder (codec version 0) and octahedral filter against ours, which write the same bytes.
// The streams are the payload's own, decoded, so quantized, numbered and ordered as MeshoptEncoder
// hands them over. Args: encoder (0 meshoptimizer, 1 vertex_encode.hpp), stream (0 positions, u16x4,
// stride 8; 1 normals, 10-bit octahedral, stride 8; 2 normals, 8-bit, stride 4; 3 the filter of the
// 10-bit normals: meshopt_encodeFilterOct on a copy of the cut's normals gathered with w = 0, which
// the library needs, against encode_filter_oct reading the model's normals by vertex id).
// Counters: time_per_vertex, bytes_per_vertex (the stream's, or the filter's output).
void BM_VertexEncode(benchmark::State& state) {
  const Model* m = model("dragon");
  if (!m) return state.SkipWithError("mesh not found");
  const core::cut::CutMesh& cut = codec_cut(*m);
  const bool ours = state.range(0) == 1;
  const int stream = static_cast<int>(state.range(1));
  core::codec::MeshoptOptions options;
  options.normals = true;
  options.normal_bits = stream == 2 ? 8 : 10;
  std::vector<std::uint8_t> payload;
  if (!core::codec::MeshoptEncoder()
           .encode({m->mt.positions, m->mt.normals, {}, cut.triangles, {}}, options, payload)
           .ok())
    return state.SkipWithError("encoding failed");
  // The payload's vertex count, then its streams (a 4-byte length each): positions, then normals.
  auto u32_at = [&payload](std::size_t at) {
    std::uint32_t v;
    std::memcpy(&v, &payload[at], 4);
    return v;
  };
  const std::size_t n = u32_at(8);
  const std::size_t position_size = u32_at(core::codec::kMeshoptHeaderBytes);
  const std::size_t normals_at = core::codec::kMeshoptHeaderBytes + 4 + position_size;
  const bool normals = stream != 0;
  const std::size_t stride = stream == 2 ? 4 : 8;
  const std::size_t stream_at = normals ? normals_at : core::codec::kMeshoptHeaderBytes;
  std::vector<std::uint8_t> vertices(n * stride);
  if (meshopt_decodeVertexBuffer(vertices.data(), n, stride, &payload[stream_at + 4], u32_at(stream_at)) != 0)
    return state.SkipWithError("decoding failed");
  // The filter's input: the cut's vertices by first use, the payload's numbering before reordering.
  std::vector<std::uint32_t> ids;
  std::vector<char> seen(m->mt.positions.size() / 3, 0);
  for (const std::uint32_t v : cut.triangles)
    if (!seen[v]) seen[v] = 1, ids.push_back(v);
  std::vector<float> gathered(4 * ids.size());

  std::vector<std::uint8_t> out(stream == 3 ? 8 * ids.size() : core::codec::vertex_stream_bound(n, stride));
  std::vector<std::uint8_t> expected(out.size());
  meshopt_encodeVertexVersion(0);
  std::size_t size = 0;
  if (stream == 3) {
    for (std::size_t i = 0; i < ids.size(); ++i) {
      std::memcpy(&gathered[4 * i], &m->mt.normals[3 * std::size_t{ids[i]}], 12);
      gathered[4 * i + 3] = 0;
    }
    meshopt_encodeFilterOct(expected.data(), ids.size(), 8, options.normal_bits, gathered.data());
  } else {
    expected.resize(meshopt_encodeVertexBuffer(expected.data(), expected.size(), vertices.data(), n, stride));
  }
  for (auto _ : state) {
    if (stream == 3) {
      if (ours) {
        core::codec::encode_filter_oct(out.data(), 8, options.normal_bits, m->mt.normals, ids);
      } else {
        for (std::size_t i = 0; i < ids.size(); ++i) {
          std::memcpy(&gathered[4 * i], &m->mt.normals[3 * std::size_t{ids[i]}], 12);
          gathered[4 * i + 3] = 0;
        }
        meshopt_encodeFilterOct(out.data(), ids.size(), 8, options.normal_bits, gathered.data());
      }
      size = out.size();
    } else {
      size = ours ? core::codec::encode_vertex_stream_v0(vertices.data(), n, stride, out)
                  : meshopt_encodeVertexBuffer(out.data(), out.size(), vertices.data(), n, stride);
    }
    benchmark::DoNotOptimize(out.data());
  }
  report_stream(state, expected, out, size, stream == 3 ? ids.size() : n, "vertex");
}
BENCHMARK(BM_VertexEncode)
    ->ArgsProduct({{0, 1}, {0, 1, 2, 3}})
    ->ArgNames({"encoder", "stream"})
    ->Unit(benchmark::kMicrosecond);

// Dynamic refinement after a small camera move against refinement from the root, same result size.
void BM_RefineAfterSmallMove(benchmark::State& state) {
  const Model* m = model("dragon");
  if (!m) return state.SkipWithError("mesh not found");
  const bool dynamic = state.range(0) == 1;
  const double error_px = error_for_size(*m, 50'000);
  protocol::Extract a = request_for(*m, error_px), b = a;
  protocol::gaze_region(b.criteria).points[0].x += 0.01;  // the gaze moves by 1% of the screen
  core::view::ViewRequest va = protocol::to_view_request(a, false), vb = protocol::to_view_request(b, false);
  va.dynamic = vb.dynamic = dynamic;
  core::view::ViewExtractor x(m->mt, *m->levels);
  core::cut::Refiner refiner(m->mt);
  core::cut::CutMesh cut;
  bool flip = false;
  double refine_us = 0;
  for (auto _ : state) {
    const core::view::ViewRequest& v = flip ? vb : va;
    flip = !flip;
    state.PauseTiming();
    x.map(v), x.occupancy(), x.distance_transforms(), x.allowed_error();
    state.ResumeTiming();
    auto t = Clock::now();
    refined(x.refine(refiner, cut));
    refine_us += us_since(t);
  }
  state.counters["refine_us"] = benchmark::Counter(refine_us, benchmark::Counter::kAvgIterations);
  state.counters["triangles"] = static_cast<double>(cut.triangle_count());
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(cut.triangle_count()));
}
BENCHMARK(BM_RefineAfterSmallMove)->Arg(0)->Arg(1)->ArgName("dynamic")->Unit(benchmark::kMillisecond);

// mtlod-gaze's criteria (tests/bench/BENCHMARKS.md, "Gaze through the server"): 0.5 px, silhouette 2,0.25,
// full resolution within 20 px of the gaze.
protocol::Extract gaze_request(const Model& m) {
  protocol::Extract e = request_for(m, 0.5);
  e.criteria.regions[core::view::Criterion::kSilhouette] = protocol::Region{2, 0.25, {}};
  e.criteria.regions[core::view::Criterion::kFocus] = protocol::Region{20, 0.1, {{0.5, 0.5}}};
  return e;
}

// The gaze of the stream benchmarks: a fixation that drifts by a fraction of a percent of the
// screen, and a saccade to a random point one gaze in ten.
class GazeWalk {
 public:
  explicit GazeWalk(unsigned seed) : rng_(seed) {}
  void step(protocol::Extract& e) {
    protocol::Point& f = protocol::gaze_region(e.criteria).points[0];
    if (chance_(rng_) < 0.1) {
      f.x = anywhere_(rng_), f.y = anywhere_(rng_);
    } else {
      f.x = std::clamp(f.x + drift_(rng_), 0.0, 1.0), f.y = std::clamp(f.y + drift_(rng_), 0.0, 1.0);
    }
  }

 private:
  std::mt19937 rng_;
  std::uniform_real_distribution<double> anywhere_{0.2, 0.8}, drift_{-0.003, 0.003}, chance_{0, 1};
};

// Delta updates on a gaze stream as the server makes them for a connection with "delta": true and a
// codec: mtlod-gaze's criteria on the dragon (cuts of about 50k triangles), drifting fixations and a
// saccade one gaze in ten, the view kept per session; each update is the diff against the client's
// cut (core::CutDelta), the new triangles gathered in cut order and encoded with the gaze's options
// (protocol::to_encode_options: normals, the model's grid). The time is that update alone, one core.
// Args: codec (0 Draco, 1 meshopt). Counters: update_p50/p90/p99/max_us, added (new triangles a
// gaze, mean), added_p99, triangles (the cut, mean).
void BM_DeltaUpdate(benchmark::State& state) {
  const Model* m = model("dragon");
  if (!m) return state.SkipWithError("mesh not found");
  protocol::Extract e = gaze_request(*m);
  e.codec = state.range(0) == 1 ? core::codec::Codec::kMeshopt : core::codec::Codec::kDraco;
  e.delta = true;
  protocol::EncodeContext context{true, m->mt.has_colors(), {}, {}};
  for (int k = 0; k < 3; ++k)
    context.bounds_min[k] = static_cast<float>(m->lo[k]),
    context.bounds_max[k] = static_cast<float>(m->hi[k]);
  const core::codec::EncodeOptions options = protocol::to_encode_options(e, context);
  core::view::ViewExtractor x(m->mt, *m->levels);
  core::view::ViewCache session;
  core::cut::Refiner refiner(m->mt);
  core::cut::CutMesh scratch;
  core::cut::CutDelta sent;
  core::codec::CutEncoder encoder;
  std::vector<std::uint32_t> added, removed, added_triangles, added_ids;
  std::vector<std::uint8_t> payload;
  std::vector<double> update_us, added_counts;
  double triangles = 0;
  GazeWalk walk(7);
  for (auto _ : state) {
    walk.step(e);
    const core::view::ViewRequest v = protocol::to_view_request(e, false);  // the extractor keeps a reference
    const core::cut::CutSpan cut = refined(x.extract(v, refiner, scratch, &session));
    auto t = Clock::now();
    sent.update(cut.ids, m->mt.triangle_count(), added, removed);
    core::cut::gather_triangles(cut.triangles, cut.ids, added, added_triangles, added_ids);
    if (!added_triangles.empty()) {
      auto encoded = encoder.encode({m->mt.positions, m->mt.normals, {}, added_triangles, m->mt.colors},
                                    options, payload);
      if (!encoded) return state.SkipWithError(encoded.error().message.c_str());
    }
    update_us.push_back(us_since(t));
    added_counts.push_back(static_cast<double>(added.size()));
    triangles += static_cast<double>(cut.triangle_count());
  }
  // The first update sends the whole cut (the client has nothing yet): not a gaze's update.
  update_us.erase(update_us.begin()), added_counts.erase(added_counts.begin());
  const double mean_added = std::accumulate(added_counts.begin(), added_counts.end(), 0.0) /
                            static_cast<double>(added_counts.size());
  std::sort(update_us.begin(), update_us.end());
  std::sort(added_counts.begin(), added_counts.end());
  state.counters["update_p50_us"] = quantile(update_us, 0.5);
  state.counters["update_p90_us"] = quantile(update_us, 0.9);
  state.counters["update_p99_us"] = quantile(update_us, 0.99);
  state.counters["update_max_us"] = update_us.back();
  state.counters["added"] = mean_added;
  state.counters["added_p99"] = quantile(added_counts, 0.99);
  state.counters["triangles"] = benchmark::Counter(triangles, benchmark::Counter::kAvgIterations);
}
BENCHMARK(BM_DeltaUpdate)->Arg(0)->Arg(1)->ArgName("codec")->Unit(benchmark::kMillisecond)->Iterations(1000);

// A budgeted extraction of a new view (the dragon, mtlod-gaze's criteria, 50k triangles): the
// refinement alone, worst-first from the root. kept:0 is Refiner::refine_budget (nothing kept),
// kept:1 Refiner::start_budget, which keeps the threshold's cut for the session's gazes (what the
// server does on a connection; the first gaze builds its mesh).
void BM_BudgetNewView(benchmark::State& state) {
  const Model* m = model("dragon");
  if (!m) return state.SkipWithError("mesh not found");
  protocol::Extract e = gaze_request(*m);
  e.budget = 50'000;
  core::view::ViewRequest v = protocol::to_view_request(e, false);
  v.allowed_error_on_demand = false;
  core::view::ViewExtractor x(m->mt, *m->levels);
  x.map(v), x.occupancy(), x.distance_transforms(), x.allowed_error();
  const core::cut::AllowedError allowed = core::cut::AllowedError::from_vertices(x.vertex_allowed_error());
  core::cut::Refiner refiner(m->mt);
  core::cut::CutMesh cut;
  for (auto _ : state) {
    if (state.range(0) == 1) {
      refined(refiner.refine(core::cut::Refinement::from_root(allowed).within(50'000).keeping(), cut));
    } else {
      refined(refiner.refine(core::cut::Refinement::from_root(allowed).within(50'000), cut));
    }
  }
  state.counters["triangles"] = static_cast<double>(cut.triangle_count());
}
BENCHMARK(BM_BudgetNewView)->Arg(0)->Arg(1)->ArgName("kept")->Unit(benchmark::kMillisecond)->Iterations(30);

// A gaze stream on the dragon (cut of about 50k triangles): fixations that drift by a fraction of a
// percent of the screen, and a saccade to a random point one sample in ten. session:0 runs every
// stage again per gaze (refining the kept cut dynamically); session:1 keeps a core::ViewCache, as
// the server does per connection: the view's stages are reused and only the vertices whose focus
// multiplier changed are recomputed and handed to the refinement. Gazes use Draco sequential;
// raw:1 stores attribute values without Draco's entropy coding, as the server's gaze replies do.
// gaze_criteria:1 uses mtlod-gaze's criteria (0.5 px, silhouette 2,0.25, full detail within 20 px
// of the gaze) instead of this file's request_for: cuts of 45–95k triangles whose fine region
// moves with every gaze. gaze_criteria:2 adds a budget of 50k triangles (`--budget 50000`): cuts
// refined worst-first, moved on a session (Refiner::update_budget).
// delta_us: the diff a delta reply sends (core::CutDelta, as the server).
void BM_GazeStream(benchmark::State& state) {
  const Model* m = model("dragon");
  if (!m) return state.SkipWithError("mesh not found");
  const bool with_session = state.range(0) == 1;
  const bool gaze_criteria = state.range(2) >= 1, budget = state.range(2) == 2;
  protocol::Extract e = gaze_criteria ? gaze_request(*m) : request_for(*m, error_for_size(*m, 50'000));
  if (budget) e.budget = 50'000;
  std::vector<double> gaze_us;
  core::view::ViewExtractor x(m->mt, *m->levels);
  core::view::ViewCache session;
  core::cut::Refiner refiner(m->mt);
  core::cut::CutMesh cut;
  core::codec::DracoEncoder encoder;
  core::codec::DracoOptions draco;
  draco.method = core::codec::DracoMethod::kSequential;
  draco.entropy_coding = state.range(1) == 0;
  std::vector<std::uint8_t> payload;
  GazeWalk walk(5);
  double labels_us = 0, refine_us = 0, before_us = 0, encode_us = 0, delta_us = 0, triangles = 0, changed = 0,
         bytes = 0;
  core::cut::CutDelta delta;  // what a delta reply's diff costs (server, "delta": true)
  std::vector<std::uint32_t> added, removed;
  for (auto _ : state) {
    walk.step(e);
    const core::view::ViewRequest v = protocol::to_view_request(e, false);
    auto start = Clock::now();
    x.map(v, with_session ? &session : nullptr);
    x.occupancy(), x.distance_transforms();
    auto t = Clock::now();
    x.allowed_error();
    labels_us += us_since(t);
    t = Clock::now();
    refined(x.refine(refiner, cut));
    refine_us += us_since(t);
    gaze_us.push_back(us_since(start));
    before_us += gaze_us.back();
    t = Clock::now();
    delta.update(cut.ids, m->mt.triangle_count(), added, removed);
    delta_us += us_since(t);
    t = Clock::now();  // encode_us is the encoding alone
    auto encoded = encoder.encode({m->mt.positions, {}, {}, cut.triangles}, draco, payload);
    encode_us += us_since(t);
    if (!encoded) return state.SkipWithError(encoded.error().message.c_str());
    triangles += static_cast<double>(cut.triangle_count());
    bytes += static_cast<double>(payload.size());
    changed += with_session && session.reused() ? static_cast<double>(session.changed_vertices()) : 0.0;
  }
  auto mean = [&](double sum) { return benchmark::Counter(sum, benchmark::Counter::kAvgIterations); };
  state.counters["labels_us"] = mean(labels_us);
  state.counters["refine_us"] = mean(refine_us);
  state.counters["before_encode_us"] = mean(before_us);
  state.counters["encode_us"] = mean(encode_us);
  state.counters["delta_us"] = mean(delta_us);
  state.counters["triangles"] = mean(triangles);
  state.counters["changed_vertices"] = mean(changed);
  state.counters["bits_per_tri"] = 8.0 * bytes / std::max(1.0, triangles);
  std::sort(gaze_us.begin(), gaze_us.end());
  state.counters["before_encode_p90_us"] = gaze_us[gaze_us.size() * 9 / 10];
  state.counters["before_encode_max_us"] = gaze_us.back();
  state.counters["refine_restarts"] = static_cast<double>(refiner.restarts());
  state.counters["budget_raises"] = static_cast<double>(refiner.budget_raises());
  state.counters["budget_starts"] = static_cast<double>(refiner.budget_starts());
}
BENCHMARK(BM_GazeStream)
    ->ArgsProduct({{0, 1}, {0, 1}, {0, 1, 2}})
    ->ArgNames({"session", "raw", "gaze_criteria"})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(300);

// The budgeted gaze stream of BENCHMARKS.md's large-model rows on the MT file MTLOD_BENCH_MT
// (skipped without it), in one process: mtlod-gaze's criteria at 0.2 px with a 40k budget, the
// session's view and refiner as the server keeps them per connection, GazeWalk's gazes. The time
// of a gaze until its cut (ViewExtractor::extract, as the server calls it; no diff, no encoding),
// with percentiles; the first 100 gazes warm the
// session and the file's pages and are not counted.
void BM_GazeFile(benchmark::State& state) {
  const Model* m = model_file();
  if (!m) return state.SkipWithError("MTLOD_BENCH_MT not set or not an MT file");
  protocol::Extract e = gaze_request(*m);
  e.error = 0.2;
  e.budget = 40'000;
  core::view::ViewExtractor x(m->mt, *m->levels);
  core::view::ViewCache session;
  core::cut::Refiner refiner(m->mt);
  core::cut::CutMesh scratch;
  GazeWalk walk(11);
  std::vector<double> gaze_us;
  double triangles = 0;
  for (auto _ : state) {
    walk.step(e);
    const core::view::ViewRequest v = protocol::to_view_request(e, false);
    auto start = Clock::now();
    const core::cut::CutSpan cut = refined(x.extract(v, refiner, scratch, &session));
    gaze_us.push_back(us_since(start));
    triangles += static_cast<double>(cut.triangle_count());
  }
  constexpr std::size_t kWarm = 100;
  gaze_us.erase(gaze_us.begin(), gaze_us.begin() + std::ptrdiff_t(std::min(kWarm, gaze_us.size())));
  if (gaze_us.empty()) return;
  const double mean =
      std::accumulate(gaze_us.begin(), gaze_us.end(), 0.0) / static_cast<double>(gaze_us.size());
  std::sort(gaze_us.begin(), gaze_us.end());
  state.counters["gaze_mean_us"] = mean;
  state.counters["gaze_p50_us"] = quantile(gaze_us, 0.5);
  state.counters["gaze_p90_us"] = quantile(gaze_us, 0.9);
  state.counters["gaze_p99_us"] = quantile(gaze_us, 0.99);
  state.counters["gaze_max_us"] = gaze_us.back();
  state.counters["triangles"] = benchmark::Counter(triangles, benchmark::Counter::kAvgIterations);
  state.counters["budget_raises"] = static_cast<double>(refiner.budget_raises());
  state.counters["budget_starts"] = static_cast<double>(refiner.budget_starts());
  state.counters["refine_restarts"] = static_cast<double>(refiner.restarts());
}
BENCHMARK(BM_GazeFile)->Unit(benchmark::kMillisecond)->Iterations(2100);

}  // namespace

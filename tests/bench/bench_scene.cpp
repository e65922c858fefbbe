// Scenes (core/view/scene_extract): a room of 100 instances of four scanned models at a shared
// 100k-triangle budget, one scene request against one request per instance. Counters give the stage
// times, triangles, payload bytes, the budget search's passes, and how many instances stayed at their
// root (hidden or out of view). BM_SceneFidelity renders both at the same total bytes and scores them
// as tests/evaluation/FIDELITY.md does (the foveated error, 1 − foveated SSIM, against the full
// models). Run: build/release/tests/mtlod_bench_scene
#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/mat4x4.hpp>

#include "core/build/mt_builder.hpp"
#include "core/codec/cut_encoder.hpp"
#include "core/eval/image_metrics.hpp"
#include "core/eval/render.hpp"
#include "core/io/mesh_io.hpp"
#include "core/model/bounds.hpp"
#include "core/view/occupancy_levels.hpp"
#include "core/view/scene_extract.hpp"
#include "core/view/view_extract.hpp"

namespace {

using namespace mtlod;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct Model {
  std::string name;
  core::model::Mt mt;
  std::unique_ptr<core::view::OccupancyLevels> levels;
  core::model::Bounds box;
};

// The four models: the bunny of build/models and three scans of the shared meshes (absent: skipped).
const std::vector<std::unique_ptr<Model>>& models() {
  static const std::vector<std::unique_ptr<Model>> loaded = [] {
    const fs::path shared = MTLOD_SHARED_MESHES_DIR, built = MTLOD_MODELS_DIR;
    std::vector<std::unique_ptr<Model>> out;
    for (const fs::path& path : {built / "bunny.ply", shared / "armadillo-52k.ply", shared / "igea-269k.ply",
                                 shared / "dragon-vrip-871k.ply"}) {
      auto mesh = core::io::load_mesh(path);
      if (!mesh) return std::vector<std::unique_ptr<Model>>{};
      auto mt = core::build::build_mt(mesh->mesh);
      if (!mt) return std::vector<std::unique_ptr<Model>>{};
      auto m = std::make_unique<Model>();
      m->name = path.stem().string();
      m->mt = std::move(*mt);
      m->levels = core::view::OccupancyLevels::make(m->mt).value();  // in memory: cannot fail
      m->box = core::model::bounds_of(m->mt.positions);
      out.push_back(std::move(m));
    }
    return out;
  }();
  return loaded;
}

// A room of `count` instances on a square floor, the models taking turns, each scaled so its box's
// largest side is 1, stood on the floor and turned by the golden angle; rows 1.3 apart, so the rows
// in front hide part of those behind from the camera, which looks down at the room from in front.
// With `wall`, one more instance: the igea bust flattened into a wall across the left half of the
// room's front, taller than the instances, hiding some of them whole.
std::vector<core::view::SceneInstance> room(std::size_t count, bool wall = false) {
  const auto& ms = models();
  const auto side = static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(count))));
  const float step = 1.3f, golden = 3.14159265f * (3.0f - std::sqrt(5.0f));
  std::vector<core::view::SceneInstance> instances;
  for (std::size_t i = 0; i < count; ++i) {
    const Model& m = *ms[i % ms.size()];
    const float scale = 1.0f / m.box.largest_side();
    const std::array<float, 3> c = m.box.centre();
    const float x = (static_cast<float>(i % side) - 0.5f * static_cast<float>(side - 1)) * step;
    const float z = (static_cast<float>(i / side) - 0.5f * static_cast<float>(side - 1)) * step;
    glm::mat4 matrix = glm::translate(glm::mat4(1), glm::vec3(x, 0, z));
    matrix = glm::rotate(matrix, static_cast<float>(i) * golden, glm::vec3(0, 1, 0));
    matrix = glm::scale(matrix, glm::vec3(scale));
    matrix = glm::translate(matrix, glm::vec3(-c[0], -m.box.lo[1], -c[2]));
    instances.push_back({&m.mt, m.levels.get(), matrix});
  }
  if (wall) {
    const Model& m = *ms[2 % ms.size()];
    const float width = 0.5f * static_cast<float>(side) * step,
                front = 0.5f * static_cast<float>(side) * step;
    const core::model::Bounds& b = m.box;
    const std::array<float, 3> c = b.centre();
    // Scaled to width × (2.5 × an instance's height) × 0.1, its base on the floor, in front of the rows.
    glm::mat4 matrix = glm::translate(glm::mat4(1), glm::vec3(-0.5f * width, 0, front));
    matrix = glm::scale(matrix, glm::vec3(width / (b.hi[0] - b.lo[0]), 2.5f / (b.hi[1] - b.lo[1]),
                                          0.1f / (b.hi[2] - b.lo[2])));
    matrix = glm::translate(matrix, glm::vec3(-c[0], -b.lo[1], -c[2]));
    instances.push_back({&m.mt, m.levels.get(), matrix});
  }
  return instances;
}

// 1280×720, the room seen from in front and above; 0.5 px at the focus (the pointer at the centre),
// the clients' foveal default and hidden-surface coarsening, a 320×180 grid.
core::view::ViewRequest room_view(std::size_t count, std::size_t budget) {
  const auto side = static_cast<float>(std::ceil(std::sqrt(static_cast<double>(count))));
  const float extent = 0.65f * side;
  core::view::ViewRequest r;
  r.camera.view =
      glm::lookAt(glm::vec3(0, 1.2f * extent, 2.2f * extent), glm::vec3(0, 0, 0), glm::vec3(0, 1, 0));
  r.camera.projection = glm::perspective(glm::radians(45.0f), 1280.0f / 720.0f, 0.05f, 20.0f * extent);
  r.grid = {320, 180};
  r.allowed.error = 0.5f;
  r.allowed.units = core::view::ErrorUnits::kScreenPixels;
  r.allowed.viewport_height_px = 720;
  r.allowed.criteria[core::view::kGazeCriterion] =
      core::view::RegionLaw{core::view::FalloffLaw::kFoveal, 0.0f, 1.0f};
  r.points[core::view::kGazeCriterion] = {{0.5f, 0.5f}};
  r.allowed.hidden_factor = 16.0f;
  r.allowed.outside_view_factor = 8.0f;
  r.budget = budget;
  r.dynamic = false;
  return r;
}

double us_since(Clock::time_point& t) {
  const auto now = Clock::now();
  const double us = std::chrono::duration<double, std::micro>(now - t).count();
  t = now;
  return us;
}

// One observer that adds up the stages' times.
struct StageTimes final : core::view::StageObserver {
  void finished(core::view::Stage stage) override { us[static_cast<std::size_t>(stage)] += us_since(clock); }
  std::array<double, core::view::kStageCount> us{};
  Clock::time_point clock;
};

// Args: instances, budget, codec (0 Draco sequential with raw values, the gazes' default; 1 meshopt).
void BM_Scene(benchmark::State& state) {
  if (models().empty()) return state.SkipWithError("the shared meshes or build/models are missing");
  const auto count = static_cast<std::size_t>(state.range(0));
  const auto budget = static_cast<std::size_t>(state.range(1));
  const bool wall = state.range(3) != 0;
  const std::vector<core::view::SceneInstance> instances = room(count, wall);
  const core::view::ViewRequest view = room_view(count, budget);
  core::codec::EncodeOptions encoding;
  encoding.codec = state.range(2) == 0 ? core::codec::Codec::kDraco : core::codec::Codec::kMeshopt;
  encoding.draco.method = core::codec::DracoMethod::kSequential;
  encoding.draco.entropy_coding = false;
  core::view::SceneExtractor extractor;
  core::codec::CutEncoder encoder;
  std::vector<core::cut::CutMesh> cuts;
  std::vector<std::uint8_t> payload;
  StageTimes stages;
  double encode_us = 0, bytes = 0;
  core::view::SceneStats stats;
  for (auto _ : state) {
    stages.clock = Clock::now();
    stats = *extractor.extract({view, instances}, cuts, &stages);
    auto t = Clock::now();
    bytes = 0;
    for (std::size_t i = 0; i < instances.size(); ++i) {
      const core::model::Mt& mt = *instances[i].mt;
      auto encoded = encoder.encode({mt.positions, mt.normals, {}, cuts[i].triangles, {}}, encoding, payload);
      benchmark::DoNotOptimize(encoded);
      bytes += static_cast<double>(payload.size());
    }
    encode_us += us_since(t);
  }
  // Instances the picture does not show at all (none of its cells names them) and those at their root.
  std::vector<std::uint8_t> shown(instances.size(), 0);
  for (const std::uint32_t owner : extractor.instance_grid())
    if (owner != core::view::SceneExtractor::kNoInstance) shown[owner] = 1;
  std::size_t at_root = 0, hidden = 0, hidden_triangles = 0, hidden_over_root = 0;
  for (std::size_t i = 0; i < count; ++i) {
    const std::size_t triangles = cuts[i].triangle_count(), root = instances[i].mt->root_triangle_count();
    at_root += triangles == root;
    if (shown[i]) continue;
    ++hidden;
    hidden_triangles += triangles;
    hidden_over_root += triangles - root;
  }
  state.counters["hidden"] = static_cast<double>(hidden);
  state.counters["hidden_tris"] = static_cast<double>(hidden_triangles);
  state.counters["hidden_over_root"] = static_cast<double>(hidden_over_root);
  const auto avg = benchmark::Counter::kAvgIterations;
  static constexpr std::array<const char*, core::view::kStageCount> kNames{"map_us", "occupancy_us", "dt_us",
                                                                           "labels_us", "refine_us"};
  for (std::size_t s = 0; s < kNames.size(); ++s)
    state.counters[kNames[s]] = benchmark::Counter(stages.us[s], avg);
  state.counters["encode_us"] = benchmark::Counter(encode_us, avg);
  state.counters["triangles"] = static_cast<double>(stats.triangles);
  state.counters["bytes"] = bytes;
  state.counters["passes"] = static_cast<double>(stats.passes);
  state.counters["in_view"] = static_cast<double>(stats.instances_in_view);
  state.counters["at_root"] = static_cast<double>(at_root);
  state.counters["memory_MiB"] = static_cast<double>(extractor.memory_bytes()) / 1048576.0;
}
BENCHMARK(BM_Scene)
    ->Args({100, 100'000, 0, 0})
    ->Args({100, 100'000, 1, 0})
    ->Args({100, 20'000, 1, 0})
    ->Args({16, 100'000, 1, 0})
    ->Args({100, 100'000, 1, 1})
    ->ArgNames({"instances", "budget", "codec", "wall"})
    ->Unit(benchmark::kMillisecond);

// A session's gazes on the room: the focus moves along a circle each iteration; the view's occupancy
// and transforms are the session's (SceneCache), the instances refined from their roots and encoded
// (meshopt). Args: instances, budget.
void BM_SceneGaze(benchmark::State& state) {
  if (models().empty()) return state.SkipWithError("the shared meshes or build/models are missing");
  const auto count = static_cast<std::size_t>(state.range(0));
  const std::vector<core::view::SceneInstance> instances = room(count);
  core::view::ViewRequest view = room_view(count, static_cast<std::size_t>(state.range(1)));
  core::codec::EncodeOptions encoding;
  encoding.codec = core::codec::Codec::kMeshopt;
  core::view::SceneExtractor extractor;
  core::view::SceneCache session;
  core::codec::CutEncoder encoder;
  std::vector<core::cut::CutMesh> cuts;
  std::vector<std::uint8_t> payload;
  StageTimes stages;
  double triangles = 0;
  std::size_t step = 0, reused = 0;
  if (!extractor.extract({view, instances}, cuts, nullptr, &session).ok())
    return state.SkipWithError("refine");
  for (auto _ : state) {
    const float angle = 0.1f * static_cast<float>(++step);
    view.points[core::view::kGazeCriterion] = {
        {0.5f + 0.2f * std::cos(angle), 0.5f + 0.2f * std::sin(angle)}};
    stages.clock = Clock::now();
    auto stats = extractor.extract({view, instances}, cuts, &stages, &session);
    reused += session.reused();
    for (std::size_t i = 0; i < count; ++i) {
      const core::model::Mt& mt = *instances[i].mt;
      benchmark::DoNotOptimize(
          encoder.encode({mt.positions, mt.normals, {}, cuts[i].triangles, {}}, encoding, payload));
    }
    triangles = static_cast<double>(stats->triangles);
  }
  const auto avg = benchmark::Counter::kAvgIterations;
  state.counters["transforms_us"] = benchmark::Counter(stages.us[2], avg);
  state.counters["refine_us"] = benchmark::Counter(stages.us[4], avg);
  state.counters["triangles"] = triangles;
  state.counters["reused"] = benchmark::Counter(static_cast<double>(reused), avg);
  state.counters["session_KiB"] = static_cast<double>(session.memory_bytes()) / 1024.0;
}
BENCHMARK(BM_SceneGaze)
    ->Args({100, 20'000})
    ->Args({16, 100'000})
    ->ArgNames({"instances", "budget"})
    ->Unit(benchmark::kMillisecond);

// The same room as one request per instance, each with the budget's even share (the only split a
// client without scenes can make) and its own transforms, blind to the others.
void BM_RequestPerInstance(benchmark::State& state) {
  if (models().empty()) return state.SkipWithError("the shared meshes or build/models are missing");
  const auto count = static_cast<std::size_t>(state.range(0));
  const auto budget = static_cast<std::size_t>(state.range(1));
  const std::vector<core::view::SceneInstance> instances = room(count);
  core::view::ViewRequest view = room_view(count, budget / count);
  std::map<const core::model::Mt*, std::unique_ptr<core::view::ViewExtractor>> extractors;
  std::map<const core::model::Mt*, std::unique_ptr<core::cut::Refiner>> refiners;
  for (const auto& i : instances) {
    if (!extractors.count(i.mt)) {
      extractors[i.mt] = std::make_unique<core::view::ViewExtractor>(*i.mt, *i.levels);
      refiners[i.mt] = std::make_unique<core::cut::Refiner>(*i.mt);
    }
  }
  core::cut::CutMesh scratch;
  double triangles = 0;
  for (auto _ : state) {
    triangles = 0;
    for (const auto& i : instances) {
      view.camera.model = i.model;
      auto cut = extractors[i.mt]->extract(view, *refiners[i.mt], scratch);
      if (!cut) return state.SkipWithError(cut.error().message.c_str());
      triangles += static_cast<double>(cut->triangle_count());
    }
  }
  state.counters["triangles"] = triangles;
}
BENCHMARK(BM_RequestPerInstance)
    ->Args({100, 100'000})
    ->ArgNames({"instances", "budget"})
    ->Unit(benchmark::kMillisecond);

// The instances' cuts as one world-space mesh for the renderer: each instance's vertices placed by
// its matrix, its model's normals turned with it (matrices without shear: their inverse transpose is
// a multiple of themselves).
struct WorldMesh {
  std::vector<float> positions, normals;
  std::vector<std::uint32_t> triangles;
  std::vector<std::uint32_t> local;  // scratch: a model vertex's index here, per instance
};

void append(WorldMesh& world, const core::view::SceneInstance& instance,
            std::span<const std::uint32_t> triangles) {
  const core::model::Mt& mt = *instance.mt;
  constexpr std::uint32_t kNone = UINT32_MAX;
  world.local.assign(mt.vertex_count(), kNone);
  const glm::mat4& m = instance.model;
  for (const std::uint32_t v : triangles) {
    std::uint32_t& id = world.local[v];
    if (id == kNone) {
      id = static_cast<std::uint32_t>(world.positions.size() / 3);
      const glm::vec4 p =
          m * glm::vec4(mt.positions[3 * v], mt.positions[3 * v + 1], mt.positions[3 * v + 2], 1);
      const glm::vec3 n = glm::normalize(
          glm::vec3(m * glm::vec4(mt.normals[3 * v], mt.normals[3 * v + 1], mt.normals[3 * v + 2], 0)));
      world.positions.insert(world.positions.end(), {p.x, p.y, p.z});
      world.normals.insert(world.normals.end(), {n.x, n.y, n.z});
    }
    world.triangles.push_back(id);
  }
}

// The picture of the instances' cuts at the room's camera, 1280×720, shaded with the models' normals.
std::vector<std::uint8_t> render(const std::vector<core::view::SceneInstance>& instances,
                                 const std::vector<std::span<const std::uint32_t>>& cuts,
                                 const core::view::ViewRequest& view, core::view::GridSize size) {
  WorldMesh world;
  for (std::size_t i = 0; i < instances.size(); ++i) append(world, instances[i], cuts[i]);
  core::view::Camera camera = view.camera;
  camera.model = glm::mat4(1);
  const core::view::ViewMapping mapping(camera, size);
  core::eval::RenderOptions options;
  options.vertex_normals = world.normals;
  std::vector<std::uint8_t> rgb(3 * size.cell_count());
  core::eval::render_mesh(mapping, world.positions, world.triangles, {}, options, rgb);
  return rgb;
}

// Encodes every instance's cut as an extract's reply would (Draco edgebreaker, 14-bit positions,
// 10-bit normals); returns the bytes.
std::size_t payload_bytes(const std::vector<core::view::SceneInstance>& instances,
                          const std::vector<std::span<const std::uint32_t>>& cuts) {
  core::codec::CutEncoder encoder;
  core::codec::EncodeOptions encoding;
  std::vector<std::uint8_t> payload;
  std::size_t bytes = 0;
  for (std::size_t i = 0; i < instances.size(); ++i) {
    const core::model::Mt& mt = *instances[i].mt;
    if (!encoder.encode({mt.positions, mt.normals, {}, cuts[i], {}}, encoding, payload)) return SIZE_MAX;
    bytes += payload.size();
  }
  return bytes;
}

// One scene request at a budget against one request per instance at the same total bytes (their
// even budget share found by bisection), both rendered and scored against the full models.
// Args: instances, budget.
void BM_SceneFidelity(benchmark::State& state) {
  if (models().empty()) return state.SkipWithError("the shared meshes or build/models are missing");
  const auto count = static_cast<std::size_t>(state.range(0));
  const auto budget = static_cast<std::size_t>(state.range(1));
  const std::vector<core::view::SceneInstance> instances = room(count);
  const core::view::ViewRequest view = room_view(count, budget);
  const core::view::GridSize size{1280, 720};
  core::eval::Foveation foveation;  // the pointer at the centre, the camera's field of view
  foveation.focus_x_px = 640, foveation.focus_y_px = 360;
  foveation.focal_px = core::eval::focal_px_from_fov(720, 45.0);
  double scene_error = 0, single_error = 0, scene_bytes = 0, single_bytes = 0, scene_triangles = 0,
         single_triangles = 0, share = 0;
  for (auto _ : state) {
    // The reference: every instance at full resolution.
    std::map<const core::model::Mt*, core::cut::CutMesh> full;
    for (const auto& i : instances) {
      if (full.count(i.mt)) continue;
      core::cut::Refiner refiner(*i.mt);
      if (!refiner.refine(core::cut::Refinement::from_root(core::cut::AllowedError::everywhere(0)),
                          full[i.mt]))
        return state.SkipWithError("a model does not refine");
    }
    std::vector<std::span<const std::uint32_t>> cuts;
    for (const auto& i : instances) cuts.push_back(full[i.mt].triangles);
    const std::vector<std::uint8_t> reference = render(instances, cuts, view, size);
    auto score = [&](const std::vector<std::span<const std::uint32_t>>& c) {
      const auto compared = core::eval::compare_rgb_renderings(render(instances, c, view, size), reference,
                                                               size, {255, 255, 255}, foveation);
      return 1.0 - compared.foveated_ssim;
    };

    core::view::SceneExtractor extractor;
    std::vector<core::cut::CutMesh> scene;
    if (!extractor.extract({view, instances}, scene).ok())
      return state.SkipWithError("the scene does not refine");
    cuts.clear();
    scene_triangles = 0;
    for (const auto& c : scene) {
      cuts.push_back(c.triangles);
      scene_triangles += static_cast<double>(c.triangle_count());
    }
    scene_bytes = static_cast<double>(payload_bytes(instances, cuts));
    scene_error = score(cuts);

    // One request per instance, each blind to the others, at the largest even share whose bytes fit.
    std::map<const core::model::Mt*, std::unique_ptr<core::view::ViewExtractor>> extractors;
    std::vector<core::cut::CutMesh> singles(count);
    auto requests = [&](std::size_t each) {
      core::view::ViewRequest one = view;
      one.budget = each;
      cuts.clear();
      for (std::size_t i = 0; i < count; ++i) {
        const auto& instance = instances[i];
        auto& x = extractors[instance.mt];
        if (!x) x = std::make_unique<core::view::ViewExtractor>(*instance.mt, *instance.levels);
        one.camera.model = instance.model;
        core::cut::Refiner refiner(*instance.mt);  // a new view: from the root
        core::cut::CutMesh scratch;
        auto cut = x->extract(one, refiner, scratch);
        if (!cut) return SIZE_MAX;
        singles[i].assign(*cut);
        cuts.push_back(singles[i].triangles);
      }
      return payload_bytes(instances, cuts);
    };
    std::size_t lo = 1, hi = budget;  // lo fits (the roots at worst), hi may not
    while (hi - lo > std::max<std::size_t>(1, lo / 100)) {
      const std::size_t mid = (lo + hi) / 2;
      (static_cast<double>(requests(mid)) <= scene_bytes ? lo : hi) = mid;
    }
    share = static_cast<double>(lo);
    single_bytes = static_cast<double>(requests(lo));
    single_triangles = 0;
    for (const auto& c : singles) single_triangles += static_cast<double>(c.triangle_count());
    single_error = score(cuts);
  }
  state.counters["scene_error"] = scene_error;
  state.counters["per_instance_error"] = single_error;
  state.counters["error_ratio"] = single_error / std::max(scene_error, 1e-12);
  state.counters["scene_bytes"] = scene_bytes;
  state.counters["per_instance_bytes"] = single_bytes;
  state.counters["scene_triangles"] = scene_triangles;
  state.counters["per_instance_triangles"] = single_triangles;
  state.counters["budget_share"] = share;
}
BENCHMARK(BM_SceneFidelity)
    ->Args({100, 100'000})
    ->Args({100, 20'000})
    ->Args({16, 20'000})
    ->Args({16, 5'000})
    ->ArgNames({"instances", "budget"})
    ->Unit(benchmark::kSecond)
    ->Iterations(1);

}  // namespace

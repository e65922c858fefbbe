// Benchmarks of the grid stages (core/ARCHITECTURE.md §1): the papers' two-pass 5-7-11 chamfer and the
// exact Euclidean transform against OpenCV's cv::distanceTransform on the same images (one thread),
// the projection of 1M vertices hand-written against a generic glm::mat4 product, occupancy of the
// shared dragon meshes, and the allowed-error labels of the 871k dragon full against lazy.
// Items are grid cells (transforms), vertices (projection, labels) or triangles (occupancy).
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec4.hpp>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <algorithm>
#include <filesystem>
#include <optional>

#include "core/build/mt_builder.hpp"
#include "core/cut/refine.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "core/view/allowed_error.hpp"
#include "core/view/distance_transform.hpp"
#include "core/view/labels.hpp"
#include "core/view/occupancy.hpp"
#include "core/view/occupancy_levels.hpp"
#include "core/view/view_grid.hpp"
#include "tests/bench/bench_support.hpp"

namespace mtlod::core {
namespace {

using mtlod::bench::refined;

// Random discs covering about half of the image, fixed seed: object cells are 1, background 0.
std::vector<std::uint8_t> blob_image(view::GridSize grid) {
  std::mt19937 rng(4242);
  std::vector<std::uint8_t> image(grid.cell_count(), 0);
  const float side = static_cast<float>(grid.width);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int disc = 0; disc < 40; ++disc) {
    const float cx = u(rng) * side, cy = u(rng) * static_cast<float>(grid.height),
                r = (0.04f + 0.12f * u(rng)) * side;
    for (std::uint32_t j = 0; j < grid.height; ++j) {
      for (std::uint32_t i = 0; i < grid.width; ++i) {
        const float dx = static_cast<float>(i) - cx, dy = static_cast<float>(j) - cy;
        if (dx * dx + dy * dy <= r * r) image[grid.cell(i, j)] = 1;
      }
    }
  }
  return image;
}

void BM_Chamfer5711(benchmark::State& state) {
  const auto side = static_cast<std::uint32_t>(state.range(0));
  const view::GridSize grid{side, side};
  const auto image = blob_image(grid);
  std::vector<std::uint16_t> out(grid.cell_count());
  view::DistanceTransformer transformer;
  for (auto _ : state) {
    transformer.chamfer(view::DistanceMetric::kChamfer5711, image, grid, out);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * grid.cell_count()));
}
BENCHMARK(BM_Chamfer5711)->Arg(256)->Arg(512)->Arg(1024)->Arg(2048)->Unit(benchmark::kMicrosecond);

// The same transform through the cell-by-cell scalar passes (the portable fallback), for reference.
void BM_Chamfer5711Scalar(benchmark::State& state) {
  const auto side = static_cast<std::uint32_t>(state.range(0));
  const view::GridSize grid{side, side};
  const auto image = blob_image(grid);
  std::vector<std::uint16_t> out(grid.cell_count());
  view::DistanceTransformer transformer;
  transformer.set_scalar(true);
  for (auto _ : state) {
    transformer.chamfer(view::DistanceMetric::kChamfer5711, image, grid, out);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * grid.cell_count()));
}
BENCHMARK(BM_Chamfer5711Scalar)->Arg(512)->Unit(benchmark::kMicrosecond);

void BM_Chamfer34(benchmark::State& state) {
  const auto side = static_cast<std::uint32_t>(state.range(0));
  const view::GridSize grid{side, side};
  const auto image = blob_image(grid);
  std::vector<std::uint16_t> out(grid.cell_count());
  view::DistanceTransformer transformer;
  for (auto _ : state) {
    transformer.chamfer(view::DistanceMetric::kChamfer34, image, grid, out);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * grid.cell_count()));
}
BENCHMARK(BM_Chamfer34)->Arg(512)->Unit(benchmark::kMicrosecond);

void BM_EuclideanSquared(benchmark::State& state) {
  const auto side = static_cast<std::uint32_t>(state.range(0));
  const view::GridSize grid{side, side};
  const auto image = blob_image(grid);
  std::vector<std::uint32_t> out(grid.cell_count());
  view::DistanceTransformer transformer;
  for (auto _ : state) {
    transformer.euclidean_squared(image, grid, out);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * grid.cell_count()));
}
BENCHMARK(BM_EuclideanSquared)->Arg(256)->Arg(512)->Arg(1024)->Arg(2048)->Unit(benchmark::kMicrosecond);

// OpenCV peers: same images, 8-bit input with zero cells as seeds (the same convention), float output.
void opencv_distance(benchmark::State& state, int mask) {
  cv::setNumThreads(1);
  const auto side = static_cast<std::uint32_t>(state.range(0));
  const view::GridSize grid{side, side};
  auto image = blob_image(grid);
  const cv::Mat src(static_cast<int>(side), static_cast<int>(side), CV_8UC1, image.data());
  cv::Mat dst;
  for (auto _ : state) {
    cv::distanceTransform(src, dst, cv::DIST_L2, mask);
    benchmark::DoNotOptimize(dst.data);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * grid.cell_count()));
}
void BM_OpenCvMask5(benchmark::State& state) {
  opencv_distance(state, cv::DIST_MASK_5);
}
void BM_OpenCvPrecise(benchmark::State& state) {
  opencv_distance(state, cv::DIST_MASK_PRECISE);
}
BENCHMARK(BM_OpenCvMask5)->Arg(256)->Arg(512)->Arg(1024)->Arg(2048)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_OpenCvPrecise)->Arg(256)->Arg(512)->Arg(1024)->Arg(2048)->Unit(benchmark::kMicrosecond);

// 1M random vertices in a unit cube seen by a perspective camera.
struct ProjectionScene {
  std::vector<float> positions;
  view::ViewMapping mapping;
  ProjectionScene() {
    std::mt19937 rng(99);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    positions.resize(3 * 1000000);
    for (float& p : positions) p = u(rng);
    view::Camera camera;
    camera.view = glm::lookAt(glm::vec3(0.5f, 0.8f, 3.0f), glm::vec3(0.0f), glm::vec3(0.0f, 1.0f, 0.0f));
    camera.projection = glm::perspective(glm::radians(45.0f), 1.0f, 0.1f, 100.0f);
    mapping = view::ViewMapping(camera, view::GridSize{512, 512});
  }
};

void BM_ProjectHandWritten(benchmark::State& state) {
  const ProjectionScene scene;
  const std::size_t n = scene.positions.size() / 3;
  std::vector<std::uint32_t> cells(n);
  std::vector<float> clip_w(n);
  for (auto _ : state) {
    view::map_vertices(scene.mapping, scene.positions, cells, clip_w);
    benchmark::DoNotOptimize(cells.data());
    benchmark::DoNotOptimize(clip_w.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
}
BENCHMARK(BM_ProjectHandWritten)->Unit(benchmark::kMicrosecond);

void BM_ProjectGlm(benchmark::State& state) {
  const ProjectionScene scene;
  const std::size_t n = scene.positions.size() / 3;
  std::vector<std::uint32_t> cells(n);
  std::vector<float> clip_w(n);
  const glm::mat4 mvp = scene.mapping.model_view_projection();
  const float w = 512.0f, h = 512.0f;
  for (auto _ : state) {
    for (std::size_t v = 0; v < n; ++v) {
      const glm::vec4 clip = mvp * glm::vec4(scene.positions[3 * v], scene.positions[3 * v + 1],
                                             scene.positions[3 * v + 2], 1.0f);
      const glm::vec4 ndc = clip / clip.w;
      const float gx = (ndc.x + 1.0f) / 2.0f * w, gy = (1.0f - ndc.y) / 2.0f * h;
      const bool inside = clip.w > 0.0f && gx >= 0.0f && gx < w && gy >= 0.0f && gy < h;
      cells[v] =
          inside ? static_cast<std::uint32_t>(gy) * 512u + static_cast<std::uint32_t>(gx) : view::kNoCell;
      clip_w[v] = clip.w;
    }
    benchmark::DoNotOptimize(cells.data());
    benchmark::DoNotOptimize(clip_w.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
}
BENCHMARK(BM_ProjectGlm)->Unit(benchmark::kMicrosecond);

// The shared dragon meshes (loaded once), seen from the front so that the model fills ~80% of the view.
struct DragonScene {
  std::optional<model::Mesh> full;    // dragon-vrip-871k: 437,645 vertices, 871,414 triangles
  std::optional<model::Mesh> coarse;  // dragon-vrip-res4-11k: 11,102 triangles, a stand-in for a coarse cut
  view::Camera camera;
  static const DragonScene& get() {
    static const DragonScene scene;
    return scene;
  }

 private:
  DragonScene() {
    const std::filesystem::path dir = MTLOD_SHARED_MESHES_DIR;
    io::LoadOptions load;
    load.clean = false;  // keep vertex ids of the files
    if (auto m = io::load_mesh(dir / "dragon-vrip-871k.ply", load); m.ok()) full = std::move(m->mesh);
    if (auto m = io::load_mesh(dir / "dragon-vrip-res4-11k.ply", load); m.ok()) coarse = std::move(m->mesh);
    if (!full) return;
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (std::size_t v = 0; v < full->vertex_count(); ++v) {
      const glm::vec3 p(full->positions[3 * v], full->positions[3 * v + 1], full->positions[3 * v + 2]);
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
    const glm::vec3 centre = 0.5f * (lo + hi);
    const float radius = 0.5f * glm::length(hi - lo);
    camera.view = glm::lookAt(centre + glm::vec3(0.0f, 0.0f, 2.6f * radius), centre, glm::vec3(0, 1, 0));
    camera.projection = glm::perspective(glm::radians(45.0f), 1.0f, 0.1f * radius, 10.0f * radius);
  }
};

void BM_OccupancyDragon(benchmark::State& state) {
  const DragonScene& scene = DragonScene::get();
  const model::Mesh* mesh =
      state.range(1) == 0 ? (scene.full ? &*scene.full : nullptr) : (scene.coarse ? &*scene.coarse : nullptr);
  if (mesh == nullptr) {
    state.SkipWithError("shared dragon meshes not found");
    return;
  }
  const auto side = static_cast<std::uint32_t>(state.range(0));
  const view::ViewMapping mapping(scene.camera, view::GridSize{side, side});
  std::vector<std::uint8_t> occupancy(mapping.grid().cell_count());
  for (auto _ : state) {
    view::rasterize_occupancy(mapping, mesh->positions, mesh->triangles, occupancy);
    benchmark::DoNotOptimize(occupancy.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * mesh->triangle_count()));
  // How far the coarse mesh's occupancy is from the full one's: cells that differ, and full-mesh
  // vertices whose silhouette label (5-7-11) changes.
  if (mesh == &*scene.coarse && scene.full) {
    std::vector<std::uint8_t> reference(occupancy.size());
    view::rasterize_occupancy(mapping, scene.full->positions, scene.full->triangles, reference);
    std::size_t differing = 0, object = 0;
    for (std::size_t c = 0; c < occupancy.size(); ++c) {
      differing += occupancy[c] != reference[c];
      object += reference[c] != 0;
    }
    std::vector<std::uint16_t> dt(occupancy.size()), dt_reference(occupancy.size());
    view::chamfer_5_7_11(occupancy, mapping.grid(), dt);
    view::chamfer_5_7_11(reference, mapping.grid(), dt_reference);
    const std::size_t n = scene.full->vertex_count();
    std::vector<std::uint32_t> cells(n);
    std::vector<float> clip_w(n);
    view::map_vertices(mapping, scene.full->positions, cells, clip_w);
    std::size_t changed = 0, within_one_px = 0, labelled = 0;
    for (std::size_t v = 0; v < n; ++v) {
      if (cells[v] == view::kNoCell) continue;
      ++labelled;
      const int a = dt[cells[v]], b = dt_reference[cells[v]];
      changed += a != b;
      within_one_px += std::abs(a - b) <= 5;
    }
    state.counters["cells_differing_pct"] =
        100.0 * static_cast<double>(differing) / static_cast<double>(object);
    state.counters["labels_changed_pct"] =
        100.0 * static_cast<double>(changed) / static_cast<double>(labelled);
    state.counters["labels_off_by_gt1px_pct"] =
        100.0 * static_cast<double>(labelled - within_one_px) / static_cast<double>(labelled);
  }
}
// Args: grid side, mesh (0 = full 871k, 1 = the 11k stand-in for a coarse cut).
BENCHMARK(BM_OccupancyDragon)
    ->Args({256, 0})
    ->Args({512, 0})
    ->Args({256, 1})
    ->Args({512, 1})
    ->Unit(benchmark::kMillisecond);

// Allowed error of the 871k dragon at 256², silhouette (step, d = 2 px, f = 0) + focus (foveal),
// pixel bound. Full: every vertex through the SIMD projection. Lazy: only the vertices of a random
// set of triangles (a refinement touching that many triangles), projected one by one.
struct LabelScene {
  view::ViewMapping mapping;
  std::vector<std::uint16_t> silhouette, focus;
  view::AllowedErrorOptions options;
  explicit LabelScene(const DragonScene& dragon) {
    mapping = view::ViewMapping(dragon.camera, view::GridSize{256, 256});
    const view::GridSize grid = mapping.grid();
    std::vector<std::uint8_t> occupancy(grid.cell_count());
    view::rasterize_occupancy(mapping, dragon.coarse->positions, dragon.coarse->triangles, occupancy);
    silhouette.resize(grid.cell_count());
    focus.resize(grid.cell_count());
    view::DistanceTransformer transformer;
    transformer.chamfer(view::DistanceMetric::kChamfer5711, occupancy, grid, silhouette);
    const std::vector<std::uint32_t> foci = {view::focus_cell(grid, 0.5f, 0.4f)};
    transformer.chamfer_from_cells(view::DistanceMetric::kChamfer5711, foci, grid, focus);
    options.error = 1.0f;
    options.units = view::ErrorUnits::kScreenPixels;
    options.criteria[view::Criterion::kSilhouette] =
        view::RegionLaw{view::FalloffLaw::kStep, 2.0f, 0.0f, 0.0f, 2.3f};
    options.criteria[view::Criterion::kFocus] =
        view::RegionLaw{view::FalloffLaw::kFoveal, 0.0f, 0.2f, 0.0f, 2.3f};
  }
};

void BM_AllowedErrorFull(benchmark::State& state) {
  const DragonScene& dragon = DragonScene::get();
  if (!dragon.full || !dragon.coarse) {
    state.SkipWithError("shared dragon meshes not found");
    return;
  }
  const LabelScene scene(dragon);
  view::AllowedErrorField field;
  field.bind(scene.mapping, scene.options,
             {{scene.silhouette, scene.focus, {}}, dragon.full->positions, {}, {}});
  std::vector<float> allowed(dragon.full->vertex_count());
  for (auto _ : state) {
    field.compute_all(allowed);
    benchmark::DoNotOptimize(allowed.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * allowed.size()));
}
BENCHMARK(BM_AllowedErrorFull)->Unit(benchmark::kMicrosecond);

void BM_AllowedErrorLazy(benchmark::State& state) {
  const DragonScene& dragon = DragonScene::get();
  if (!dragon.full || !dragon.coarse) {
    state.SkipWithError("shared dragon meshes not found");
    return;
  }
  const LabelScene scene(dragon);
  view::AllowedErrorField field;
  field.bind(scene.mapping, scene.options,
             {{scene.silhouette, scene.focus, {}}, dragon.full->positions, {}, {}});
  // Touched triangles: random (arg 1 = 0) or a contiguous run in file order (arg 1 = 1).
  const auto touched = static_cast<std::size_t>(state.range(0));
  std::vector<std::uint32_t> triangles(touched);
  std::mt19937 rng(3);
  std::uniform_int_distribution<std::uint32_t> pick(
      0, static_cast<std::uint32_t>(dragon.full->triangle_count() - 1));
  for (std::size_t k = 0; k < touched; ++k)
    triangles[k] = state.range(1) == 0 ? pick(rng) : static_cast<std::uint32_t>(k);
  for (auto _ : state) {
    float sum = 0.0f;
    for (const std::uint32_t t : triangles) {
      const std::uint32_t* tri = dragon.full->triangles.data() + 3 * std::size_t{t};
      sum += std::min({field.vertex_allowed_error(tri[0]), field.vertex_allowed_error(tri[1]),
                       field.vertex_allowed_error(tri[2])});
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * 3 * touched));
}
// Args: triangles touched, order (0 random, 1 file order).
BENCHMARK(BM_AllowedErrorLazy)
    ->Args({10000, 0})
    ->Args({50000, 0})
    ->Args({150000, 0})
    ->Args({150000, 1})
    ->Unit(benchmark::kMicrosecond);

// The grid part of a request before refinement, 871k dragon at 256²: occupancy of the 11k stand-in
// for a coarse cut, silhouette 5-7-11, focus 5-7-11, and the full allowed-error array.
void BM_GridPipelineDragon256(benchmark::State& state) {
  const DragonScene& dragon = DragonScene::get();
  if (!dragon.full || !dragon.coarse) {
    state.SkipWithError("shared dragon meshes not found");
    return;
  }
  LabelScene scene(dragon);
  const view::GridSize grid = scene.mapping.grid();
  std::vector<std::uint8_t> occupancy(grid.cell_count());
  view::DistanceTransformer transformer;
  view::AllowedErrorField field;
  std::vector<float> allowed(dragon.full->vertex_count());
  const std::vector<std::uint32_t> foci = {view::focus_cell(grid, 0.5f, 0.4f)};
  for (auto _ : state) {
    view::rasterize_occupancy(scene.mapping, dragon.coarse->positions, dragon.coarse->triangles, occupancy);
    transformer.chamfer(view::DistanceMetric::kChamfer5711, occupancy, grid, scene.silhouette);
    transformer.chamfer_from_cells(view::DistanceMetric::kChamfer5711, foci, grid, scene.focus);
    field.bind(scene.mapping, scene.options,
               {{scene.silhouette, scene.focus, {}}, dragon.full->positions, {}, {}});
    field.compute_all(allowed);
    benchmark::DoNotOptimize(allowed.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * allowed.size()));
}
BENCHMARK(BM_GridPipelineDragon256)->Unit(benchmark::kMicrosecond);

// The whole per-request pipeline before encoding: 871k dragon at 256², occupancy of the
// 16k-triangle occupancy level (the one a request takes here), silhouette 5-7-11, labels and allowed
// error for every vertex (step law, d = 2 px, f = 0.25), and static refinement with a reused Refiner.
// The error bound is tuned once so that the cut has about 50k triangles. (BM_Request in
// bench_pipeline.cpp is the request as the server runs it, allowed error on demand.)
struct DragonMt {
  std::optional<model::Mt> mt;
  std::unique_ptr<view::OccupancyLevels> levels;
  view::Camera camera;
  float radius = 0.0f;
  // The occupancy level of at most `triangles` triangles.
  const view::OccupancyLevel& level(std::size_t triangles) const {
    const view::OccupancyLevel* found = &levels->levels().front();
    for (const view::OccupancyLevel& l : levels->levels())
      if (l.triangle_count() <= triangles) found = &l;
    return *found;
  }
  static const DragonMt& get() {
    static const DragonMt d;
    return d;
  }

 private:
  DragonMt() {
    const std::filesystem::path prepared = std::filesystem::path(MTLOD_MODELS_DIR) / "dragon-871k.mt";
    if (auto read = io::read_mt_file(prepared); read.ok()) {
      mt = std::move(read).value();
    } else {
      auto loaded = io::load_mesh(std::filesystem::path(MTLOD_SHARED_MESHES_DIR) / "dragon-vrip-871k.ply");
      if (!loaded.ok()) return;
      auto built = build::build_mt(loaded->mesh);
      if (!built.ok()) return;
      mt = std::move(built).value();
    }
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (std::size_t v = 0; v < mt->vertex_count(); ++v) {
      const glm::vec3 p(mt->positions[3 * v], mt->positions[3 * v + 1], mt->positions[3 * v + 2]);
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
    const glm::vec3 centre = 0.5f * (lo + hi);
    radius = 0.5f * glm::length(hi - lo);
    camera.view = glm::lookAt(centre + glm::vec3(0.0f, 0.0f, 2.6f * radius), centre, glm::vec3(0, 1, 0));
    camera.projection = glm::perspective(glm::radians(45.0f), 1.0f, 0.1f * radius, 10.0f * radius);
    levels = view::OccupancyLevels::make(*mt).value();  // in memory: cannot fail
  }
};

// Bisection on an error bound over [1e-5, 1] × radius (cut size falls as the bound grows) until
// run(bound), which refines with that bound, returns a cut size within 2 % of target; run's last
// call is with the bound found.
template <class Run>
void tune_error_for_size(float radius, std::size_t target, Run&& run) {
  float lo = 1e-5f * radius, hi = radius;
  for (int step = 0; step < 40; ++step) {
    const float bound = std::sqrt(lo * hi);
    const std::size_t size = run(bound);
    if (size > target + target / 50)
      lo = bound;
    else if (size < target - target / 50)
      hi = bound;
    else
      break;
  }
}

void BM_RequestPipelineDragon256(benchmark::State& state) {
  const DragonMt& dragon = DragonMt::get();
  if (!dragon.mt) {
    state.SkipWithError("no dragon MT (models dir) and no shared dragon mesh");
    return;
  }
  const model::Mt& mt = *dragon.mt;
  const view::ViewMapping mapping(dragon.camera, view::GridSize{256, 256});
  const view::GridSize grid = mapping.grid();
  cut::CutMesh cut;
  const view::OccupancyLevel& level = dragon.level(16384);
  std::vector<view::ProjectedCorner> projected;
  std::vector<std::uint8_t> occupancy(grid.cell_count());
  std::vector<std::uint16_t> silhouette(grid.cell_count());
  std::vector<float> allowed(mt.vertex_count());
  view::DistanceTransformer transformer;
  view::AllowedErrorField field;
  cut::Refiner refiner(mt);
  view::AllowedErrorOptions options;
  options.criteria[view::Criterion::kSilhouette] =
      view::RegionLaw{view::FalloffLaw::kStep, 2.0f, 0.25f, 0.0f, 2.3f};
  auto request = [&] {
    view::rasterize_occupancy_compact(mapping, level.positions, level.triangles, occupancy, {}, projected,
                                      level.closed);
    transformer.chamfer(view::DistanceMetric::kChamfer5711, occupancy, grid, silhouette);
    field.bind(mapping, options, {{silhouette, {}, {}}, mt.positions, {}, {}});
    field.compute_all(allowed);
    refined(refiner.refine(cut::Refinement::from_root(cut::AllowedError::from_vertices(allowed)), cut));
  };
  tune_error_for_size(dragon.radius, 50'000, [&](float bound) {
    options.error = bound;
    request();
    return cut.triangle_count();
  });
  for (auto _ : state) {
    request();
    benchmark::DoNotOptimize(cut.triangles.data());
  }
  state.counters["cut_triangles"] = static_cast<double>(cut.triangle_count());
  state.counters["occupancy_triangles"] = static_cast<double>(level.triangle_count());
  state.counters["error_over_radius"] = options.error / dragon.radius;
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()));
}
BENCHMARK(BM_RequestPipelineDragon256)->Unit(benchmark::kMillisecond);

// Occupancy from the coarse cuts requests rasterise (core::OccupancyLevels; arg: the level's
// triangle budget) for the dragon at 256², and how far the silhouette labels of the full-resolution
// vertices move from those of the full mesh's occupancy: share of vertices whose label changes at
// all, and by more than 1 px. Chosen by size, not by error bound, so the rows stay the levels a
// request uses whatever scale the builder's errors have.
void BM_OccupancyFromMtCut256(benchmark::State& state) {
  const DragonMt& dragon = DragonMt::get();
  if (!dragon.mt) {
    state.SkipWithError("no dragon MT");
    return;
  }
  const model::Mt& mt = *dragon.mt;
  const view::OccupancyLevel* level = &dragon.level(static_cast<std::size_t>(state.range(0)));
  const view::ViewMapping mapping(dragon.camera, view::GridSize{256, 256});
  const view::GridSize grid = mapping.grid();
  cut::CutMesh full;
  cut::refine_static(mt, cut::AllowedError::everywhere(-1.0f), full);
  std::vector<view::ProjectedCorner> projected;
  std::vector<std::uint8_t> occupancy(grid.cell_count()), reference(grid.cell_count());
  for (auto _ : state) {
    view::rasterize_occupancy_compact(mapping, level->positions, level->triangles, occupancy, {}, projected,
                                      level->closed);
    benchmark::DoNotOptimize(occupancy.data());
  }
  view::rasterize_occupancy(mapping, mt.positions, full.triangles, reference);
  std::vector<std::uint16_t> dt(grid.cell_count()), dt_reference(grid.cell_count());
  view::chamfer_5_7_11(occupancy, grid, dt);
  view::chamfer_5_7_11(reference, grid, dt_reference);
  std::vector<std::uint32_t> cells(mt.vertex_count());
  std::vector<float> clip_w(mt.vertex_count());
  view::map_vertices(mapping, mt.positions, cells, clip_w);
  std::size_t labelled = 0, changed = 0, far = 0, cells_differing = 0, object = 0;
  for (std::size_t v = 0; v < cells.size(); ++v) {
    if (cells[v] == view::kNoCell) continue;
    ++labelled;
    const int a = dt[cells[v]], b = dt_reference[cells[v]];
    changed += a != b;
    far += std::abs(a - b) > 5;
  }
  for (std::size_t c = 0; c < occupancy.size(); ++c) {
    cells_differing += occupancy[c] != reference[c];
    object += reference[c] != 0;
  }
  state.counters["cells_differing_pct"] =
      100.0 * static_cast<double>(cells_differing) / static_cast<double>(object);
  state.counters["labels_changed_pct"] = 100.0 * static_cast<double>(changed) / static_cast<double>(labelled);
  state.counters["labels_off_gt1px_pct"] = 100.0 * static_cast<double>(far) / static_cast<double>(labelled);
  state.counters["cut_triangles"] = static_cast<double>(level->triangle_count());
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * level->triangle_count()));
}
BENCHMARK(BM_OccupancyFromMtCut256)
    ->Arg(4096)
    ->Arg(8192)
    ->Arg(16384)
    ->Arg(32768)
    ->Arg(65536)
    ->Arg(131072)
    ->Unit(benchmark::kMillisecond);

// Hidden-surface coarsening's extra work on the dragon at 256²: the 16k level rasterised with depths
// (every triangle: no one-sided shortcut), the 3×3 bound, and the share of the in-view vertices the
// allowed-error stage then finds hidden.
void BM_VisibleDepthDragon256(benchmark::State& state) {
  const DragonMt& dragon = DragonMt::get();
  if (!dragon.mt) {
    state.SkipWithError("no dragon MT");
    return;
  }
  const model::Mt& mt = *dragon.mt;
  const view::OccupancyLevel& level = dragon.level(16384);
  const view::ViewMapping mapping(dragon.camera, view::GridSize{256, 256});
  const view::GridSize grid = mapping.grid();
  std::vector<view::ProjectedCorner> projected;
  std::vector<std::uint8_t> occupancy(grid.cell_count());
  std::vector<float> depth(grid.cell_count()), visible(grid.cell_count());
  for (auto _ : state) {
    view::rasterize_occupancy_compact(mapping, level.positions, level.cut_triangles(), occupancy, depth,
                                      projected);
    view::visible_depth_bound(depth, grid, visible);
    benchmark::DoNotOptimize(visible.data());
  }
  view::AllowedErrorOptions options;
  options.hidden_factor = 2.0f;
  std::vector<float> allowed(mt.vertex_count());
  view::compute_vertex_allowed_error(mapping, options, {{}, mt.positions, {}, visible}, allowed);
  std::vector<std::uint32_t> cells(mt.vertex_count());
  std::vector<float> clip_w(mt.vertex_count());
  view::map_vertices(mapping, mt.positions, cells, clip_w);
  std::size_t in_view = 0, hidden = 0;
  for (std::size_t v = 0; v < cells.size(); ++v) {
    if (cells[v] == view::kNoCell) continue;
    ++in_view;
    hidden += allowed[v] == 2.0f;
  }
  state.counters["hidden_pct"] = 100.0 * static_cast<double>(hidden) / static_cast<double>(in_view);
  state.counters["cut_triangles"] = static_cast<double>(level.triangle_count());
}
BENCHMARK(BM_VisibleDepthDragon256)->Unit(benchmark::kMillisecond);

// The refinement alone, with the allowed errors of the pipeline above (for the breakdown).
void BM_RefineOnlyDragon256(benchmark::State& state) {
  const DragonMt& dragon = DragonMt::get();
  if (!dragon.mt) {
    state.SkipWithError("no dragon MT");
    return;
  }
  const model::Mt& mt = *dragon.mt;
  const view::ViewMapping mapping(dragon.camera, view::GridSize{256, 256});
  cut::CutMesh cut;
  const view::OccupancyLevel& level = dragon.level(16384);
  std::vector<view::ProjectedCorner> projected;
  std::vector<std::uint8_t> occupancy(mapping.grid().cell_count());
  std::vector<std::uint16_t> silhouette(occupancy.size());
  view::rasterize_occupancy_compact(mapping, level.positions, level.triangles, occupancy, {}, projected,
                                    level.closed);
  view::chamfer_5_7_11(occupancy, mapping.grid(), silhouette);
  view::AllowedErrorOptions options;
  options.criteria[view::Criterion::kSilhouette] =
      view::RegionLaw{view::FalloffLaw::kStep, 2.0f, 0.25f, 0.0f, 2.3f};
  std::vector<float> allowed(mt.vertex_count());
  cut::Refiner refiner(mt);
  tune_error_for_size(dragon.radius, static_cast<std::size_t>(state.range(0)), [&](float bound) {
    options.error = bound;
    view::compute_vertex_allowed_error(mapping, options, {{silhouette, {}, {}}, mt.positions, {}, {}},
                                       allowed);
    refined(refiner.refine(cut::Refinement::from_root(cut::AllowedError::from_vertices(allowed)), cut));
    return cut.triangle_count();
  });
  for (auto _ : state) {
    refined(refiner.refine(cut::Refinement::from_root(cut::AllowedError::from_vertices(allowed)), cut));
    benchmark::DoNotOptimize(cut.triangles.data());
  }
  state.counters["cut_triangles"] = static_cast<double>(cut.triangle_count());
}
// Arg: the cut's size (the error bound is tuned for it).
BENCHMARK(BM_RefineOnlyDragon256)->Arg(10'000)->Arg(50'000)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace mtlod::core

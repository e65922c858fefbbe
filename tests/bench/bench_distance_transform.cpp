// Benchmarks of the per-request grid stages (DESIGN.md §1): the papers' two-pass 5-7-11 chamfer and the
// exact Euclidean transform against OpenCV's cv::distanceTransform on the same images (one thread),
// and the projection of 1M vertices hand-written against a generic glm::mat4 product.
// Items are grid cells (transforms) or vertices (projection).
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

#include "core/distance_transform.hpp"
#include "core/view_grid.hpp"

namespace mtlod::core {
namespace {

// Random discs covering about half of the image, fixed seed: object cells are 1, background 0.
std::vector<std::uint8_t> blob_image(GridSize grid) {
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
  const GridSize grid{side, side};
  const auto image = blob_image(grid);
  std::vector<std::uint16_t> out(grid.cell_count());
  DistanceTransformer transformer;
  for (auto _ : state) {
    transformer.chamfer(DistanceMetric::kChamfer5711, image, grid, out);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * grid.cell_count()));
}
BENCHMARK(BM_Chamfer5711)->Arg(256)->Arg(512)->Arg(1024)->Arg(2048)->Unit(benchmark::kMicrosecond);

void BM_Chamfer34(benchmark::State& state) {
  const auto side = static_cast<std::uint32_t>(state.range(0));
  const GridSize grid{side, side};
  const auto image = blob_image(grid);
  std::vector<std::uint16_t> out(grid.cell_count());
  DistanceTransformer transformer;
  for (auto _ : state) {
    transformer.chamfer(DistanceMetric::kChamfer34, image, grid, out);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * grid.cell_count()));
}
BENCHMARK(BM_Chamfer34)->Arg(512)->Unit(benchmark::kMicrosecond);

void BM_EuclideanSquared(benchmark::State& state) {
  const auto side = static_cast<std::uint32_t>(state.range(0));
  const GridSize grid{side, side};
  const auto image = blob_image(grid);
  std::vector<std::uint32_t> out(grid.cell_count());
  DistanceTransformer transformer;
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
  const GridSize grid{side, side};
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
  ViewMapping mapping;
  ProjectionScene() {
    std::mt19937 rng(99);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    positions.resize(3 * 1000000);
    for (float& p : positions) p = u(rng);
    Camera camera;
    camera.view = glm::lookAt(glm::vec3(0.5f, 0.8f, 3.0f), glm::vec3(0.0f), glm::vec3(0.0f, 1.0f, 0.0f));
    camera.projection = glm::perspective(glm::radians(45.0f), 1.0f, 0.1f, 100.0f);
    mapping = ViewMapping(camera, GridSize{512, 512});
  }
};

void BM_ProjectHandWritten(benchmark::State& state) {
  const ProjectionScene scene;
  const std::size_t n = scene.positions.size() / 3;
  std::vector<std::uint32_t> cells(n);
  std::vector<float> clip_w(n);
  for (auto _ : state) {
    map_vertices(scene.mapping, scene.positions, cells, clip_w);
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
      cells[v] = inside ? static_cast<std::uint32_t>(gy) * 512u + static_cast<std::uint32_t>(gx) : kNoCell;
      clip_w[v] = clip.w;
    }
    benchmark::DoNotOptimize(cells.data());
    benchmark::DoNotOptimize(clip_w.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
}
BENCHMARK(BM_ProjectGlm)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace mtlod::core

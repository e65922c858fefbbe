// Image-space metrics (core/eval/image_metrics): SSIM, mean absolute error and their foveated
// variants on analytic images whose answers are known by hand — identical images, a constant
// offset, a shifted square, a blurred step — SSIM against a direct evaluation of the paper's
// definition, the acuity weights against closed-form angles, and renderings of a real MT: the model
// against itself, against uniform cuts, and against a cut refined around the focus.
#include "core/eval/image_metrics.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>

#include "core/cut/refine.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/eval/render.hpp"
#include "core/view/allowed_error.hpp"
#include "core/view/occupancy_levels.hpp"
#include "core/view/view_extract.hpp"
#include "core/view/view_grid.hpp"
#include "tests/core/mt_fixtures.hpp"

namespace mtlod::core {
namespace {

constexpr double kC1 = 0.01 * 0.01, kC2 = 0.03 * 0.03;  // the paper's constants for L = 1

// A smooth pattern plus uniform noise in [0, 1], fixed seed.
std::vector<float> textured_image(view::GridSize size, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> noise(-0.15f, 0.15f);
  std::vector<float> img(size.cell_count());
  for (std::uint32_t j = 0; j < size.height; ++j)
    for (std::uint32_t i = 0; i < size.width; ++i)
      img[size.cell(i, j)] = std::clamp(
          0.5f + 0.3f * std::sin(0.3f * float(i)) * std::cos(0.2f * float(j)) + noise(rng), 0.0f, 1.0f);
  return img;
}

// SSIM map straight from the paper's definition with its 2D Gaussian window:
// for each window wholly inside the image, the weighted means, then the weighted variances and
// covariance about them, then the product formula. No separable filtering, no shared terms.
std::vector<double> direct_ssim_map(const std::vector<float>& a, const std::vector<float>& b,
                                    view::GridSize size) {
  const int r = 5;
  double w[11][11], total = 0;
  for (int y = -r; y <= r; ++y)
    for (int x = -r; x <= r; ++x) total += w[y + r][x + r] = std::exp(-(x * x + y * y) / (2 * 1.5 * 1.5));
  std::vector<double> map;
  for (int cy = r; cy + r < int(size.height); ++cy) {
    for (int cx = r; cx + r < int(size.width); ++cx) {
      const auto at = [&](const std::vector<float>& img, int dx, int dy) {
        return double(img[std::size_t(cy + dy) * size.width + std::size_t(cx + dx)]);
      };
      double ma = 0, mb = 0;
      for (int y = -r; y <= r; ++y)
        for (int x = -r; x <= r; ++x) {
          ma += w[y + r][x + r] / total * at(a, x, y);
          mb += w[y + r][x + r] / total * at(b, x, y);
        }
      double va = 0, vb = 0, cov = 0;
      for (int y = -r; y <= r; ++y)
        for (int x = -r; x <= r; ++x) {
          const double wt = w[y + r][x + r] / total, da = at(a, x, y) - ma, db = at(b, x, y) - mb;
          va += wt * da * da, vb += wt * db * db, cov += wt * da * db;
        }
      map.push_back((2 * ma * mb + kC1) * (2 * cov + kC2) / ((ma * ma + mb * mb + kC1) * (va + vb + kC2)));
    }
  }
  return map;
}

double mean(const std::vector<double>& v) {
  double s = 0;
  for (const double x : v) s += x;
  return s / double(v.size());
}

TEST(Ssim, MapSizeLeavesOutTheBorderWindows) {
  const view::GridSize m = eval::ssim_map_size({40, 30});
  EXPECT_EQ(m.width, 30u);  // window centres 5 … 34
  EXPECT_EQ(m.height, 20u);
  EXPECT_EQ(eval::ssim_map_size({11, 11}).cell_count(), 1u);
}

TEST(Ssim, IdenticalImagesScoreExactlyOne) {
  const view::GridSize size{40, 32};
  const std::vector<float> a = textured_image(size, 7);
  std::vector<float> map(eval::ssim_map_size(size).cell_count());
  EXPECT_EQ(eval::ssim(a, a, size, map), 1.0);
  for (const float s : map) ASSERT_EQ(s, 1.0f);
  EXPECT_EQ(eval::mean_absolute_error(a, a), 0.0);
  std::vector<float> weights(size.cell_count());
  eval::foveation_weights(size, {10.5f, 20.5f, 50.0, 2.3}, weights);
  const eval::ImageComparison c = eval::compare_images(a, a, size, {}, weights, map);
  EXPECT_EQ(c.ssim, 1.0);
  EXPECT_EQ(c.foveated_ssim, 1.0);
  EXPECT_EQ(c.mae, 0.0);
  EXPECT_EQ(c.foveated_mae, 0.0);
  EXPECT_EQ(c.covered_pixels, size.cell_count());
}

TEST(Ssim, ConstantOffsetGivesTheLuminanceTerm) {
  // Two flat images: no variance, so the structure term is C2/C2 = 1 and every window's SSIM is the
  // luminance term l = (2·μa·μb + C1)/(μa² + μb² + C1) of the two levels.
  const view::GridSize size{32, 24};
  const float lo = 0.25f, hi = 0.375f;  // both exact in binary: the offset is exactly 0.125
  const std::vector<float> a(size.cell_count(), lo), b(size.cell_count(), hi);
  const double l = (2.0 * lo * hi + kC1) / (double(lo) * lo + double(hi) * hi + kC1);
  std::vector<float> map(eval::ssim_map_size(size).cell_count());
  // The window's weights sum to 1 only up to rounding (a few 1e-16), hence the tolerance.
  EXPECT_NEAR(eval::ssim(a, b, size, map), l, 1e-12);
  EXPECT_LT(l, 1.0);
  EXPECT_EQ(eval::mean_absolute_error(a, b), 0.125);
  EXPECT_EQ(eval::mean_absolute_error(b, a), 0.125);
}

TEST(Ssim, MatchesTheDefinitionEvaluatedDirectly) {
  const view::GridSize size{37, 29};
  const std::vector<float> a = textured_image(size, 1), b = textured_image(size, 2);
  std::vector<float> map(eval::ssim_map_size(size).cell_count());
  const double s = eval::ssim(a, b, size, map);
  const std::vector<double> expected = direct_ssim_map(a, b, size);
  ASSERT_EQ(expected.size(), map.size());
  // The map is stored in float: agreement to float precision.
  for (std::size_t k = 0; k < map.size(); ++k) ASSERT_NEAR(map[k], expected[k], 1e-6) << k;
  // The mean is accumulated in double from the unrounded values; the two orders of evaluation
  // differ by cancellation in the variances only (values in [0, 1], double precision).
  EXPECT_NEAR(s, mean(expected), 1e-12);
  EXPECT_LT(s, 0.9);  // unrelated noise: far from identical
  // Symmetric in its arguments (the definition is).
  EXPECT_NEAR(eval::ssim(b, a, size), s, 1e-15);
}

// A light square on a dark background, its left column at x0.
std::vector<float> square_image(view::GridSize size, std::uint32_t x0, float background, float square) {
  std::vector<float> img(size.cell_count(), background);
  for (std::uint32_t j = 22; j < 42; ++j)
    for (std::uint32_t i = x0; i < x0 + 20; ++i) img[size.cell(i, j)] = square;
  return img;
}

TEST(ImageMetrics, ShiftedSquareHasTheCountedError) {
  const view::GridSize size{64, 64};
  const float background = 0.2f, square = 0.8f;
  const double contrast = double(square) - double(background);
  const std::vector<float> a = square_image(size, 20, background, square);
  double last_ssim = 1.0;
  for (const std::uint32_t k : {1u, 2u, 3u, 4u}) {
    const std::vector<float> b = square_image(size, 20 + k, background, square);
    // The 20-row square moved k columns: a k-wide strip on each side changed, 2·k·20 pixels.
    std::size_t changed = 0, covered = 0;
    std::vector<std::uint8_t> mask(size.cell_count());
    for (std::size_t c = 0; c < a.size(); ++c) {
      changed += a[c] != b[c];
      mask[c] = a[c] == square || b[c] == square;
      covered += mask[c];
    }
    ASSERT_EQ(changed, 2u * k * 20u);
    ASSERT_EQ(covered, 20u * (20u + k));
    EXPECT_NEAR(eval::mean_absolute_error(a, b), double(changed) * contrast / double(size.cell_count()),
                1e-15);
    EXPECT_NEAR(eval::mean_absolute_error(a, b, {mask, {}}), double(changed) * contrast / double(covered),
                1e-15);

    // Windows that see no changed pixel compare equal pixels, and score exactly 1; every other < 1.
    const view::GridSize m = eval::ssim_map_size(size);
    std::vector<float> map(m.cell_count());
    const double s = eval::ssim(a, b, size, map);
    for (std::uint32_t j = 0; j < m.height; ++j) {
      for (std::uint32_t i = 0; i < m.width; ++i) {
        bool touched = false;
        for (std::uint32_t y = j; y < j + 11; ++y)
          for (std::uint32_t x = i; x < i + 11; ++x) touched |= a[size.cell(x, y)] != b[size.cell(x, y)];
        if (touched)
          ASSERT_LT(map[m.cell(i, j)], 1.0f) << i << "," << j;
        else
          ASSERT_EQ(map[m.cell(i, j)], 1.0f) << i << "," << j;
      }
    }
    // A larger shift changes more pixels and scores lower.
    EXPECT_LT(s, last_ssim) << "shift " << k;
    last_ssim = s;
  }
}

TEST(ImageMetrics, BoxBlurredStepHasTheHandComputedError) {
  // A vertical step of contrast Δ between columns 31 and 32, each row blurred by a box of width
  // 2r + 1. Left of the edge, column 32 − m (m = 1 … r) gains (r + 1 − m) bright pixels of 2r + 1;
  // right of it, column 31 + m loses as many: the errors per row sum to 2·Δ·(1 + … + r)/(2r + 1) =
  // Δ·r(r + 1)/(2r + 1), so MAE = Δ·r(r + 1)/((2r + 1)·W).
  const view::GridSize size{64, 48};
  const float lo = 0.2f, hi = 0.8f;
  const double contrast = double(hi) - double(lo);
  std::vector<float> step(size.cell_count());
  for (std::uint32_t j = 0; j < size.height; ++j)
    for (std::uint32_t i = 0; i < size.width; ++i) step[size.cell(i, j)] = i < 32 ? lo : hi;
  double last_ssim = 1.0;
  for (const int r : {1, 2, 3, 4, 6}) {
    std::vector<float> blurred(step.size());
    for (std::uint32_t j = 0; j < size.height; ++j) {
      for (int i = 0; i < int(size.width); ++i) {
        float sum = 0;  // the border columns repeat: the flat sides stay flat
        for (int k = -r; k <= r; ++k) sum += step[size.cell(std::uint32_t(std::clamp(i + k, 0, 63)), j)];
        blurred[size.cell(std::uint32_t(i), j)] = sum / float(2 * r + 1);
      }
    }
    const double expected = contrast * r * (r + 1) / ((2.0 * r + 1) * size.width);
    // The blurred values are floats: each carries a rounding error below 1e-7.
    EXPECT_NEAR(eval::mean_absolute_error(step, blurred), expected, 1e-7) << "r = " << r;
    const double s = eval::ssim(step, blurred, size);
    EXPECT_LT(s, last_ssim) << "r = " << r;  // more blur, less structure kept
    last_ssim = s;
  }
  EXPECT_LT(last_ssim, 0.95);
}

TEST(ImageMetrics, EmptyWeightingMeansNothingToCompare) {
  const view::GridSize size{16, 16};
  const std::vector<float> a = textured_image(size, 3), b = textured_image(size, 4);
  const std::vector<std::uint8_t> none(size.cell_count(), 0);
  std::vector<float> map(eval::ssim_map_size(size).cell_count());
  eval::ssim(a, b, size, map);
  EXPECT_EQ(eval::mean_absolute_error(a, b, {none, {}}), 0.0);
  EXPECT_EQ(eval::weighted_ssim(map, size, {none, {}}), 1.0);
}

TEST(Luminance, Bt601Luma) {
  const std::vector<std::uint8_t> rgb = {255, 255, 255, 0, 0, 0, 255, 0, 0, 0, 255, 0, 0, 0, 255, 51, 51, 51};
  std::vector<float> y(6);
  eval::luminance_from_rgb(rgb, y);
  EXPECT_FLOAT_EQ(y[0], 1.0f);
  EXPECT_EQ(y[1], 0.0f);
  EXPECT_FLOAT_EQ(y[2], 0.299f);
  EXPECT_FLOAT_EQ(y[3], 0.587f);
  EXPECT_FLOAT_EQ(y[4], 0.114f);
  EXPECT_FLOAT_EQ(y[5], 0.2f);  // grey 51 = 0.2 · 255
}

TEST(Foveation, EccentricityIsTheAngleBetweenRays) {
  // An odd image: its centre (32.5, 32.5) is the centre of pixel (32, 32).
  const view::GridSize size{65, 65};
  const double focal = eval::focal_px_from_fov(65, 40.0);
  EXPECT_NEAR(focal, 32.5 / std::tan(20.0 * std::numbers::pi / 180), 1e-12);
  EXPECT_NEAR(eval::focal_px_from_fov(100, 90.0), 50.0, 1e-12);
  const auto degrees = [](double radians) { return radians * 180 / std::numbers::pi; };
  // Focus at the centre: a point d pixels away along a row is atan(d/focal) off the axis.
  eval::Foveation f{32.5f, 32.5f, focal, 2.3};
  EXPECT_EQ(eval::pixel_eccentricity_deg(size, f, 32.5, 32.5), 0.0);
  for (const double d : {1.0, 10.0, 30.0})
    EXPECT_NEAR(eval::pixel_eccentricity_deg(size, f, 32.5 + d, 32.5), degrees(std::atan(d / focal)), 1e-12);
  // The server's foveal law computes the same angle for a focus at the view centre (in float).
  const float tan_per_px = float(2 * std::tan(20.0 * std::numbers::pi / 180) / 65);
  EXPECT_NEAR(eval::pixel_eccentricity_deg(size, f, 32.5, 32.5 - 30),
              view::eccentricity_deg(30.0f, tan_per_px), 1e-4);
  // Off the axis: two points on the horizontal line through the centre are atan(x2/focal) −
  // atan(x1/focal) apart, not (x2 − x1)/focal.
  f.focus_x_px = 32.5f + 10;
  EXPECT_NEAR(eval::pixel_eccentricity_deg(size, f, 32.5 + 40, 32.5),
              degrees(std::atan(40 / focal) - std::atan(10 / focal)), 1e-12);
  // Symmetric in focus and point.
  f = {5.5f, 60.5f, focal, 2.3};
  const eval::Foveation g{50.5f, 3.5f, focal, 2.3};
  EXPECT_NEAR(eval::pixel_eccentricity_deg(size, f, 50.5, 3.5),
              eval::pixel_eccentricity_deg(size, g, 5.5, 60.5), 1e-12);
}

TEST(Foveation, AcuityWeightsFollowGeislerPerry) {
  EXPECT_EQ(eval::acuity_weight(0.0, 2.3), 1.0);
  EXPECT_DOUBLE_EQ(eval::acuity_weight(2.3, 2.3), 0.5);  // acuity halves at e2
  EXPECT_DOUBLE_EQ(eval::acuity_weight(20.7, 2.3), 0.1);
  const view::GridSize size{65, 65};
  const double focal = eval::focal_px_from_fov(65, 40.0);
  const eval::Foveation f{20.5f, 40.5f, focal, 2.3};
  std::vector<float> w(size.cell_count());
  eval::foveation_weights(size, f, w);
  EXPECT_EQ(w[size.cell(20, 40)], 1.0f);  // the focus pixel
  EXPECT_EQ(*std::max_element(w.begin(), w.end()), 1.0f);
  // Falling with the distance from the focus along its row.
  for (std::uint32_t i = 21; i < 65; ++i) ASSERT_LT(w[size.cell(i, 40)], w[size.cell(i - 1, 40)]);
}

TEST(Foveation, AnErrorAtTheFocusWeighsMoreThanTheSameErrorAway) {
  const view::GridSize size{97, 97};
  const double focal = eval::focal_px_from_fov(97, 40.0);
  const eval::Foveation f{48.5f, 48.5f, focal, 2.3};  // focus on pixel (48, 48), the centre
  std::vector<float> w(size.cell_count());
  eval::foveation_weights(size, f, w);
  const std::vector<float> flat(size.cell_count(), 0.5f);
  std::vector<float> near_error = flat, far_error = flat;
  near_error[size.cell(48, 48)] = 0.75f;  // the same error of 0.25 ...
  far_error[size.cell(78, 48)] = 0.75f;   // ... 30 pixels to the right, 13 from the border
  const double e_far = std::atan(30 / focal) * 180 / std::numbers::pi;
  const double near_mae = eval::mean_absolute_error(flat, near_error, {{}, w});
  const double far_mae = eval::mean_absolute_error(flat, far_error, {{}, w});
  // The same total weight divides both, so the ratio is the acuity ratio w(e_far)/w(0) (the weights
  // are floats: 1e-7 relative).
  EXPECT_NEAR(far_mae / near_mae, 2.3 / (2.3 + e_far), 1e-6);
  // Unweighted, the two errors are the same.
  EXPECT_EQ(eval::mean_absolute_error(flat, near_error), eval::mean_absolute_error(flat, far_error));

  // SSIM: both maps hold the same values (a translated single-pixel difference, every window inside
  // the image), so the plain means agree; weighted, the error at the focus costs more.
  std::vector<float> near_map(eval::ssim_map_size(size).cell_count()), far_map(near_map.size());
  const double near_ssim = eval::ssim(flat, near_error, size, near_map);
  const double far_ssim = eval::ssim(flat, far_error, size, far_map);
  EXPECT_NEAR(near_ssim, far_ssim, 1e-12);
  EXPECT_LT(near_ssim, 1.0);
  const double near_fov = eval::weighted_ssim(near_map, size, {{}, w});
  const double far_fov = eval::weighted_ssim(far_map, size, {{}, w});
  EXPECT_LT(near_fov, far_fov);
  EXPECT_LT(far_fov, 1.0);
}

// ---------------------------------------------------------------------------------------------
// Renderings of real MTs from one camera: the full model and cuts of it, shaded with the full
// model's normals (a cut's vertices are the model's).

struct ModelCase {
  model::Mesh mesh;  // numbered like the MT
  model::Mt mt;
  std::unique_ptr<view::OccupancyLevels> levels;
  std::vector<float> normals;  // the full model's, per MT vertex
};

std::unique_ptr<ModelCase> build_case(const eval::GenerateOptions& options) {
  auto s = std::make_unique<ModelCase>();
  s->mesh = eval::generate_mesh(options);
  auto mt = test::build_mt_renumbering(s->mesh);
  EXPECT_TRUE(mt.ok());
  s->mt = std::move(*mt);
  s->levels = view::OccupancyLevels::make(s->mt).value();  // in memory: cannot fail
  s->normals.resize(s->mesh.positions.size());
  eval::area_weighted_normals(s->mesh.positions, s->mesh.triangles, s->normals);
  return s;
}

// A noisy sphere seen whole (silhouettes), and a terrain seen from above filling the view.
const ModelCase& sphere_case() {
  static const std::unique_ptr<ModelCase> c = build_case({eval::Shape::kSphere, 3000, 3, 0.08f, false});
  return *c;
}
const ModelCase& terrain_case() {
  static const std::unique_ptr<ModelCase> c = build_case({eval::Shape::kTerrain, 5000, 5, 0.05f, false});
  return *c;
}

constexpr std::uint32_t kImagePx = 192;

struct View {
  view::Camera camera;
  float fov_deg = 40.0f;
};

View sphere_view() {
  View v;
  v.camera.view = glm::lookAt(glm::vec3(0.3f, 0.4f, 3.4f), glm::vec3(0, 0, 0), glm::vec3(0, 1, 0));
  v.camera.projection = glm::perspective(glm::radians(v.fov_deg), 1.0f, 0.5f, 10.0f);
  return v;
}

// 1.2 above the terrain's middle with a 60° field of view: the view ends about 0.7 from the middle,
// inside the [−1, 1]² terrain, so the whole image is surface.
View terrain_view() {
  View v;
  v.fov_deg = 60.0f;
  v.camera.view = glm::lookAt(glm::vec3(0.0f, 0.0f, 1.2f), glm::vec3(0, 0, 0), glm::vec3(0, 1, 0));
  v.camera.projection = glm::perspective(glm::radians(v.fov_deg), 1.0f, 0.1f, 10.0f);
  return v;
}

struct Rendering {
  std::vector<float> luminance, depth;
};

Rendering render(const ModelCase& s, const View& view, std::span<const std::uint32_t> triangles) {
  const view::ViewMapping mapping(view.camera, {kImagePx, kImagePx});
  eval::RenderOptions options;
  options.vertex_normals = s.normals;
  std::vector<std::uint8_t> rgb(3 * mapping.grid().cell_count());
  Rendering out{std::vector<float>(mapping.grid().cell_count()),
                std::vector<float>(mapping.grid().cell_count())};
  eval::render_mesh(mapping, s.mt.positions, triangles, {}, options, rgb, out.depth);
  eval::luminance_from_rgb(rgb, out.luminance);
  return out;
}

eval::ImageComparison compare(const Rendering& a, const Rendering& b, const View& view,
                              std::array<float, 2> focus01) {
  const view::GridSize size{kImagePx, kImagePx};
  std::vector<std::uint8_t> covered(size.cell_count());
  for (std::size_t c = 0; c < covered.size(); ++c)
    covered[c] = std::isfinite(a.depth[c]) || std::isfinite(b.depth[c]);
  std::vector<float> weights(size.cell_count()), map(eval::ssim_map_size(size).cell_count());
  eval::foveation_weights(size,
                          {focus01[0] * float(kImagePx), focus01[1] * float(kImagePx),
                           eval::focal_px_from_fov(kImagePx, view.fov_deg), 2.3},
                          weights);
  return eval::compare_images(a.luminance, b.luminance, size, covered, weights, map);
}

TEST(ImageMetricsRender, ModelAgainstItselfIsPerfect) {
  const ModelCase& s = sphere_case();
  const Rendering full = render(s, sphere_view(), s.mesh.triangles);
  std::size_t covered = 0;
  for (const float d : full.depth) covered += std::isfinite(d);
  ASSERT_GT(covered, kImagePx * kImagePx / 5);  // the sphere fills a good part of the view
  ASSERT_LT(covered, kImagePx * kImagePx);
  const eval::ImageComparison c = compare(full, full, sphere_view(), {0.5f, 0.5f});
  EXPECT_EQ(c.ssim, 1.0);
  EXPECT_EQ(c.ssim_covered, 1.0);
  EXPECT_EQ(c.foveated_ssim, 1.0);
  EXPECT_EQ(c.mae, 0.0);
  EXPECT_EQ(c.mae_covered, 0.0);
  EXPECT_EQ(c.foveated_mae, 0.0);
  EXPECT_EQ(c.covered_pixels, covered);
}

TEST(ImageMetricsRender, CoarserUniformCutsScoreWorse) {
  const ModelCase& s = sphere_case();
  const Rendering full = render(s, sphere_view(), s.mesh.triangles);
  cut::Refiner refiner(s.mt);
  cut::CutMesh cut;
  double last_ssim = 0, last_mae = INFINITY, last_fov_ssim = 0, last_fov_mae = INFINITY;
  for (const std::size_t budget : {100u, 400u, 1500u}) {
    EXPECT_TRUE(
        refiner.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)).within(budget), cut));
    const eval::ImageComparison c =
        compare(full, render(s, sphere_view(), cut.triangles), sphere_view(), {0.5f, 0.5f});
    EXPECT_LT(c.ssim, 1.0) << budget;
    EXPECT_GT(c.mae, 0.0) << budget;
    EXPECT_GT(c.ssim, last_ssim) << budget;
    EXPECT_LT(c.mae, last_mae) << budget;
    EXPECT_GT(c.foveated_ssim, last_fov_ssim) << budget;
    EXPECT_LT(c.foveated_mae, last_fov_mae) << budget;
    last_ssim = c.ssim, last_mae = c.mae, last_fov_ssim = c.foveated_ssim, last_fov_mae = c.foveated_mae;
  }
}

// The experiment's setup (clients/tools/eval.cpp): a focus-DT field (step law, ×factor within
// radius of the focus, a fraction of the view) and the uniform ranking, both refined to the same
// triangle count; returns the comparisons of the uniform and the focused cut with the full model.
std::pair<eval::ImageComparison, eval::ImageComparison> uniform_and_focused(const ModelCase& s,
                                                                            const View& view,
                                                                            std::array<float, 2> focus,
                                                                            float radius, float factor,
                                                                            std::size_t budget) {
  view::ViewExtractor extractor(s.mt, *s.levels);
  view::ViewRequest request;
  request.camera = view.camera;
  request.grid = {128, 128};
  request.allowed.error = 1e-9f;  // every triangle fails; the budget alone stops the refinement
  request.allowed.criteria[view::Criterion::kFocus] =
      view::RegionLaw{view::FalloffLaw::kStep, radius * 128, factor, 16.0f, 2.3f};
  request.points[view::Criterion::kFocus] = {focus};
  request.dynamic = false;
  request.allowed_error_on_demand = false;
  extractor.map(request);
  extractor.occupancy();
  extractor.distance_transforms();
  extractor.allowed_error();
  const std::vector<float> field(extractor.vertex_allowed_error().begin(),
                                 extractor.vertex_allowed_error().end());

  cut::Refiner refiner(s.mt);
  cut::CutMesh uniform, focused;
  std::size_t target = budget;
  for (int round = 0; round < 8; ++round) {
    EXPECT_TRUE(refiner.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)).within(target),
                               uniform));
    EXPECT_TRUE(refiner.refine(
        cut::Refinement::from_root(cut::AllowedError::from_vertices(field)).within(target), focused));
    if (uniform.triangle_count() == focused.triangle_count()) break;
    target = std::min(uniform.triangle_count(), focused.triangle_count());
  }
  EXPECT_EQ(uniform.triangle_count(), focused.triangle_count());
  EXPECT_GT(uniform.triangle_count(), budget * 9 / 10);
  const Rendering full = render(s, view, s.mesh.triangles);
  return {compare(full, render(s, view, uniform.triangles), view, focus),
          compare(full, render(s, view, focused.triangles), view, focus)};
}

TEST(ImageMetricsRender, FocusRefinedCutWinsTheFoveatedScore) {
  // The terrain fills the view, so every pixel is shading and no silhouette: at 600 triangles of
  // ~5000 the cut refined within 10 % of the view around the focus and the uniform cut score about
  // the same over the whole image, and the foveated scores prefer the focused cut.
  //
  // (The sphere above does not make this case: its silhouette, 17° from a central focus in a 40°
  // view, still weighs ~0.12 in acuity and is where a coarse cut's error is largest — background
  // against surface — so there the uniform cut, which keeps the silhouette, wins even foveated.)
  const auto [u, f] = uniform_and_focused(terrain_case(), terrain_view(), {0.38f, 0.42f}, 0.1f, 0.1f, 600);
  EXPECT_GT(f.foveated_ssim, u.foveated_ssim);
  EXPECT_LT(f.foveated_mae, u.foveated_mae);
  // The weighting is what makes the difference: the focused cut gains more under it than without.
  EXPECT_GT(f.foveated_ssim - u.foveated_ssim, f.ssim - u.ssim);
  EXPECT_LT(f.foveated_mae - u.foveated_mae, f.mae - u.mae);
  // No background: every pixel is covered by both.
  EXPECT_EQ(u.covered_pixels, std::size_t{kImagePx} * kImagePx);
}

}  // namespace
}  // namespace mtlod::core

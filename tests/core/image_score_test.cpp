// Scoring renderings that arrive as pictures (mtlod-eval score, the viewer study): PNG files read
// back bit for bit (core/io/image_io), coverage from a background colour on a hand-made case, and
// compare_rgb_renderings against the scores evaluated straight from their definitions — SSIM per
// window with the 2D Gaussian, acuity e2/(e2 + e) from the angle between the two rays at the eye,
// the weighted mean over windows centred on covered pixels.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <numbers>
#include <random>
#include <vector>

#include "core/eval/image_metrics.hpp"
#include "core/io/image_io.hpp"

namespace mtlod::core {
namespace {

namespace fs = std::filesystem;

constexpr std::array<std::uint8_t, 3> kBackground{32, 36, 40};  // the viewer's background, #202428

// A disc of shaded "model" on the background, its shading a smooth pattern plus noise (fixed seed).
std::vector<std::uint8_t> disc_image(view::GridSize size, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> noise(-12, 12);
  std::vector<std::uint8_t> rgb(3 * size.cell_count());
  for (std::uint32_t j = 0; j < size.height; ++j) {
    for (std::uint32_t i = 0; i < size.width; ++i) {
      const std::size_t c = size.cell(i, j);
      const double dx = i - 0.5 * size.width, dy = j - 0.5 * size.height;
      const bool inside = dx * dx + dy * dy < 0.16 * size.height * size.height;
      for (int k = 0; k < 3; ++k) {
        const int v = 140 + int(60 * std::sin(0.21 * i + k) * std::cos(0.17 * j)) + noise(rng);
        rgb[3 * c + k] = inside ? std::uint8_t(std::clamp(v, 0, 255)) : kBackground[k];
      }
    }
  }
  return rgb;
}

double luma(const std::vector<std::uint8_t>& rgb, std::size_t c) {
  return float((0.299 * rgb[3 * c] + 0.587 * rgb[3 * c + 1] + 0.114 * rgb[3 * c + 2]) / 255.0);
}

// The foveated SSIM from its definition: every window wholly inside the image, centred on a pixel
// either image covers, weighted by the acuity at its centre; the eye on the axis through the image
// centre at focal_px, eccentricity the angle between the rays through the focus and the pixel.
double direct_foveated_ssim(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b,
                            view::GridSize size, double fx, double fy, double focal_px, double e2) {
  const int r = 5;
  double w[11][11], total = 0;
  for (int y = -r; y <= r; ++y)
    for (int x = -r; x <= r; ++x) total += w[y + r][x + r] = std::exp(-(x * x + y * y) / (2 * 1.5 * 1.5));
  const double c1 = 0.01 * 0.01, c2 = 0.03 * 0.03;
  const auto covered = [&](std::size_t c) {
    for (int k = 0; k < 3; ++k)
      if (a[3 * c + k] != kBackground[k] || b[3 * c + k] != kBackground[k]) return true;
    return false;
  };
  double sum = 0, weight_sum = 0;
  for (int cy = r; cy + r < int(size.height); ++cy) {
    for (int cx = r; cx + r < int(size.width); ++cx) {
      if (!covered(size.cell(cx, cy))) continue;
      const auto at = [&](const std::vector<std::uint8_t>& img, int dx, int dy) {
        return luma(img, std::size_t(cy + dy) * size.width + std::size_t(cx + dx));
      };
      double ma = 0, mb = 0;
      for (int y = -r; y <= r; ++y)
        for (int x = -r; x <= r; ++x)
          ma += w[y + r][x + r] / total * at(a, x, y), mb += w[y + r][x + r] / total * at(b, x, y);
      double va = 0, vb = 0, cov = 0;
      for (int y = -r; y <= r; ++y)
        for (int x = -r; x <= r; ++x) {
          const double wt = w[y + r][x + r] / total, da = at(a, x, y) - ma, db = at(b, x, y) - mb;
          va += wt * da * da, vb += wt * db * db, cov += wt * da * db;
        }
      const double s = (2 * ma * mb + c1) * (2 * cov + c2) / ((ma * ma + mb * mb + c1) * (va + vb + c2));
      const std::array<double, 3> p{cx + 0.5 - 0.5 * size.width, cy + 0.5 - 0.5 * size.height, focal_px};
      const std::array<double, 3> f{fx - 0.5 * size.width, fy - 0.5 * size.height, focal_px};
      const double cosine =
          (p[0] * f[0] + p[1] * f[1] + p[2] * f[2]) /
          std::sqrt((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) * (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]));
      const double e_deg = std::acos(std::min(1.0, cosine)) * 180 / std::numbers::pi;
      const double acuity = e2 / (e2 + e_deg);
      sum += acuity * s, weight_sum += acuity;
    }
  }
  return sum / weight_sum;
}

TEST(ReadPngRgb, ReadsBackWhatWasWrittenBitForBit) {
  const view::GridSize size{37, 23};
  const std::vector<std::uint8_t> rgb = disc_image(size, 3);
  const fs::path path = fs::path(::testing::TempDir()) / "image_score_rgb.png";
  ASSERT_TRUE(io::write_png_rgb(path, rgb, size));
  auto read = io::read_png_rgb(path);
  ASSERT_TRUE(read) << read.error().message;
  EXPECT_EQ(read->size.width, 37u);
  EXPECT_EQ(read->size.height, 23u);
  EXPECT_EQ(read->rgb, rgb);
  // A grey PNG comes back with three equal channels.
  const std::vector<std::uint8_t> grey{0, 50, 100, 150, 200, 255};
  ASSERT_TRUE(io::write_png_gray(path, grey, {3, 2}));
  read = io::read_png_rgb(path);
  ASSERT_TRUE(read);
  for (std::size_t c = 0; c < grey.size(); ++c)
    for (int k = 0; k < 3; ++k) ASSERT_EQ(read->rgb[3 * c + k], grey[c]);
  EXPECT_FALSE(io::read_png_rgb(fs::path(::testing::TempDir()) / "no-such-file.png"));
  fs::remove(path);
}

TEST(CoverageFromBackground, APixelCountsWhenEitherImageDiffers) {
  // Four pixels: background in both, model in a only, in b only (one channel off by one), in both.
  const std::vector<std::uint8_t> a{32, 36, 40, 200, 200, 200, 32, 36, 40, 90, 90, 90};
  const std::vector<std::uint8_t> b{32, 36, 40, 32, 36, 40, 32, 36, 41, 10, 10, 10};
  std::vector<std::uint8_t> covered(4);
  EXPECT_EQ(eval::coverage_from_background(a, b, kBackground, covered), 3u);
  EXPECT_EQ(covered, (std::vector<std::uint8_t>{0, 1, 1, 1}));
}

TEST(CompareRgbRenderings, IdenticalPicturesHaveNoError) {
  const view::GridSize size{64, 48};
  const std::vector<std::uint8_t> a = disc_image(size, 5);
  const eval::ImageComparison c =
      eval::compare_rgb_renderings(a, a, size, kBackground, {20.5f, 30.5f, 60.0, 2.3});
  EXPECT_EQ(c.foveated_ssim, 1.0);
  EXPECT_EQ(c.ssim, 1.0);
  EXPECT_EQ(c.foveated_mae, 0.0);
}

TEST(CompareRgbRenderings, MatchesTheDefinitionEvaluatedDirectly) {
  const view::GridSize size{71, 53};
  const std::vector<std::uint8_t> a = disc_image(size, 1);
  std::vector<std::uint8_t> b = disc_image(size, 2);  // other noise on the model, same coverage
  // And a patch of model where a has background: the coverage is the union.
  for (std::uint32_t j = 2; j < 9; ++j)
    for (std::uint32_t i = 3; i < 12; ++i)
      for (int k = 0; k < 3; ++k) b[3 * size.cell(i, j) + k] = 120;
  const double fx = 40.25, fy = 20.75, focal = eval::focal_px_from_fov(size.height, 40.0);
  const eval::ImageComparison c =
      eval::compare_rgb_renderings(a, b, size, kBackground, {float(fx), float(fy), focal, 2.3});
  const double expected = direct_foveated_ssim(a, b, size, fx, fy, focal, 2.3);
  // The map and the weights are stored in float: agreement to float precision.
  EXPECT_NEAR(c.foveated_ssim, expected, 1e-6);
  EXPECT_LT(c.foveated_ssim, 0.95);  // the noise differs: clearly not identical
  EXPECT_GT(c.foveated_ssim, 0.0);
}

}  // namespace
}  // namespace mtlod::core

// Image-space silhouette error (core/silhouette_metrics): masks of squares whose pixel coverage is
// known, a shifted square with a known XOR count and contour distance, contour distances against
// brute force, and the focus-region triangle selection.
#include "core/eval/silhouette_metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "core/view/view_grid.hpp"
#include "tests/core/test_scenes.hpp"

namespace mtlod::core {
namespace {

using test::add_rectangle;
using test::ortho_camera;

TEST(SilhouetteMask, SquareCoversKnownPixels) {
  const view::ViewMapping mapping = ortho_camera(1.0f, 100);
  std::vector<float> p;
  std::vector<std::uint32_t> t;
  // x ∈ [−0.5, 0.5] maps to grid x ∈ [25, 75]: pixel centres 25.5 … 74.5, 50 columns; same for rows.
  add_rectangle(p, t, -0.5f, -0.5f, 0.5f, 0.5f, 0.0f);
  std::vector<std::uint8_t> mask(100 * 100);
  EXPECT_EQ(eval::rasterize_silhouette(mapping, p, t, mask), 2500u);
  EXPECT_EQ(mask[50 * 100 + 25], 1);
  EXPECT_EQ(mask[50 * 100 + 24], 0);
  EXPECT_EQ(mask[74 * 100 + 74], 1);
  EXPECT_EQ(mask[75 * 100 + 74], 0);
}

TEST(SilhouetteMask, ShiftedSquareHasKnownXorAndContourDistance) {
  const view::ViewMapping mapping = ortho_camera(1.0f, 100);
  std::vector<float> pa, pb;
  std::vector<std::uint32_t> ta, tb;
  add_rectangle(pa, ta, -0.5f, -0.5f, 0.5f, 0.5f, 0.0f);
  // Shifted right by 0.1 = 5 pixels: the two masks differ in a 5×50 strip on either side.
  add_rectangle(pb, tb, -0.4f, -0.5f, 0.6f, 0.5f, 0.0f);
  std::vector<std::uint8_t> a(100 * 100), b(100 * 100);
  eval::rasterize_silhouette(mapping, pa, ta, a);
  eval::rasterize_silhouette(mapping, pb, tb, b);
  const eval::SilhouetteError e = eval::compare_silhouettes(a, b, {100, 100});
  EXPECT_EQ(e.xor_pixels, 2u * 5u * 50u);
  EXPECT_EQ(e.pixels_a, 2500u);
  EXPECT_EQ(e.pixels_b, 2500u);
  // The left edge of one is 5 pixels from the left edge of the other, and no contour pixel is farther.
  EXPECT_DOUBLE_EQ(e.a_to_b.max_px, 5.0);
  EXPECT_DOUBLE_EQ(e.b_to_a.max_px, 5.0);
  EXPECT_EQ(e.a_to_b.pixels, 4u * 49u);  // the 50×50 square's ring of pixels

  // Brute-force mean of a → b: nearest contour pixel of b for every contour pixel of a.
  std::vector<std::uint8_t> ca(a.size()), cb(b.size());
  eval::extract_contour(a, {100, 100}, ca);
  eval::extract_contour(b, {100, 100}, cb);
  double sum = 0;
  int n = 0;
  for (int c = 0; c < 10000; ++c) {
    if (!ca[c]) continue;
    double best = std::numeric_limits<double>::infinity();
    for (int d = 0; d < 10000; ++d)
      if (cb[d]) best = std::min(best, std::hypot(double(c % 100 - d % 100), double(c / 100 - d / 100)));
    sum += best, ++n;
  }
  EXPECT_NEAR(e.a_to_b.mean_px, sum / n, 1e-12);
}

TEST(SilhouetteMask, IdenticalMasksHaveZeroError) {
  const view::ViewMapping mapping = ortho_camera(1.0f, 64);
  std::vector<float> p;
  std::vector<std::uint32_t> t;
  add_rectangle(p, t, -0.7f, -0.3f, 0.2f, 0.9f, 0.0f);
  std::vector<std::uint8_t> a(64 * 64);
  eval::rasterize_silhouette(mapping, p, t, a);
  const eval::SilhouetteError e = eval::compare_silhouettes(a, a, {64, 64});
  EXPECT_EQ(e.xor_pixels, 0u);
  EXPECT_EQ(e.max_px(), 0.0);
  EXPECT_EQ(e.mean_px(), 0.0);
  EXPECT_GT(e.a_to_b.pixels, 0u);
}

TEST(SilhouetteMask, ContourOfAFilledImageIsItsBorder) {
  std::vector<std::uint8_t> mask(10 * 6, 1), contour(mask.size());
  // Off-image counts as background, so the border ring is the contour: 2·10 + 2·4 pixels.
  EXPECT_EQ(eval::extract_contour(mask, {10, 6}, contour), 28u);
  EXPECT_EQ(contour[2 * 10 + 5], 0);
}

TEST(SilhouetteMask, EmptyAgainstNonEmptyIsInfinitelyFar) {
  std::vector<std::uint8_t> a(16 * 16, 0), b(16 * 16, 0);
  b[5 * 16 + 5] = 1;
  const eval::SilhouetteError e = eval::compare_silhouettes(a, b, {16, 16});
  EXPECT_EQ(e.xor_pixels, 1u);
  EXPECT_TRUE(std::isinf(e.b_to_a.max_px));
  EXPECT_EQ(e.a_to_b.pixels, 0u);
}

TEST(FocusRegion, TrianglesWithinRadiusOfAPoint) {
  const view::ViewMapping mapping = ortho_camera(1.0f, 100);
  std::vector<float> p;
  std::vector<std::uint32_t> t;
  add_rectangle(p, t, -0.1f, -0.1f, 0.1f, 0.1f, 0.0f);  // grid [45, 55]², covering the centre
  add_rectangle(p, t, 0.5f, -0.1f, 0.7f, 0.1f, 0.0f);   // grid x ∈ [75, 85]: 25 px right of the centre
  std::vector<std::uint8_t> region(4);
  // Radius 20 px around the centre (50, 50): only the first square.
  EXPECT_EQ(eval::triangles_near_point(mapping, p, t, 50.0f, 50.0f, 20.0f, region), 2u);
  EXPECT_EQ(region[0] + region[1], 2);
  EXPECT_EQ(region[2] + region[3], 0);
  // Radius 25.5 px reaches the second square's left edge (25 px away, up to float rounding of the
  // projection).
  EXPECT_EQ(eval::triangles_near_point(mapping, p, t, 50.0f, 50.0f, 25.5f, region), 4u);
}

}  // namespace
}  // namespace mtlod::core

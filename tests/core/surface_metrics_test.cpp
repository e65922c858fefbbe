// Object-space error (core/surface_metrics): exact point–triangle distances in hand-made cases, the
// grid index against brute force on random triangles, and Hausdorff/RMS on analytic pairs: identical
// meshes, a plane and its offset copy, and a sphere against its inscribed octahedron.
#include "core/eval/surface_metrics.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace mtlod::core {
namespace {

struct Soup {
  std::vector<float> positions;
  std::vector<std::uint32_t> triangles;
};

// An n×n grid of quads (two triangles each) over [0, size]² at height z.
Soup plane(int n, float size, float z) {
  Soup s;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) s.positions.insert(s.positions.end(), {size * i / n, size * j / n, z});
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const std::uint32_t a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      s.triangles.insert(s.triangles.end(), {a, b, d, a, d, c});
    }
  }
  return s;
}

// The regular octahedron with vertices on the unit sphere.
Soup octahedron() {
  Soup s;
  s.positions = {1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1};
  s.triangles = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
  return s;
}

// The octahedron subdivided `levels` times (1→4), every vertex pushed onto the unit sphere.
Soup sphere(int levels) {
  Soup s = octahedron();
  for (int l = 0; l < levels; ++l) {
    std::vector<std::uint32_t> next;
    std::vector<std::array<std::uint32_t, 3>> edges;  // a < b, midpoint id: a tiny edge map
    std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> by_vertex(s.positions.size() / 3);
    const auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
      if (a > b) std::swap(a, b);
      for (const auto& [other, id] : by_vertex[a])
        if (other == b) return id;
      const std::uint32_t id = std::uint32_t(s.positions.size() / 3);
      float m[3];
      for (int c = 0; c < 3; ++c) m[c] = 0.5f * (s.positions[3 * a + c] + s.positions[3 * b + c]);
      const float len = std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
      s.positions.insert(s.positions.end(), {m[0] / len, m[1] / len, m[2] / len});
      by_vertex[a].push_back({b, id});
      by_vertex.emplace_back();
      return id;
    };
    for (std::size_t t = 0; t < s.triangles.size() / 3; ++t) {
      const std::uint32_t a = s.triangles[3 * t], b = s.triangles[3 * t + 1], c = s.triangles[3 * t + 2];
      const std::uint32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
      next.insert(next.end(), {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca});
    }
    s.triangles = std::move(next);
  }
  return s;
}

TEST(PointTriangleDistance, HandMadeRegions) {
  const double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0, 1, 0};
  // Above the face: the height.
  const double above[3] = {0.25, 0.25, 2};
  EXPECT_DOUBLE_EQ(eval::point_triangle_distance(above, a, b, c), 2.0);
  // Beyond vertex b along the x axis: the distance to b.
  const double beyond[3] = {3, 0, 0};
  EXPECT_DOUBLE_EQ(eval::point_triangle_distance(beyond, a, b, c), 2.0);
  // Outside the hypotenuse, in the plane: distance to the line x + y = 1 is (x + y − 1)/√2.
  const double outside[3] = {1, 1, 0};
  EXPECT_NEAR(eval::point_triangle_distance(outside, a, b, c), 1.0 / std::sqrt(2.0), 1e-15);
  // A collinear (zero-area) triangle behaves as its longest segment.
  const double d[3] = {2, 0, 0};
  const double p[3] = {1, 3, 0};
  EXPECT_DOUBLE_EQ(eval::point_triangle_distance(p, a, b, d), 3.0);
}

TEST(TriangleIndex, MatchesBruteForceOnRandomTriangles) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> coord(-1.0f, 1.0f), small(-0.1f, 0.1f), far(-4.0f, 4.0f);
  Soup s;
  for (std::uint32_t t = 0; t < 300; ++t) {
    const float cx = coord(rng), cy = coord(rng), cz = coord(rng);
    for (int k = 0; k < 3; ++k)
      s.positions.insert(s.positions.end(), {cx + small(rng), cy + small(rng), cz + small(rng)});
    s.triangles.insert(s.triangles.end(), {3 * t, 3 * t + 1, 3 * t + 2});
  }
  eval::TriangleIndex index(s.positions, s.triangles);
  for (int q = 0; q < 2000; ++q) {
    // Half the queries inside the box, half far outside it.
    const float x = q % 2 ? far(rng) : coord(rng), y = q % 2 ? far(rng) : coord(rng),
                z = q % 2 ? far(rng) : coord(rng);
    const double p[3] = {x, y, z};
    double expected = std::numeric_limits<double>::infinity();
    for (std::size_t t = 0; t < s.triangles.size() / 3; ++t) {
      double v[3][3];
      for (int k = 0; k < 3; ++k)
        for (int c = 0; c < 3; ++c) v[k][c] = s.positions[3 * s.triangles[3 * t + k] + c];
      expected = std::min(expected, eval::point_triangle_distance(p, v[0], v[1], v[2]));
    }
    // The index evaluates the same exact function on a subset that must contain the nearest triangle.
    ASSERT_EQ(index.distance(x, y, z), expected) << "query " << q;
  }
}

TEST(SurfaceMetrics, IdenticalMeshesHaveZeroError) {
  const Soup s = sphere(3);
  const eval::SurfaceError e =
      eval::compare_surfaces(s.positions, s.triangles, s.positions, s.triangles, {20000, true, 3});
  // Area samples are rounded to float, so they sit up to ~1 ulp of a unit coordinate off the plane.
  EXPECT_LT(e.hausdorff(), 1e-6);
  EXPECT_LT(e.rms(), 1e-6);
  EXPECT_EQ(e.a_to_b.samples, 20000 + s.positions.size() / 3);
}

TEST(SurfaceMetrics, PlaneOffsetByKnownDistance) {
  const Soup a = plane(8, 2.0f, 0.0f), b = plane(3, 2.0f, 0.25f);
  const eval::SurfaceError e =
      eval::compare_surfaces(a.positions, a.triangles, b.positions, b.triangles, {5000, true, 11});
  // Both planes cover the same square, so every sample's nearest point is straight above or below it:
  // every distance is 0.25 (float rounding of 0.25 is exact; the samples' z is exactly 0 or 0.25).
  EXPECT_NEAR(e.a_to_b.max, 0.25, 1e-7);
  EXPECT_NEAR(e.a_to_b.mean, 0.25, 1e-7);
  EXPECT_NEAR(e.b_to_a.rms, 0.25, 1e-7);
  EXPECT_NEAR(e.hausdorff(), 0.25, 1e-7);
}

TEST(SurfaceMetrics, SphereAgainstInscribedOctahedron) {
  const Soup ball = sphere(5), octa = octahedron();  // 8192 triangles on the unit sphere
  const eval::SurfaceError e = eval::compare_surfaces(ball.positions, ball.triangles, octa.positions,
                                                      octa.triangles, {50000, true, 5});
  // The farthest points are the face centres of the octahedron, at 1/√3 from the centre, against the
  // sphere point straight outside them: 1 − 1/√3 both ways. Tolerance: the polyhedral sphere's chords
  // (edge ≈ π/64 → sag ≈ edge²/8 ≈ 3e-4) and the sampling near the maximum (quadratic in the angle).
  const double expected = 1.0 - 1.0 / std::sqrt(3.0);
  EXPECT_NEAR(e.a_to_b.max, expected, 2e-3);
  EXPECT_NEAR(e.b_to_a.max, expected, 2e-3);
  EXPECT_LE(e.b_to_a.max, expected + 1e-6);  // the polyhedral sphere lies inside the unit sphere
  // Independent RMS of octahedron → sphere: for a face point at parameter q, d = 1 − |q|; estimate the
  // mean of d² over one face by a fine barycentric grid (no sampling code shared).
  double sum2 = 0;
  int n = 0;
  const int steps = 400;
  for (int i = 0; i <= steps; ++i) {
    for (int j = 0; i + j <= steps; ++j) {
      const double u = double(i) / steps, v = double(j) / steps, w = 1 - u - v;
      const double d = 1.0 - std::sqrt(u * u + v * v + w * w);
      sum2 += d * d, ++n;
    }
  }
  // The grid estimate and the sphere's own sag limit agreement to about 1e-3.
  EXPECT_NEAR(e.b_to_a.rms, std::sqrt(sum2 / n), 2e-3);
}

TEST(SurfaceMetrics, MaskRestrictsSamples) {
  const Soup s = plane(4, 1.0f, 0.0f);
  std::vector<std::uint8_t> mask(s.triangles.size() / 3, 0);
  for (std::size_t t = 0; t < mask.size(); t += 3) mask[t] = 1;
  eval::SurfaceSamples samples;
  eval::sample_surface(s.positions, s.triangles, mask, {1000, true, 1}, samples);
  ASSERT_GT(samples.size(), 1000u);
  for (const std::uint32_t t : samples.triangle_ids) EXPECT_EQ(mask[t], 1);
  // The same mask in the distance pass: only the masked samples count; a plane 1 above is 1 away.
  const Soup above = plane(1, 1.0f, 1.0f);
  eval::TriangleIndex index(above.positions, above.triangles);
  eval::SurfaceSamples all;
  eval::sample_surface(s.positions, s.triangles, {}, {1000, false, 1}, all);
  const eval::DistanceStats masked = eval::sample_distances_masked(all, mask, index);
  std::size_t expected = 0;
  for (const std::uint32_t t : all.triangle_ids) expected += mask[t];
  EXPECT_EQ(masked.samples, expected);
  EXPECT_NEAR(masked.max, 1.0, 1e-7);
}

TEST(SurfaceMetrics, EmptyTargetIsInfinitelyFar) {
  const Soup s = plane(1, 1.0f, 0.0f);
  eval::TriangleIndex empty(s.positions, std::span<const std::uint32_t>());
  EXPECT_TRUE(std::isinf(empty.distance(0, 0, 0)));
}

}  // namespace
}  // namespace mtlod::core

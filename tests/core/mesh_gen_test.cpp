// Synthetic meshes: sizes near the target, the promised topology, outward orientation, and
// determinism for a seed.
#include "core/eval/mesh_gen.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "core/model/mesh_cleanup.hpp"

namespace mtlod::core {
namespace {

// Six times the signed volume of a closed mesh (divergence theorem); positive when outward.
double signed_volume6(const model::Mesh& m) {
  double sum = 0;
  for (std::size_t t = 0; t < m.triangle_count(); ++t) {
    const float* a = &m.positions[3 * m.triangles[3 * t]];
    const float* b = &m.positions[3 * m.triangles[3 * t + 1]];
    const float* c = &m.positions[3 * m.triangles[3 * t + 2]];
    sum += double{a[0]} * (double{b[1]} * c[2] - double{b[2]} * c[1]) -
           double{a[1]} * (double{b[0]} * c[2] - double{b[2]} * c[0]) +
           double{a[2]} * (double{b[0]} * c[1] - double{b[1]} * c[0]);
  }
  return sum;
}

model::Mesh generate(eval::Shape shape, std::size_t triangles, std::uint32_t seed = 1) {
  eval::GenerateOptions o;
  o.shape = shape;
  o.target_triangles = triangles;
  o.seed = seed;
  return eval::generate_mesh(o);
}

TEST(GenerateMesh, ClosedShapesAreOutwardGenusZeroManifoldsNearTheTarget) {
  for (eval::Shape shape : {eval::Shape::kSphere, eval::Shape::kShell}) {
    for (std::size_t target : {200u, 5'000u, 120'000u}) {
      const model::Mesh m = generate(shape, target);
      const model::TopologyReport r = model::analyze_topology(m.positions, m.triangles);
      SCOPED_TRACE(testing::Message() << "shape " << int(shape) << " target " << target);
      EXPECT_TRUE(r.is_closed_manifold()) << r.summary();
      EXPECT_EQ(r.euler_characteristic, 2);
      EXPECT_EQ(r.components, 1u);
      EXPECT_EQ(r.duplicate_triangles, 0u);
      EXPECT_EQ(r.unused_vertices, 0u);
      EXPECT_GT(signed_volume6(m), 0.0);
      // Rounding a grid side to a whole number moves small meshes most: 10% at 200 triangles.
      EXPECT_NEAR(static_cast<double>(m.triangle_count()), static_cast<double>(target), 0.10 * target);
    }
  }
}

TEST(GenerateMesh, TerrainIsOneDiskFacingUp) {
  const model::Mesh m = generate(eval::Shape::kTerrain, 20'000);
  const model::TopologyReport r = model::analyze_topology(m.positions, m.triangles);
  EXPECT_EQ(r.boundary_loops, 1u);
  EXPECT_EQ(r.euler_characteristic, 1);
  EXPECT_EQ(r.non_manifold_edges + r.inconsistent_edges + r.non_manifold_vertices, 0u);
  EXPECT_NEAR(static_cast<double>(m.triangle_count()), 20'000.0, 600.0);
  // Every triangle's normal has a positive z: seen from above, counter-clockwise.
  for (std::size_t t = 0; t < m.triangle_count(); ++t) {
    const float* a = &m.positions[3 * m.triangles[3 * t]];
    const float* b = &m.positions[3 * m.triangles[3 * t + 1]];
    const float* c = &m.positions[3 * m.triangles[3 * t + 2]];
    ASSERT_GT((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]), 0.0f);
  }
}

TEST(GenerateMesh, SameSeedSameMeshOtherSeedOtherSurface) {
  const model::Mesh a = generate(eval::Shape::kSphere, 3'000, 5),
                    b = generate(eval::Shape::kSphere, 3'000, 5);
  const model::Mesh c = generate(eval::Shape::kSphere, 3'000, 6);
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.triangles, c.triangles);
  EXPECT_NE(a.positions, c.positions);
}

TEST(GenerateMesh, ColoursGrowAlongTheAxesOverTheWholeByteRange) {
  eval::GenerateOptions o;
  o.shape = eval::Shape::kShell;
  o.target_triangles = 5'000;
  const model::Mesh plain = eval::generate_mesh(o);
  o.colors = true;
  const model::Mesh painted = eval::generate_mesh(o);
  EXPECT_FALSE(plain.has_colors());
  ASSERT_EQ(painted.positions, plain.positions);  // the same surface, coloured
  ASSERT_EQ(painted.colors.size(), painted.positions.size());
  for (int k = 0; k < 3; ++k) {
    // Channel k never falls as coordinate k grows, and spans 0..255 (the box's two faces).
    std::vector<std::pair<float, int>> by_coordinate;
    for (std::size_t v = 0; v < painted.vertex_count(); ++v)
      by_coordinate.emplace_back(painted.positions[3 * v + k], painted.colors[3 * v + k]);
    std::sort(by_coordinate.begin(), by_coordinate.end());
    EXPECT_EQ(by_coordinate.front().second, 0) << k;
    EXPECT_EQ(by_coordinate.back().second, 255) << k;
    for (std::size_t i = 1; i < by_coordinate.size(); ++i)
      ASSERT_LE(by_coordinate[i - 1].second, by_coordinate[i].second) << "channel " << k << " at " << i;
  }
}

TEST(GenerateMesh, MillionTriangleShellIsClosedManifold) {
  const model::Mesh m = generate(eval::Shape::kShell, 1'000'000);
  const model::TopologyReport r = model::analyze_topology(m.positions, m.triangles);
  EXPECT_TRUE(r.is_closed_manifold()) << r.summary();
  EXPECT_EQ(r.euler_characteristic, 2);
  EXPECT_NEAR(static_cast<double>(m.triangle_count()), 1e6, 1e4);
}

}  // namespace
}  // namespace mtlod::core

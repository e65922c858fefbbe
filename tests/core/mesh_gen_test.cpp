// Synthetic meshes: sizes near the target, the promised topology, outward orientation, and
// determinism for a seed.
#include "core/eval/mesh_gen.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "core/mesh_cleanup.hpp"

namespace mtlod::core {
namespace {

// Six times the signed volume of a closed mesh (divergence theorem); positive when outward.
double signed_volume6(const Mesh& m) {
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

Mesh generate(Shape shape, std::size_t triangles, std::uint32_t seed = 1) {
  GenerateOptions o;
  o.shape = shape;
  o.target_triangles = triangles;
  o.seed = seed;
  return generate_mesh(o);
}

TEST(GenerateMesh, ClosedShapesAreOutwardGenusZeroManifoldsNearTheTarget) {
  for (Shape shape : {Shape::kSphere, Shape::kShell}) {
    for (std::size_t target : {200u, 5'000u, 120'000u}) {
      const Mesh m = generate(shape, target);
      const TopologyReport r = analyze_topology(m.positions, m.triangles);
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
  const Mesh m = generate(Shape::kTerrain, 20'000);
  const TopologyReport r = analyze_topology(m.positions, m.triangles);
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
  const Mesh a = generate(Shape::kSphere, 3'000, 5), b = generate(Shape::kSphere, 3'000, 5);
  const Mesh c = generate(Shape::kSphere, 3'000, 6);
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.triangles, c.triangles);
  EXPECT_NE(a.positions, c.positions);
}

TEST(GenerateMesh, MillionTriangleShellIsClosedManifold) {
  const Mesh m = generate(Shape::kShell, 1'000'000);
  const TopologyReport r = analyze_topology(m.positions, m.triangles);
  EXPECT_TRUE(r.is_closed_manifold()) << r.summary();
  EXPECT_EQ(r.euler_characteristic, 2);
  EXPECT_NEAR(static_cast<double>(m.triangle_count()), 1e6, 1e4);
}

}  // namespace
}  // namespace mtlod::core

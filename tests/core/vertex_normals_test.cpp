// Vertex normals against hand-computed ones (a cube corner, a flat fan however it is split), a
// sphere's radial directions, the repair of NaN, zero and missing normals, and the MT's normals
// against the mesh it was built from.
#include "core/build/vertex_normals.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "core/build/mt_builder.hpp"
#include "core/eval/mesh_gen.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::core {
namespace {

double dot3(const float* a, const double b[3]) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
double length3(const float* a) {
  return std::sqrt(double{a[0]} * a[0] + double{a[1]} * a[1] + double{a[2]} * a[2]);
}

// The unit cube, each face split along a diagonal; counter-clockwise seen from outside.
model::Mesh cube(bool other_diagonals) {
  model::Mesh m;
  for (int i = 0; i < 8; ++i)
    m.positions.insert(m.positions.end(), {float(i & 1), float(i >> 1 & 1), float(i >> 2 & 1)});
  // Each face as a quad a, b, c, d counter-clockwise from outside.
  const std::uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                     {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    if (other_diagonals)
      m.triangles.insert(m.triangles.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
    else
      m.triangles.insert(m.triangles.end(), {q[1], q[2], q[3], q[1], q[3], q[0]});
  }
  return m;
}

TEST(VertexNormals, CubeCornersPointAlongTheDiagonalHoweverTheFacesAreSplit) {
  // Every corner meets three faces at 90° each, whichever diagonal splits them: angle weighting
  // gives the corner the direction (±1, ±1, ±1)/√3 exactly (area or plain averaging would not).
  for (const bool other : {false, true}) {
    const model::Mesh m = cube(other);
    const std::vector<float> n = build::vertex_normals(m.positions, m.triangles);
    ASSERT_EQ(n.size(), m.positions.size());
    for (std::size_t v = 0; v < 8; ++v) {
      double want[3];
      for (int k = 0; k < 3; ++k) want[k] = (m.positions[3 * v + k] - 0.5) * 2 / std::sqrt(3.0);
      EXPECT_NEAR(dot3(&n[3 * v], want), 1.0, 1e-6) << "corner " << v << (other ? " (other diagonals)" : "");
    }
  }
}

TEST(VertexNormals, FlatFanGivesThePlaneNormalAndDegenerateTrianglesAddNothing) {
  model::Mesh m = test::square();
  m.triangles.insert(m.triangles.end(), {0, 0, 1});  // a repeated corner: no direction
  const std::vector<float> n = build::vertex_normals(m.positions, m.triangles);
  const double z[3] = {0, 0, 1};
  for (std::size_t v = 0; v < m.vertex_count(); ++v) EXPECT_NEAR(dot3(&n[3 * v], z), 1.0, 1e-6) << v;
}

TEST(VertexNormals, SphereNormalsAreRadial) {
  eval::GenerateOptions o;
  o.target_triangles = 20'000;
  o.noise = 0;
  const model::Mesh m = eval::generate_mesh(o);
  const std::vector<float> n = build::vertex_normals(m.positions, m.triangles);
  double worst = 1;
  for (std::size_t v = 0; v < m.vertex_count(); ++v) {
    const float* p = &m.positions[3 * v];
    const double l = length3(p);
    const double radial[3] = {p[0] / l, p[1] / l, p[2] / l};
    worst = std::min(worst, dot3(&n[3 * v], radial));
  }
  EXPECT_GT(worst, 0.999) << "a vertex normal of the smooth sphere leans away from the radius";
}

TEST(VertexNormals, IsolatedVertexGetsAUnitNormalNotNaN) {
  model::Mesh m = test::square();
  m.positions.insert(m.positions.end(), {5, 5, 5});
  const std::vector<float> n = build::vertex_normals(m.positions, m.triangles);
  const float* lonely = &n[3 * (m.vertex_count() - 1)];
  EXPECT_NEAR(length3(lonely), 1.0, 1e-6);
}

TEST(RepairNormals, ReplacesNaNAndZeroNormalsKeepsAndNormalisesTheRest) {
  model::Mesh m = cube(false);
  const std::vector<float> computed = build::vertex_normals(m.positions, m.triangles);
  m.normals.assign(m.positions.size(), 0.0f);
  for (std::size_t v = 0; v < 8; ++v) {
    m.normals[3 * v] = 3.0f;  // the file's own (odd but valid) direction +x, not unit length
  }
  m.normals[3 * 2 + 1] = std::numeric_limits<float>::quiet_NaN();  // vertex 2: NaN
  std::fill_n(&m.normals[3 * 5], 3, 0.0f);                         // vertex 5: zero length
  const build::NormalRepair r = build::repair_normals(m.normals, m.positions, m.triangles);
  EXPECT_TRUE(r.had_normals);
  EXPECT_EQ(r.computed, 2u);
  for (std::size_t v = 0; v < 8; ++v) {
    const float* n = &m.normals[3 * v];
    EXPECT_NEAR(length3(n), 1.0, 1e-6) << v;
    if (v == 2 || v == 5) {
      for (int k = 0; k < 3; ++k) EXPECT_FLOAT_EQ(n[k], computed[3 * v + k]) << v;
    } else {
      EXPECT_FLOAT_EQ(n[0], 1.0f) << "vertex " << v << " lost its own normal";
    }
  }
}

TEST(RepairNormals, ComputesAllWhenThereAreNone) {
  model::Mesh m = cube(true);
  const build::NormalRepair r = build::repair_normals(m.normals, m.positions, m.triangles);
  EXPECT_FALSE(r.had_normals);
  EXPECT_EQ(r.computed, 8u);
  EXPECT_EQ(m.normals, build::vertex_normals(m.positions, m.triangles));
}

TEST(BuildMt, EveryMtHasTheInputSurfaceNormals) {
  eval::GenerateOptions o;
  o.target_triangles = 5'000;
  o.noise = 0.1f;
  const model::Mesh m = eval::generate_mesh(o);
  ASSERT_FALSE(m.has_normals());
  build::BuildStats stats;
  std::vector<std::uint32_t> ids;
  auto mt = build::build_mt(m, {}, &stats, &ids);
  ASSERT_TRUE(mt.ok()) << mt.error().message;
  EXPECT_EQ(stats.normals_computed, m.vertex_count());
  ASSERT_TRUE(mt->has_normals());
  const std::vector<float> want = build::vertex_normals(m.positions, m.triangles);
  // The same normals, under the MT's numbering; and the MT computes them from its own
  // full-resolution triangles as an MT stored without normals gets them at load.
  model::MtArrays arrays = mt->arrays();
  arrays.normals.clear();
  model::Mt without(std::move(arrays));
  ASSERT_TRUE(*build::ensure_normals(without));
  for (std::size_t v = 0; v < m.vertex_count(); ++v) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_FLOAT_EQ(mt->normals[3 * std::size_t{ids[v]} + k], want[3 * v + k]) << v;
      EXPECT_NEAR(without.normals[3 * std::size_t{ids[v]} + k], want[3 * v + k], 1e-5) << v;
    }
  }
  EXPECT_FALSE(*build::ensure_normals(without)) << "normals computed twice";
}

}  // namespace
}  // namespace mtlod::core

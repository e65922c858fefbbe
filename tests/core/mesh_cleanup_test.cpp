// Topology counts and clean-up on hand-made meshes whose defects are known, and against a
// brute-force edge census on random triangle soups.
#include "core/model/mesh_cleanup.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>
#include <utility>

#include "tests/core/test_meshes.hpp"

namespace mtlod::core {
namespace {

model::TopologyReport analyze(const model::Mesh& m) {
  return model::analyze_topology(m.positions, m.triangles);
}

TEST(AnalyzeTopology, TetrahedronIsClosedManifoldWithEulerTwo) {
  const model::TopologyReport r = analyze(test::tetrahedron());
  EXPECT_EQ(r.vertices, 4u);
  EXPECT_EQ(r.edges, 6u);
  EXPECT_EQ(r.euler_characteristic, 2);
  EXPECT_EQ(r.components, 1u);
  EXPECT_TRUE(r.is_closed_manifold());
}

TEST(AnalyzeTopology, SquareHasOneBoundaryLoopOfFourEdges) {
  const model::TopologyReport r = analyze(test::square());
  EXPECT_EQ(r.boundary_edges, 4u);
  EXPECT_EQ(r.boundary_loops, 1u);
  EXPECT_EQ(r.euler_characteristic, 1);  // a disk
  EXPECT_FALSE(r.is_closed_manifold());
}

TEST(AnalyzeTopology, CountsUnusedVerticesAndDuplicatePositions) {
  model::Mesh m = test::tetrahedron();
  m.positions.insert(m.positions.end(), {1, 1, 1, 5, 5, 5});  // vertex 4 repeats vertex 0; both unused
  const model::TopologyReport r = analyze(m);
  EXPECT_EQ(r.unused_vertices, 2u);
  EXPECT_EQ(r.duplicate_positions, 1u);
}

TEST(AnalyzeTopology, RepeatedFaceMakesItsThreeEdgesNonManifold) {
  // Each edge of the repeated face now has three triangles.
  model::Mesh m = test::tetrahedron();
  m.triangles.insert(m.triangles.end(), {0, 1, 2});
  const model::TopologyReport r = analyze(m);
  EXPECT_EQ(r.duplicate_triangles, 1u);
  EXPECT_EQ(r.non_manifold_edges, 3u);
  EXPECT_FALSE(r.is_closed_manifold());
}

TEST(AnalyzeTopology, FlippedTriangleGivesClashingEdge) {
  // Square with its second triangle wound the other way: the diagonal is walked 0->2 twice.
  model::Mesh m = test::square();
  std::swap(m.triangles[4], m.triangles[5]);
  EXPECT_EQ(analyze(m).inconsistent_edges, 1u);
}

TEST(AnalyzeTopology, TwoTetrahedraSharingOneVertexMakeANonManifoldVertex) {
  model::Mesh m = test::tetrahedron();
  // Second tetrahedron: vertex 0 shared, three new vertices far away.
  m.positions.insert(m.positions.end(), {3, 3, 1, 1, 3, 3, 3, 1, 3});
  m.triangles.insert(m.triangles.end(), {0, 4, 5, 0, 5, 6, 0, 6, 4, 4, 6, 5});
  const model::TopologyReport r = analyze(m);
  EXPECT_EQ(r.components, 1u);
  EXPECT_EQ(r.non_manifold_edges, 0u);
  EXPECT_EQ(r.non_manifold_vertices, 1u);
  EXPECT_FALSE(r.is_closed_manifold());
}

TEST(AnalyzeTopology, DegenerateTrianglesByRepeatedIdAndByZeroArea) {
  model::Mesh m = test::square();
  m.positions.insert(m.positions.end(), {2, 0, 0});  // 4: on the line through 0 and 1
  m.triangles.insert(m.triangles.end(), {0, 0, 2, 0, 1, 4});
  EXPECT_EQ(analyze(m).degenerate_triangles, 2u);
}

TEST(CleanMesh, DropsDegenerateDuplicateAndUnusedKeepingGeometry) {
  model::Mesh m = test::tetrahedron();
  m.positions.insert(m.positions.end(), {9, 9, 9});  // 4: unused
  m.triangles.insert(m.triangles.end(), {0, 1, 1});  // degenerate
  m.triangles.insert(m.triangles.end(), {2, 0, 1});  // duplicate of {0,1,2}, same winding
  m.normals.assign(3 * 5, 0.0f);
  m.normals[3 * 3] = 7.0f;  // marks vertex 3 so we can see it follow its vertex
  const model::CleanupSummary s = model::clean_mesh(m);
  EXPECT_EQ(s.dropped_degenerate_triangles, 1u);
  EXPECT_EQ(s.dropped_duplicate_triangles, 1u);
  EXPECT_EQ(s.dropped_unused_vertices, 1u);
  EXPECT_EQ(m.vertex_count(), 4u);
  EXPECT_EQ(m.normals.size(), 12u);
  EXPECT_EQ(m.normals[9], 7.0f);
  EXPECT_TRUE(analyze(m).is_closed_manifold());
  EXPECT_EQ(m.triangles, test::tetrahedron().triangles);
}

TEST(CleanMesh, WeldingSeparateCornersRestoresAClosedTetrahedron) {
  // STL-style: every triangle has its own three vertices.
  const model::Mesh tet = test::tetrahedron();
  model::Mesh soup;
  for (std::uint32_t v : tet.triangles) {
    soup.positions.insert(soup.positions.end(), &tet.positions[3 * v], &tet.positions[3 * v] + 3);
    soup.triangles.push_back(static_cast<std::uint32_t>(soup.triangles.size()));
  }
  EXPECT_EQ(analyze(soup).boundary_edges, 12u);
  model::CleanupOptions options;
  options.weld_duplicate_positions = true;
  const model::CleanupSummary s = model::clean_mesh(soup, options);
  EXPECT_EQ(s.welded_vertices, 8u);  // 12 corners become 4 vertices
  EXPECT_EQ(s.dropped_unused_vertices, 0u);
  EXPECT_EQ(soup.vertex_count(), 4u);
  EXPECT_TRUE(analyze(soup).is_closed_manifold());
}

// Brute-force census with ordered containers: independent of the sort-based implementation.
TEST(AnalyzeTopology, EdgeCountsMatchBruteForceOnRandomSoups) {
  std::mt19937 rng(7);
  for (int round = 0; round < 50; ++round) {
    model::Mesh m;
    const std::uint32_t n = 4 + rng() % 30;
    for (std::uint32_t v = 0; v < n; ++v) {
      for (int c = 0; c < 3; ++c) m.positions.push_back(static_cast<float>(rng() % 1000));
    }
    const std::uint32_t faces = 1 + rng() % 60;
    for (std::uint32_t f = 0; f < faces; ++f) {
      std::uint32_t a = rng() % n, b = rng() % n, c = rng() % n;
      if (a == b || b == c || a == c) continue;
      m.triangles.insert(m.triangles.end(), {a, b, c});
    }
    if (m.triangles.empty()) continue;
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::pair<int, int>> edges;  // forward, backward
    std::set<std::uint32_t> used;
    for (std::size_t t = 0; t < m.triangle_count(); ++t) {
      for (int k = 0; k < 3; ++k) {
        const std::uint32_t a = m.triangles[3 * t + k], b = m.triangles[3 * t + (k + 1) % 3];
        used.insert(a);
        auto& e = edges[{std::min(a, b), std::max(a, b)}];
        (a < b ? e.first : e.second) += 1;
      }
    }
    std::size_t boundary = 0, non_manifold = 0, clashing = 0;
    for (const auto& [key, e] : edges) {
      const int count = e.first + e.second;
      boundary += count == 1;
      non_manifold += count > 2;
      clashing += count == 2 && e.first != e.second;
    }
    const model::TopologyReport r = analyze(m);
    EXPECT_EQ(r.edges, edges.size());
    EXPECT_EQ(r.boundary_edges, boundary);
    EXPECT_EQ(r.non_manifold_edges, non_manifold);
    EXPECT_EQ(r.inconsistent_edges, clashing);
    EXPECT_EQ(r.unused_vertices, n - used.size());
    EXPECT_EQ(r.euler_characteristic, static_cast<std::int64_t>(used.size()) -
                                          static_cast<std::int64_t>(edges.size()) +
                                          static_cast<std::int64_t>(m.triangle_count()));
  }
}

}  // namespace
}  // namespace mtlod::core

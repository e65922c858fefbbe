// Labels (core/ARCHITECTURE.md §1.4–1.5) on hand-made scenes: a square and a sphere seen from known
// cameras; labels and region membership are checked against the papers' definitions computed
// directly from the occupancy or from closed forms, not through the same code path.
#include "core/view/labels.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <vector>

#include "core/view/occupancy.hpp"
#include "tests/core/test_scenes.hpp"

namespace mtlod::core {
namespace {

// A (n+1)×(n+1) vertex grid over the rectangle, two triangles per quad.
test::Scene tessellated_rectangle(float x0, float y0, float x1, float y1, std::uint32_t n) {
  test::Scene s;
  for (std::uint32_t r = 0; r <= n; ++r)
    for (std::uint32_t c = 0; c <= n; ++c)
      s.positions.insert(s.positions.end(), {x0 + (x1 - x0) * c / n, y0 + (y1 - y0) * r / n, 0.0f});
  for (std::uint32_t r = 0; r < n; ++r) {
    for (std::uint32_t c = 0; c < n; ++c) {
      const std::uint32_t a = r * (n + 1) + c;
      s.triangles.insert(s.triangles.end(), {a, a + 1, a + n + 2, a, a + n + 2, a + n + 1});
    }
  }
  return s;
}

TEST(Labels, SquareSeenHeadOnHasLabelsGrowingInwardFromTheContour) {
  // Ortho 8×8 over [-2, 2]²: the rectangle covers columns 2..5 and rows 1..5 (see the occupancy
  // test), so its cells' nearest background is straight across one of its sides and the 5-7-11 label
  // of cell (i, j) is 5·min(i − 1, 6 − i, j, 6 − j) — 5 on the ring, 10 inside.
  const view::ViewMapping mapping = test::ortho_camera(2.0f, 8);
  const view::GridSize grid = mapping.grid();
  const test::Scene square = tessellated_rectangle(-0.9f, -0.6f, 0.6f, 1.1f, 6);
  std::vector<std::uint8_t> occupancy(grid.cell_count());
  view::rasterize_occupancy(mapping, square.positions, square.triangles, occupancy);
  std::vector<std::uint16_t> dt(grid.cell_count());
  view::chamfer_5_7_11(occupancy, grid, dt);
  const std::size_t n = square.vertex_count();
  std::vector<std::uint32_t> cells(n), labels(n);
  std::vector<float> clip_w(n);
  view::map_vertices(mapping, square.positions, cells, clip_w);
  view::label_vertices(cells, dt, labels);
  std::size_t inner = 0;
  for (std::size_t v = 0; v < n; ++v) {
    const float x = square.positions[3 * v], y = square.positions[3 * v + 1];
    const int i = static_cast<int>((x + 2.0f) * 2.0f), j = static_cast<int>((2.0f - y) * 2.0f);
    const std::uint32_t expected = 5 * static_cast<std::uint32_t>(std::min({i - 1, 6 - i, j, 6 - j}));
    EXPECT_EQ(labels[v], expected) << "vertex " << v << " in cell " << i << "," << j;
    inner += expected == 10;
  }
  EXPECT_GT(inner, 0u);  // the scene has vertices in interior cells too
  // Triangle label = min over its vertices; the region d = 1 px (raw 5) holds exactly the triangles
  // with a vertex in a ring cell.
  std::vector<std::uint32_t> triangle_labels(square.triangles.size() / 3);
  view::label_triangles(square.triangles, labels, triangle_labels);
  std::vector<std::uint8_t> in_region(triangle_labels.size());
  const std::size_t count = view::region_triangles(
      triangle_labels, view::raw_threshold(1.0f, view::DistanceMetric::kChamfer5711), in_region);
  std::size_t expected_count = 0;
  for (std::size_t t = 0; t < triangle_labels.size(); ++t) {
    const std::uint32_t* tri = square.triangles.data() + 3 * t;
    const std::uint32_t expected = std::min({labels[tri[0]], labels[tri[1]], labels[tri[2]]});
    EXPECT_EQ(triangle_labels[t], expected);
    const bool touches_ring = labels[tri[0]] == 5 || labels[tri[1]] == 5 || labels[tri[2]] == 5;
    EXPECT_EQ(in_region[t] != 0, touches_ring);
    expected_count += touches_ring;
  }
  EXPECT_EQ(count, expected_count);
  EXPECT_LT(count, triangle_labels.size());  // some triangles lie wholly inside
}

TEST(Labels, SphereRegionHoldsExactlyTrianglesTouchingContourCells) {
  // A sphere of radius 1.5 seen orthographically over [-2, 2]² on 64×64: silhouette mode. The papers'
  // region for d = 1 px is the triangles having a vertex in a contour cell, i.e. an object cell with a
  // background edge neighbour; that is computed here from the occupancy alone.
  const view::ViewMapping mapping = test::ortho_camera(2.0f, 64);
  const view::GridSize grid = mapping.grid();
  const test::Scene sphere = test::uv_sphere(1.5f, 40, 80);
  std::vector<std::uint8_t> occupancy(grid.cell_count());
  view::rasterize_occupancy(mapping, sphere.positions, sphere.triangles, occupancy);
  std::vector<std::uint16_t> dt(grid.cell_count());
  view::chamfer_5_7_11(occupancy, grid, dt);
  const std::size_t n = sphere.vertex_count();
  std::vector<std::uint32_t> cells(n), labels(n);
  std::vector<float> clip_w(n);
  view::map_vertices(mapping, sphere.positions, cells, clip_w);
  view::label_vertices(cells, dt, labels);
  auto contour_cell = [&](std::uint32_t c) {
    const std::uint32_t i = c % grid.width, j = c / grid.width;
    if (occupancy[c] == 0) return false;
    return (i > 0 && occupancy[c - 1] == 0) || (i + 1 < grid.width && occupancy[c + 1] == 0) ||
           (j > 0 && occupancy[c - grid.width] == 0) ||
           (j + 1 < grid.height && occupancy[c + grid.width] == 0);
  };
  std::vector<std::uint32_t> triangle_labels(sphere.triangles.size() / 3);
  view::label_triangles(sphere.triangles, labels, triangle_labels);
  std::vector<std::uint8_t> in_region(triangle_labels.size());
  view::region_triangles(triangle_labels, view::raw_threshold(1.0f, view::DistanceMetric::kChamfer5711),
                         in_region);
  std::size_t region = 0;
  for (std::size_t t = 0; t < triangle_labels.size(); ++t) {
    const std::uint32_t* tri = sphere.triangles.data() + 3 * t;
    const bool expected =
        contour_cell(cells[tri[0]]) || contour_cell(cells[tri[1]]) || contour_cell(cells[tri[2]]);
    ASSERT_EQ(in_region[t] != 0, expected) << "triangle " << t;
    region += expected;
  }
  EXPECT_GT(region, 100u);
  EXPECT_LT(region, triangle_labels.size() / 2);
  // Rim vertices (on the outline, z = 0 and |(x, y)| = 1.5) lie in an object cell whose outward
  // diagonal neighbour is outside the inscribed outline polygon, so their label is 5 or 7; at the
  // four axis points it is 5.
  for (std::size_t v = 0; v < n; ++v) {
    if (std::abs(sphere.positions[3 * v + 2]) > 1e-6f) continue;
    EXPECT_TRUE(labels[v] == 5 || labels[v] == 7) << "rim vertex " << v << " label " << labels[v];
  }
  EXPECT_EQ(labels[0], 5u);  // north pole, (0, 1.5, 0)
}

// 5-7-11 distance between cells dx, dy apart on an unbounded grid (knight, diagonal and edge moves):
// with a ≥ b the larger and smaller offsets, 5a + b when a ≥ 2b, else 4a + 3b.
std::uint32_t chamfer_5711_closed_form(int dx, int dy) {
  const int a = std::max(std::abs(dx), std::abs(dy)), b = std::min(std::abs(dx), std::abs(dy));
  return static_cast<std::uint32_t>(a >= 2 * b ? 5 * a + b : 4 * a + 3 * b);
}

TEST(Labels, FocusLabelsAreChamferDistanceToTheNearestFocus) {
  // Focus mode on the sphere scene with two foci: every vertex's label is the closed-form 5-7-11
  // distance from its cell to the nearer focus cell.
  const view::ViewMapping mapping = test::ortho_camera(2.0f, 64);
  const view::GridSize grid = mapping.grid();
  const test::Scene sphere = test::uv_sphere(1.5f, 30, 60);
  const std::vector<std::uint32_t> foci = {view::focus_cell(grid, 0.5f, 0.5f),
                                           view::focus_cell(grid, 0.2f, 0.7f)};
  std::vector<std::uint16_t> dt(grid.cell_count());
  view::DistanceTransformer().chamfer_from_cells(view::DistanceMetric::kChamfer5711, foci, grid, dt);
  for (std::uint32_t v = 0; v < sphere.vertex_count(); ++v) {
    const std::uint32_t label =
        view::vertex_label(mapping, sphere.positions, v, std::span<const std::uint16_t>(dt));
    const std::uint32_t c =
        mapping.map_point(sphere.positions[3 * v], sphere.positions[3 * v + 1], sphere.positions[3 * v + 2]);
    ASSERT_NE(c, view::kNoCell);
    std::uint32_t expected = 0xFFFFFFFFu;
    for (const std::uint32_t f : foci) {
      expected =
          std::min(expected, chamfer_5711_closed_form(static_cast<int>(c % 64) - static_cast<int>(f % 64),
                                                      static_cast<int>(c / 64) - static_cast<int>(f / 64)));
    }
    ASSERT_EQ(label, expected) << "vertex " << v;
  }
}

TEST(Labels, VerticesWithoutCellOrSeedGetSentinelsThatLoseTheMinimum) {
  const std::vector<std::uint16_t> dt = {0, 5, view::kChamferUnreached, 10};
  const std::vector<std::uint32_t> cells = {3, view::kNoCell, 2, 1};
  std::vector<std::uint32_t> labels(4);
  view::label_vertices(cells, dt, labels);
  EXPECT_EQ(labels, (std::vector<std::uint32_t>{10, view::kLabelNoCell, view::kLabelUnreached, 5}));
  // A triangle with one vertex in view takes that vertex's label; no-cell and unreached alone stay out
  // of every region.
  const std::vector<std::uint32_t> triangles = {1, 2, 0, 1, 2, 2, 1, 1, 1};
  std::vector<std::uint32_t> triangle_labels(3);
  view::label_triangles(triangles, labels, triangle_labels);
  EXPECT_EQ(triangle_labels, (std::vector<std::uint32_t>{10, view::kLabelUnreached, view::kLabelNoCell}));
  std::vector<std::uint8_t> in_region(3);
  EXPECT_EQ(view::region_triangles(triangle_labels, 0xFFFFFFFFu, in_region), 1u);
}

}  // namespace
}  // namespace mtlod::core

// Occupancy (core/ARCHITECTURE.md §1.2): rasterization marks exactly the cells a triangle meets,
// tiny triangles included; triangles behind the camera are clipped; depth discontinuities seed.
#include "core/view/occupancy.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <limits>
#include <random>
#include <unordered_map>
#include <vector>

#include "core/view/distance_transform.hpp"
#include "core/view/occupancy_levels.hpp"
#include "tests/core/test_scenes.hpp"

namespace mtlod::core {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

using test::ortho_camera;
using test::rectangle;

// Cells of `occupancy` that are set, as (i, j) ids.
std::vector<std::uint32_t> set_cells(const std::vector<std::uint8_t>& occupancy) {
  std::vector<std::uint32_t> cells;
  for (std::uint32_t c = 0; c < occupancy.size(); ++c)
    if (occupancy[c] != 0) cells.push_back(c);
  return cells;
}

TEST(Occupancy, TriangleSmallerThanACellMarksItsCell) {
  // Ortho over [-2, 2]² on 8×8: a cell is 0.5 units. Corners near (0.1, 0.1) map to about (4.2, 3.8).
  const view::ViewMapping mapping = ortho_camera(2.0f, 8);
  const std::vector<float> positions = {0.1f, 0.1f, 0.0f, 0.12f, 0.1f, 0.0f, 0.1f, 0.12f, 0.0f};
  const std::vector<std::uint32_t> triangles = {0, 1, 2, 0, 0, 0};  // the second is a single point
  std::vector<std::uint8_t> occupancy(64, 7);
  EXPECT_EQ(view::rasterize_occupancy(mapping, positions, triangles, occupancy), 2u);
  EXPECT_EQ(set_cells(occupancy), std::vector<std::uint32_t>{mapping.grid().cell(4, 3)});
}

TEST(Occupancy, SquareSeenHeadOnMarksExactlyItsCells) {
  // Rectangle [-0.9, 0.6] × [-0.6, 1.1] on the 8×8 grid over [-2, 2]²: x ↦ (x + 2)·2 spans
  // [2.2, 5.2] → columns 2..5; y ↦ (2 − y)·2 spans [1.8, 5.2] → rows 1..5. 4 × 5 = 20 cells; the
  // shared diagonal adds none.
  const view::ViewMapping mapping = ortho_camera(2.0f, 8);
  const test::Scene square = rectangle(-0.9f, -0.6f, 0.6f, 1.1f, 0.0f);
  std::vector<std::uint8_t> occupancy(64);
  std::vector<float> depth(64);
  view::rasterize_occupancy(mapping, square.positions, square.triangles, occupancy, depth);
  std::vector<std::uint32_t> expected;
  for (std::uint32_t j = 1; j <= 5; ++j)
    for (std::uint32_t i = 2; i <= 5; ++i) expected.push_back(mapping.grid().cell(i, j));
  EXPECT_EQ(set_cells(occupancy), expected);
  // The camera sits at z = 5, so every covered cell is 5 units deep. Tolerance: the depth goes
  // through float ndc.z and back (relative error ~1e-6 of the 0.1..10 depth range).
  for (std::uint32_t c = 0; c < 64; ++c) {
    if (occupancy[c] != 0)
      EXPECT_NEAR(depth[c], 5.0f, 1e-4f) << c;
    else
      EXPECT_EQ(depth[c], std::numeric_limits<float>::infinity()) << c;
  }
}

// Exact reference: does the closed triangle meet the closed square [i, i+1] × [j, j+1]? Separating
// axis test on the two box axes and the three edge normals, in double.
bool triangle_meets_cell(const double (&p)[3][2], double i, double j) {
  double axes[5][2] = {{1, 0}, {0, 1}};
  for (int k = 0; k < 3; ++k) {
    axes[2 + k][0] = -(p[(k + 1) % 3][1] - p[k][1]);
    axes[2 + k][1] = p[(k + 1) % 3][0] - p[k][0];
  }
  const double box[4][2] = {{i, j}, {i + 1, j}, {i, j + 1}, {i + 1, j + 1}};
  for (const auto& a : axes) {
    double tmin = 1e300, tmax = -1e300, bmin = 1e300, bmax = -1e300;
    for (const auto& q : p) {
      tmin = std::min(tmin, a[0] * q[0] + a[1] * q[1]);
      tmax = std::max(tmax, a[0] * q[0] + a[1] * q[1]);
    }
    for (const auto& q : box) {
      bmin = std::min(bmin, a[0] * q[0] + a[1] * q[1]);
      bmax = std::max(bmax, a[0] * q[0] + a[1] * q[1]);
    }
    if (tmax < bmin || bmax < tmin) return false;
  }
  return true;
}

TEST(Occupancy, RandomTrianglesMarkExactlyTheCellsTheyMeet) {
  // Orthographic over [-1, 1]² on 32×32: grid coordinates are (x + 1)·16 and (1 − y)·16, so the
  // reference works on those. Triangles of every size, some partly off the grid.
  const view::ViewMapping mapping = ortho_camera(1.0f, 32);
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> centre(-1.1f, 1.1f), size(0.0f, 0.4f), offset(-1.0f, 1.0f);
  for (int trial = 0; trial < 300; ++trial) {
    const float cx = centre(rng), cy = centre(rng), s = size(rng) * size(rng) * 3.0f;
    std::vector<float> positions;
    double p[3][2];
    for (int k = 0; k < 3; ++k) {
      const float x = cx + s * offset(rng), y = cy + s * offset(rng);
      positions.insert(positions.end(), {x, y, 0.0f});
      p[k][0] = (static_cast<double>(x) + 1.0) * 16.0;
      p[k][1] = (1.0 - static_cast<double>(y)) * 16.0;
    }
    std::vector<std::uint8_t> occupancy(32 * 32);
    view::rasterize_occupancy(mapping, positions, std::vector<std::uint32_t>{0, 1, 2}, occupancy);
    for (std::uint32_t j = 0; j < 32; ++j) {
      for (std::uint32_t i = 0; i < 32; ++i) {
        ASSERT_EQ(occupancy[j * 32 + i] != 0, triangle_meets_cell(p, i, j))
            << "trial " << trial << " cell " << i << "," << j;
      }
    }
  }
}

TEST(Occupancy, ManyTrianglesMarkTheUnionOfTheirCells) {
  // Small triangles drawn into one grid: each must add its cells without clearing its neighbours'
  // (small boxes are written 16 cells at a time, past the box and into the next row), up to the
  // grid's last cells.
  const view::ViewMapping mapping = ortho_camera(1.0f, 32);
  std::mt19937 rng(47);
  std::uniform_real_distribution<float> centre(-1.0f, 1.0f), size(0.0f, 0.3f), offset(-1.0f, 1.0f);
  for (int trial = 0; trial < 40; ++trial) {
    std::vector<float> positions;
    std::vector<std::uint32_t> triangles;
    std::vector<std::array<std::array<double, 2>, 3>> projected;
    for (std::uint32_t t = 0; t < 25; ++t) {
      const float cx = centre(rng), cy = centre(rng), s = size(rng) * size(rng);
      std::array<std::array<double, 2>, 3> p;
      for (int k = 0; k < 3; ++k) {
        const float x = cx + s * offset(rng), y = cy + s * offset(rng);
        positions.insert(positions.end(), {x, y, 0.0f});
        triangles.push_back(3 * t + k);
        p[k] = {(static_cast<double>(x) + 1.0) * 16.0, (1.0 - static_cast<double>(y)) * 16.0};
      }
      projected.push_back(p);
    }
    std::vector<std::uint8_t> occupancy(32 * 32, 7);  // overwritten
    view::rasterize_occupancy(mapping, positions, triangles, occupancy);
    for (std::uint32_t j = 0; j < 32; ++j) {
      for (std::uint32_t i = 0; i < 32; ++i) {
        bool met = false;
        for (const auto& p : projected) {
          const double q[3][2] = {{p[0][0], p[0][1]}, {p[1][0], p[1][1]}, {p[2][0], p[2][1]}};
          met = met || triangle_meets_cell(q, i, j);
        }
        ASSERT_EQ(occupancy[j * 32 + i], met ? 1 : 0) << "trial " << trial << " cell " << i << "," << j;
      }
    }
  }
}

TEST(Occupancy, TrianglesBehindTheCameraAreClippedAway) {
  // Perspective camera at the origin looking down −z, 90°, 16×16 grid.
  view::Camera camera;
  camera.view = glm::lookAt(glm::vec3(0, 0, 0), glm::vec3(0, 0, -1), glm::vec3(0, 1, 0));
  camera.projection = glm::perspective(glm::radians(90.0f), 1.0f, 0.1f, 100.0f);
  const view::ViewMapping mapping(camera, view::GridSize{16, 16});
  std::vector<std::uint8_t> occupancy(256);
  // Entirely behind: nothing.
  const std::vector<float> behind = {-1, -1, 2, 1, -1, 2, 0, 1, 3};
  EXPECT_EQ(view::rasterize_occupancy(mapping, behind, std::vector<std::uint32_t>{0, 1, 2}, occupancy), 0u);
  EXPECT_TRUE(set_cells(occupancy).empty());
  // Partly behind: the front corners' cells are marked, (4, 12) and (12, 12). The two edges to the
  // third corner leave the front half-space at y ≈ −0.2 (t = 0.4 and 0.6 along them), just below the
  // eye, so the visible part runs down to the grid's bottom row; nothing is drawn above row 12.
  const std::vector<float> straddling = {-1, -1, -2, 1, -1, -2, 0, 1, 3};
  EXPECT_EQ(view::rasterize_occupancy(mapping, straddling, std::vector<std::uint32_t>{0, 1, 2}, occupancy),
            1u);
  EXPECT_NE(occupancy[mapping.map_point(-1, -1, -2)], 0);
  EXPECT_NE(occupancy[mapping.map_point(1, -1, -2)], 0);
  EXPECT_NE(occupancy[mapping.grid().cell(8, 15)], 0);
  EXPECT_NE(occupancy[mapping.grid().cell(0, 15)], 0);
  EXPECT_EQ(occupancy[mapping.grid().cell(8, 11)], 0);
  EXPECT_EQ(occupancy[mapping.grid().cell(8, 0)], 0);
}

TEST(Occupancy, CompactRasterisationEqualsThePlainOne) {
  // A perspective camera inside a cloud of triangles of every size, some straddling the eye plane,
  // with vertices shared between triangles: the compact variant projects each vertex once and must
  // mark the same cells, count the same triangles and write the same depths, bit for bit.
  view::Camera camera;
  camera.view = glm::lookAt(glm::vec3(0, 0, 0), glm::vec3(0, 0, -1), glm::vec3(0, 1, 0));
  camera.projection = glm::perspective(glm::radians(70.0f), 1.3f, 0.1f, 100.0f);
  const view::ViewMapping mapping(camera, view::GridSize{97, 64});
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> coordinate(-6.0f, 6.0f), depth(-12.0f, 1.0f), nudge(-0.3f, 0.3f);
  std::vector<float> positions;
  for (int v = 0; v < 3000; ++v)
    positions.insert(positions.end(), {coordinate(rng), coordinate(rng), depth(rng)});
  // Small triangles around random vertices, plus large ones between random vertices.
  std::vector<std::uint32_t> local, triangles;
  std::uniform_int_distribution<std::uint32_t> pick(0, 2999);
  for (int t = 0; t < 4000; ++t) {
    for (int k = 0; k < 3; ++k) triangles.push_back(pick(rng));
  }
  for (int t = 0; t < 2000; ++t) {
    const std::uint32_t base = pick(rng);
    const std::uint32_t added = static_cast<std::uint32_t>(positions.size() / 3);
    for (int k = 0; k < 2; ++k) {
      positions.insert(positions.end(),
                       {positions[3 * base] + nudge(rng), positions[3 * base + 1] + nudge(rng),
                        positions[3 * base + 2] + nudge(rng)});
    }
    triangles.insert(triangles.end(), {base, added, added + 1});
  }
  // The compact copy: used vertices only, in first-use order, triangles renumbered.
  std::vector<float> compact;
  std::unordered_map<std::uint32_t, std::uint32_t> index;
  for (const std::uint32_t v : triangles) {
    const auto [it, added] = index.try_emplace(v, static_cast<std::uint32_t>(compact.size() / 3));
    if (added)
      compact.insert(compact.end(), &positions[3 * std::size_t{v}], &positions[3 * std::size_t{v} + 3]);
    local.push_back(it->second);
  }
  std::vector<view::ProjectedCorner> scratch;
  for (const bool with_depth : {false, true}) {
    std::vector<std::uint8_t> plain(mapping.grid().cell_count()), indexed(mapping.grid().cell_count(), 9);
    std::vector<float> plain_depth(with_depth ? plain.size() : 0), indexed_depth(plain_depth.size());
    const std::size_t a = view::rasterize_occupancy(mapping, positions, triangles, plain, plain_depth);
    const std::size_t b =
        view::rasterize_occupancy_compact(mapping, compact, local, indexed, indexed_depth, scratch);
    EXPECT_EQ(a, b);
    EXPECT_GT(a, 1000u);
    EXPECT_EQ(plain, indexed);
    ASSERT_EQ(plain_depth.size(), indexed_depth.size());
    if (with_depth) {
      EXPECT_EQ(std::memcmp(plain_depth.data(), indexed_depth.data(), plain_depth.size() * sizeof(float)), 0);
    }
  }
}

// A perspective camera at `eye` looking at the origin, on a side×side grid.
view::ViewMapping perspective_camera(glm::vec3 eye, std::uint32_t side) {
  view::Camera camera;
  camera.view = glm::lookAt(eye, glm::vec3(0, 0, 0), glm::vec3(0, 1, 0));
  camera.projection = glm::perspective(glm::radians(50.0f), 1.0f, 0.1f, 100.0f);
  return view::ViewMapping(camera, view::GridSize{side, side});
}

TEST(Occupancy, CappedHolesCloseTheSurface) {
  // A sphere with random triangles removed (single ones, and neighbours that merge into larger
  // holes, some meeting at a vertex): open before, closed after, the caps appended after the
  // surface's triangles and none of them degenerate.
  std::mt19937 rng(5);
  for (int trial = 0; trial < 20; ++trial) {
    test::Scene sphere = test::uv_sphere(1.0f, 12, 16);
    ASSERT_TRUE(view::is_closed_surface(sphere.triangles));
    std::vector<std::uint32_t> open;
    std::bernoulli_distribution drop(0.05 + 0.01 * trial);
    for (std::size_t t = 0; t < sphere.triangles.size(); t += 3)
      if (!drop(rng)) open.insert(open.end(), &sphere.triangles[t], &sphere.triangles[t] + 3);
    if (open.size() == sphere.triangles.size()) continue;
    EXPECT_FALSE(view::is_closed_surface(open));
    const std::size_t cut = open.size() / 3;
    const std::size_t caps = view::cap_holes(open);
    EXPECT_TRUE(view::is_closed_surface(open)) << "trial " << trial;
    EXPECT_EQ(open.size() / 3, cut + caps);
    for (std::size_t t = 3 * cut; t < open.size(); t += 3) {  // caps use the surface's vertices
      EXPECT_NE(open[t], open[t + 1]);
      EXPECT_NE(open[t + 1], open[t + 2]);
      EXPECT_NE(open[t], open[t + 2]);
    }
  }
}

TEST(Occupancy, CappedHolesCloseSheetsThatMeetOnAnEdge) {
  // Coarse cuts whose topology the builder changed join sheets: an edge with three faces, two of
  // them walking it the same way. Three open quads fanned around one shared edge (not all the same
  // way round), a book of three pages, and a closed sphere with a quad glued to one of its edges:
  // closed after capping.
  const std::vector<std::vector<std::uint32_t>> cases = {
      // edge (0, 1) walked as 0->1 twice and 1->0 once
      {0, 1, 2, 2, 1, 3, 0, 1, 4, 4, 1, 5, 1, 0, 6, 6, 0, 7},
      // a book: two pages the same way round and one the other way
      {0, 1, 2, 0, 1, 3, 1, 0, 4},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    std::vector<std::uint32_t> triangles = cases[i];
    EXPECT_FALSE(view::is_closed_surface(triangles)) << i;
    view::cap_holes(triangles);
    EXPECT_TRUE(view::is_closed_surface(triangles)) << i;
  }
  test::Scene sphere = test::uv_sphere(1.0f, 8, 10);
  std::vector<std::uint32_t> glued = sphere.triangles;
  const std::uint32_t a = sphere.triangles[0], b = sphere.triangles[1];
  const std::uint32_t extra = static_cast<std::uint32_t>(sphere.positions.size() / 3);
  glued.insert(glued.end(), {a, b, extra, a, extra, extra + 1});  // walks (a, b) as the sphere's face does
  EXPECT_FALSE(view::is_closed_surface(glued));
  view::cap_holes(glued);
  EXPECT_TRUE(view::is_closed_surface(glued));
}

TEST(Occupancy, ClosedSurfacesRasteriseOneSideOnly) {
  // Rasterising only the triangles of one orientation gives the same cells as all of them, for
  // closed surfaces seen from anywhere in front: spheres, capped spheres with holes, and spheres
  // whose vertices are scattered at random (the same closed connectivity, folded over itself in
  // every direction). With a vertex behind the camera everything is rasterised.
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f), distance(2.5f, 6.0f);
  std::vector<view::ProjectedCorner> scratch;
  for (int trial = 0; trial < 60; ++trial) {
    test::Scene scene = test::uv_sphere(1.0f, 6 + trial % 7, 8 + trial % 5);
    if (trial % 3 == 1) {
      std::vector<std::uint32_t> open;
      for (std::size_t t = 0; t < scene.triangles.size(); t += 3)
        if (rng() % 8 != 0) open.insert(open.end(), &scene.triangles[t], &scene.triangles[t] + 3);
      view::cap_holes(open);
      scene.triangles = open;
    } else if (trial % 3 == 2) {
      for (float& p : scene.positions) p = 0.9f * unit(rng);
    }
    ASSERT_TRUE(view::is_closed_surface(scene.triangles));
    glm::vec3 direction(unit(rng), unit(rng), unit(rng));
    if (glm::length(direction) < 0.1f) direction = glm::vec3(0, 0, 1);
    const glm::vec3 eye = glm::normalize(direction) * (trial % 10 == 9 ? 0.3f : distance(rng));
    const view::ViewMapping mapping = perspective_camera(eye, 48);
    std::vector<std::uint8_t> all(mapping.grid().cell_count()), one_side(all.size());
    const std::size_t rasterised_all =
        view::rasterize_occupancy_compact(mapping, scene.positions, scene.triangles, all, {}, scratch);
    const std::size_t rasterised = view::rasterize_occupancy_compact(
        mapping, scene.positions, scene.triangles, one_side, {}, scratch, true);
    ASSERT_EQ(all, one_side) << "trial " << trial;
    if (trial % 10 == 9) {
      EXPECT_EQ(rasterised, rasterised_all);  // the eye inside: nothing skipped
    } else {
      EXPECT_LT(rasterised, rasterised_all) << "trial " << trial;
    }
  }
}

TEST(Occupancy, DepthJumpSeedsTheFartherSide) {
  // A front rectangle (z = 1, depth 4) over a back one filling the view (z = −3, depth 8), ortho
  // 8×8 over [-2, 2]². The front one covers columns 2..5 and rows 1..5 (as in the head-on test); the
  // back cells 4-adjacent to it are the ring: 5 + 5 left/right, 4 + 4 above/below = 18 cells.
  const view::ViewMapping mapping = ortho_camera(2.0f, 8);
  test::Scene scene = rectangle(-2.5f, -2.5f, 2.5f, 2.5f, -3.0f);
  const test::Scene front = rectangle(-0.9f, -0.6f, 0.6f, 1.1f, 1.0f);
  for (const float p : front.positions) scene.positions.push_back(p);
  for (const std::uint32_t t : front.triangles) scene.triangles.push_back(t + 4);
  std::vector<std::uint8_t> occupancy(64);
  std::vector<float> depth(64);
  view::rasterize_occupancy(mapping, scene.positions, scene.triangles, occupancy, depth);
  std::vector<std::uint8_t> image = occupancy;
  EXPECT_EQ(view::mark_depth_discontinuities(depth, mapping.grid(), 0.1f, image), 18u);
  // The internal silhouette now behaves like the external one: the front rectangle's border cells
  // are one edge step (5) from a seed, its interior cells 10.
  std::vector<std::uint16_t> dt(64);
  view::chamfer_5_7_11(image, mapping.grid(), dt);
  EXPECT_EQ(dt[mapping.grid().cell(2, 1)], 5);
  EXPECT_EQ(dt[mapping.grid().cell(3, 3)], 10);
  EXPECT_EQ(dt[mapping.grid().cell(1, 3)], 0);
  // A 20 % threshold is still exceeded by the 4 → 8 jump; 150 % is not.
  image = occupancy;
  EXPECT_EQ(view::mark_depth_discontinuities(depth, mapping.grid(), 1.5f, image), 0u);
}

// Hidden-surface coarsening's bound against its definition: every cell's largest depth over its 3×3
// neighbourhood, off-grid neighbours counting as background (+inf), on grids of several shapes.
TEST(Occupancy, VisibleDepthBoundIsTheLargestDepthAroundEachCell) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> depth_of(1.0f, 9.0f);
  std::bernoulli_distribution background(0.1);
  for (const view::GridSize grid :
       {view::GridSize{1, 1}, view::GridSize{7, 5}, view::GridSize{5, 7}, view::GridSize{64, 48}}) {
    std::vector<float> depth(grid.cell_count());
    for (float& d : depth) d = background(rng) ? kInf : depth_of(rng);
    std::vector<float> bound(grid.cell_count());
    view::visible_depth_bound(depth, grid, bound);
    for (std::uint32_t j = 0; j < grid.height; ++j) {
      for (std::uint32_t i = 0; i < grid.width; ++i) {
        float expected = -kInf;
        for (int dj = -1; dj <= 1; ++dj) {
          for (int di = -1; di <= 1; ++di) {
            const int x = int(i) + di, y = int(j) + dj;
            const bool on_grid = x >= 0 && y >= 0 && x < int(grid.width) && y < int(grid.height);
            expected = std::max(expected, on_grid ? depth[grid.cell(x, y)] : kInf);
          }
        }
        ASSERT_EQ(bound[grid.cell(i, j)], expected) << "cell " << i << ", " << j;
      }
    }
  }
  // A surface at one depth with no background near: the bound is that depth inside, +inf at the rim.
  const view::GridSize ten{10, 10};
  std::vector<float> flat(ten.cell_count(), 3.0f), bound(ten.cell_count());
  view::visible_depth_bound(flat, ten, bound);
  EXPECT_EQ(bound[ten.cell(5, 5)], 3.0f);
  EXPECT_EQ(bound[ten.cell(0, 5)], kInf);
}

}  // namespace
}  // namespace mtlod::core

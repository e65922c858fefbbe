// The request pipeline in core (view_extract), end to end on a real MT: the papers' silhouette
// guarantee on the 871k dragon, falling density around a focus, exact Euclidean labels against
// brute force, and occupancy cuts chosen by the model's size on the grid.
#include "core/view/view_extract.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <random>
#include <set>

#include "core/build/mt_builder.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mesh_io.hpp"
#include "core/model/bounds.hpp"
#include "core/view/distance_transform.hpp"
#include "core/view/labels.hpp"
#include "core/view/occupancy.hpp"
#include "core/view/occupancy_levels.hpp"
#include "tests/core/cut_validator.hpp"
#include "tests/core/mt_fixtures.hpp"
#include "tests/core/test_meshes.hpp"

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/geometric.hpp>
#include <glm/mat4x4.hpp>
#include <glm/matrix.hpp>

namespace mtlod::core {
namespace {

struct Built {
  model::Mesh input;
  model::Mt mt;
  std::unique_ptr<view::OccupancyLevels> levels;
  bool coarse_topology_changes = false;  // the builder's topology phase made collapses
  bool stacked_faces = false;            // some of them may stack two faces
};

std::unique_ptr<Built> build(model::Mesh mesh) {
  auto b = std::make_unique<Built>();
  b->input = std::move(mesh);
  build::BuildStats stats;
  auto mt = test::build_mt_renumbering(b->input, {}, &stats);
  EXPECT_TRUE(mt.ok()) << mt.error().message;
  if (!mt.ok()) return nullptr;
  b->mt = std::move(*mt);
  b->coarse_topology_changes = stats.topology_collapses > 0;
  b->stacked_faces = stats.stacking_collapses > 0;
  b->levels = view::OccupancyLevels::make(b->mt).value();  // in memory: cannot fail
  return b;
}

// A perspective camera at centre + distance·axis looking at the bounding-box centre of `positions`,
// the whole box in view (for an axis of about unit length).
view::Camera camera_along(std::span<const float> positions, glm::vec3 axis, float aspect) {
  const model::Bounds box = model::bounds_of(positions);
  const std::array<float, 3> middle = box.centre();
  const glm::vec3 centre(middle[0], middle[1], middle[2]);
  const float distance = 1.1f * box.radius() / std::sin(glm::radians(22.5f));
  view::Camera c;
  c.view = glm::lookAt(centre + distance * axis, centre, glm::vec3(0, 1, 0));
  c.projection = glm::perspective(glm::radians(45.0f), aspect, distance / 100, distance * 100);
  return c;
}

// The same from +z.
view::Camera front_camera(const model::Mesh& m, float aspect) {
  return camera_along(m.positions, glm::vec3(0, 0, 1), aspect);
}

void run(view::ViewExtractor& x, const view::ViewRequest& r, cut::Refiner& refiner, cut::CutMesh& cut,
         view::ViewCache* session = nullptr) {
  x.map(r, session);
  x.occupancy();
  x.distance_transforms();
  x.allowed_error();
  EXPECT_TRUE(x.refine(refiner, cut));
}

// What the session tests compare with: a static extraction from nothing that computes every
// vertex's allowed error (with r's budget, if any), in a fresh refiner.
void run_fresh(view::ViewExtractor& x, const model::Mt& mt, view::ViewRequest r, cut::CutMesh& cut) {
  cut::Refiner fresh(mt);
  r.dynamic = false;
  r.allowed_error_on_demand = false;
  r.labels = true;  // every transform over the whole grid: labels read them everywhere
  run(x, r, fresh, cut);
}

// Shared by the dragon tests: one MT build per process.
const Built* dragon() {
  static std::unique_ptr<Built> built = [] {
    const auto path = test::shared_meshes_dir() / "dragon-vrip-871k.ply";
    std::unique_ptr<Built> b;
    if (auto mesh = io::load_mesh(path); mesh.ok()) b = build(std::move(mesh->mesh));
    return b;
  }();
  return built.get();
}

TEST(ViewExtract, DragonSilhouetteRegionIsAtFullResolutionAndTheRestIsCoarser) {
  const Built* d = dragon();
  if (!d) GTEST_SKIP() << "no shared dragon-vrip-871k.ply";
  view::ViewRequest r;
  r.camera = front_camera(d->input, 1.0f);
  r.grid = {256, 256};
  r.allowed.error = 8.0f;  // pixels, outside the region
  r.allowed.units = view::ErrorUnits::kScreenPixels;
  r.allowed.viewport_height_px = 256;
  r.allowed.criteria[view::Criterion::kSilhouette] =
      view::RegionLaw{view::FalloffLaw::kStep, 2.0f, 0.0f};  // d = 2 px, f = 0
  r.labels = true;
  view::ViewExtractor x(d->mt, *d->levels);
  cut::Refiner refiner(d->mt);
  cut::CutMesh cut;
  run(x, r, refiner, cut);

  // Independent labels: the 5-7-11 transform of the extractor's occupancy, each vertex projected
  // through the mapping again.
  std::vector<std::uint16_t> dt(r.grid.cell_count());
  view::chamfer_5_7_11(x.occupancy_grid(), r.grid, dt);
  const std::uint32_t d_raw = view::raw_threshold(2.0f, view::DistanceMetric::kChamfer5711);  // 10
  std::set<std::array<std::uint32_t, 3>> input;
  for (std::size_t t = 0; t < d->input.triangle_count(); ++t) {
    input.insert(test::canonical(d->input.triangles[3 * t], d->input.triangles[3 * t + 1],
                                 d->input.triangles[3 * t + 2]));
  }
  std::size_t in_region = 0, coarse = 0, contour_vertices = 0;
  for (std::size_t t = 0; t < cut.triangle_count(); ++t) {
    const std::uint32_t* v = &cut.triangles[3 * t];
    std::uint32_t label = view::kLabelNoCell;
    for (int c = 0; c < 3; ++c) {
      const std::uint32_t l = view::vertex_label(x.mapping(), std::span<const float>(d->mt.positions), v[c],
                                                 std::span<const std::uint16_t>(dt));
      label = std::min(label, l);
      contour_vertices += l == 5;  // on a contour cell: one step from the background
    }
    const bool original = input.count(test::canonical(v[0], v[1], v[2])) != 0;
    if (label <= d_raw) {
      ++in_region;
      ASSERT_TRUE(original) << "triangle " << t << " with label " << label << " is not at full resolution";
    }
    coarse += !original;
  }
  EXPECT_GT(in_region, 1000u);
  EXPECT_GT(contour_vertices, 0u);
  EXPECT_GT(coarse, 1000u) << "away from the silhouette the cut should be coarser";
  EXPECT_LT(cut.triangle_count(), d->input.triangle_count());
  test::CutReference reference = test::make_reference(d->input);
  reference.coarse_topology_changes = d->coarse_topology_changes;
  reference.stacked_faces = d->stacked_faces;
  EXPECT_TRUE(test::validate_cut(reference, cut.triangles));
  // The labels handed to the encoder are the same labels.
  for (std::size_t i = 0; i < std::min<std::size_t>(cut.triangles.size(), 3000); ++i) {
    const std::uint32_t v = cut.triangles[i];
    ASSERT_EQ(x.vertex_labels()[v], view::vertex_label(x.mapping(), std::span<const float>(d->mt.positions),
                                                       v, std::span<const std::uint16_t>(dt)));
  }
}

TEST(ViewExtract, DragonTriangleDensityFallsWithDistanceFromTheFocus) {
  const Built* d = dragon();
  if (!d) GTEST_SKIP() << "no shared dragon-vrip-871k.ply";
  view::ViewRequest r;
  r.camera = front_camera(d->input, 1.0f);
  r.grid = {256, 256};
  r.allowed.error = 2.0f;
  r.allowed.units = view::ErrorUnits::kScreenPixels;
  r.allowed.viewport_height_px = 256;
  r.allowed.criteria[view::Criterion::kFocus] =
      view::RegionLaw{view::FalloffLaw::kLinear, 10.0f, 0.05f, 80.0f};
  r.points[view::Criterion::kFocus] = {{0.5f, 0.5f}};
  view::ViewExtractor x(d->mt, *d->levels);
  cut::Refiner refiner(d->mt);
  cut::CutMesh cut;
  run(x, r, refiner, cut);
  // Mean projected area of the cut's triangles by rings of 20 cells around the focus cell (128, 128),
  // out to 80 cells: inside the dragon's outline, where grazing triangles at the rim do not blur it.
  constexpr int kRings = 4;
  std::vector<double> areas[kRings];
  for (std::size_t t = 0; t < cut.triangle_count(); ++t) {
    view::GridPoint g[3];
    bool visible = true;
    for (int c = 0; c < 3; ++c) {
      const float* p = &d->mt.positions[3 * std::size_t{cut.triangles[3 * t + c]}];
      float cx, cy, cw;
      x.mapping().clip_xyw(p[0], p[1], p[2], cx, cy, cw);
      visible = visible && cw > 0;
      g[c] = x.mapping().to_grid(cx, cy, cw);
    }
    if (!visible) continue;
    const double mx = (g[0].x + g[1].x + g[2].x) / 3 - 128, my = (g[0].y + g[1].y + g[2].y) / 3 - 128;
    const int ring = static_cast<int>(std::sqrt(mx * mx + my * my) / 20);
    if (ring >= kRings) continue;
    areas[ring].push_back(
        0.5 * std::abs((g[1].x - g[0].x) * (g[2].y - g[0].y) - (g[2].x - g[0].x) * (g[1].y - g[0].y)));
  }
  // Per ring, the area-weighted mean area Σa²/Σa: the size of the triangle under a random covered
  // cell. The dragon's never-collapsed slivers (boundary and non-manifold bits, full resolution in
  // every cut) are many but cover little, so they barely move it, unlike a plain mean or median.
  double size[kRings];
  for (int ring = 0; ring < kRings; ++ring) {
    ASSERT_GT(areas[ring].size(), 20u) << "ring " << ring << " is nearly empty";
    double sum = 0, sum2 = 0;
    for (double a : areas[ring]) sum += a, sum2 += a * a;
    size[ring] = sum2 / sum;
  }
  // Triangles grow ring by ring away from the focus, the outer ring's at least twice the inner's.
  for (int ring = 1; ring < kRings; ++ring) EXPECT_GT(size[ring], size[ring - 1]) << "ring " << ring;
  EXPECT_GT(size[kRings - 1], 2 * size[0]);
}

TEST(ViewExtract, EuclideanLabelsAreExactDistancesInFifthsOfAPixel) {
  eval::GenerateOptions o;
  o.target_triangles = 3000;
  auto b = build(eval::generate_mesh(o));
  ASSERT_NE(b, nullptr);
  view::ViewRequest r;
  r.camera = front_camera(b->input, 1.0f);
  r.grid = {48, 40};
  r.allowed.error = 0.01f;
  r.allowed.criteria[view::Criterion::kSilhouette] = view::RegionLaw{};
  r.allowed.metric = view::DistanceMetric::kEuclidean;
  r.points[view::Criterion::kFocus] = {{0.25f, 0.5f}, {0.8f, 0.1f}};
  r.allowed.criteria[view::Criterion::kFocus] = view::RegionLaw{};
  r.labels = true;  // the focus transform over the whole grid, not only within the law's reach
  view::ViewExtractor x(b->mt, *b->levels);
  cut::Refiner refiner(b->mt);
  cut::CutMesh cut;
  run(x, r, refiner, cut);
  const std::span<const std::uint8_t> occ = x.occupancy_grid();
  std::vector<std::uint32_t> focus_cells = {view::focus_cell(r.grid, 0.25f, 0.5f),
                                            view::focus_cell(r.grid, 0.8f, 0.1f)};
  for (std::uint32_t j = 0; j < r.grid.height; ++j) {
    for (std::uint32_t i = 0; i < r.grid.width; ++i) {
      // Brute force: the nearest background cell, and the nearest focus.
      double best = INFINITY, best_focus = INFINITY;
      for (std::uint32_t jj = 0; jj < r.grid.height; ++jj) {
        for (std::uint32_t ii = 0; ii < r.grid.width; ++ii) {
          const double d2 = double(ii - double(i)) * (ii - double(i)) + (jj - double(j)) * (jj - double(j));
          if (occ[r.grid.cell(ii, jj)] == 0) best = std::min(best, d2);
          if (r.grid.cell(ii, jj) == focus_cells[0] || r.grid.cell(ii, jj) == focus_cells[1])
            best_focus = std::min(best_focus, d2);
        }
      }
      const std::uint32_t c = r.grid.cell(i, j);
      ASSERT_EQ(x.distance_transform(view::Criterion::kSilhouette)[c], std::lround(5 * std::sqrt(best)))
          << "cell " << i << "," << j;
      ASSERT_EQ(x.distance_transform(view::Criterion::kFocus)[c], std::lround(5 * std::sqrt(best_focus)))
          << "cell " << i << "," << j;
    }
  }
}

// The screen-edge criterion: its labels are the 5-7-11 distance to the grid's border (5 per cell
// straight in: the nearest border cell is straight out), and a vertex's allowed error is e·F within
// D of the edge and e elsewhere.
TEST(ViewExtract, ScreenEdgeCoarsensWithinItsDistanceOfTheBorder) {
  eval::GenerateOptions o;
  o.target_triangles = 3000;
  auto b = build(eval::generate_mesh(o));
  ASSERT_NE(b, nullptr);
  view::ViewRequest r;
  // Twice as close as framing: the model fills the view and crosses its edges.
  r.camera = camera_along(b->input.positions, glm::vec3(0, 0, 0.5f), 1.0f);
  r.grid = {48, 40};
  r.allowed.error = 0.01f;
  r.allowed.outside_view_factor = 1.0f;
  constexpr float kDistance = 6.0f, kFactor = 4.0f;
  r.allowed.criteria[view::Criterion::kScreenEdge] =
      view::RegionLaw{view::FalloffLaw::kStep, kDistance, kFactor};
  view::ViewExtractor x(b->mt, *b->levels);
  const std::span<const float> allowed = x.allowed_error_field(r);
  const std::span<const std::uint16_t> dt = x.distance_transform(view::Criterion::kScreenEdge);
  ASSERT_EQ(dt.size(), r.grid.cell_count());
  for (std::uint32_t j = 0; j < r.grid.height; ++j) {
    for (std::uint32_t i = 0; i < r.grid.width; ++i) {
      const std::uint32_t cells_to_edge = std::min({i, j, r.grid.width - 1 - i, r.grid.height - 1 - j});
      ASSERT_EQ(dt[r.grid.cell(i, j)], 5 * cells_to_edge) << "cell " << i << "," << j;
    }
  }
  std::size_t near = 0, far = 0;
  for (std::uint32_t v = 0; v < b->mt.vertex_count(); ++v) {
    const float* p = &b->mt.positions[3 * std::size_t{v}];
    const std::uint32_t cell = x.mapping().map_point(p[0], p[1], p[2]);
    if (cell == view::kNoCell) continue;
    const bool within = dt[cell] <= 5 * kDistance;
    ASSERT_EQ(allowed[v], within ? 0.01f * kFactor : 0.01f) << "vertex " << v;
    ++(within ? near : far);
  }
  EXPECT_GT(near, 0u);
  EXPECT_GT(far, 0u);
}

TEST(ViewExtract, APixelBoundHoldsOnTheScreenForAScaledModel) {
  // The same picture two ways: the model as it is, and the model scaled x4 by its matrix seen from
  // 4 times as far (near and far planes too). Each vertex lands on the same pixel at 4 times the
  // clip.w, and a pixel spans 1/4 of the scaled model's units there: the allowed errors, in the
  // model's own units, are the plain ones.
  eval::GenerateOptions o;
  o.target_triangles = 2000;
  auto b = build(eval::generate_mesh(o));
  ASSERT_NE(b, nullptr);
  view::ViewRequest plain;
  plain.camera = camera_along(b->input.positions, glm::vec3(0.3f, 0.2f, 1.0f), 1.0f);
  plain.grid = {64, 64};
  plain.allowed.error = 0.5f;
  plain.allowed.units = view::ErrorUnits::kScreenPixels;
  view::ViewRequest scaled = plain;
  constexpr float kScale = 4.0f;
  const glm::mat4 grow = glm::scale(glm::mat4(1), glm::vec3(kScale));
  scaled.camera.model = grow;
  scaled.camera.view = grow * plain.camera.view * glm::inverse(grow);  // the eye and target x4
  // The plain camera's near and far planes, both x4.
  const float p22 = plain.camera.projection[2][2], p32 = plain.camera.projection[3][2];
  const float near = p32 / (p22 - 1.0f), far = p32 / (p22 + 1.0f);
  scaled.camera.projection = glm::perspective(glm::radians(45.0f), 1.0f, kScale * near, kScale * far);
  view::ViewExtractor x(b->mt, *b->levels), y(b->mt, *b->levels);
  const std::span<const float> expected = x.allowed_error_field(plain);
  const std::span<const float> got = y.allowed_error_field(scaled);
  ASSERT_EQ(got.size(), expected.size());
  std::size_t compared = 0;
  for (std::size_t v = 0; v < got.size(); ++v) {
    if (!std::isfinite(expected[v]) || !(expected[v] > 0.0f)) continue;
    ASSERT_NEAR(got[v] / expected[v], 1.0f, 1e-3f) << "vertex " << v;
    ++compared;
  }
  EXPECT_GT(compared, b->mt.vertex_count() / 2);
}

// Sorted triangles (each rotated to start at its smallest id) of a cut: its set, in any order.
std::vector<std::array<std::uint32_t, 3>> triangle_set(const cut::CutMesh& cut) {
  std::vector<std::array<std::uint32_t, 3>> out;
  for (std::size_t t = 0; t < cut.triangle_count(); ++t) {
    std::array<std::uint32_t, 3> tri{cut.triangles[3 * t], cut.triangles[3 * t + 1],
                                     cut.triangles[3 * t + 2]};
    std::rotate(tri.begin(), std::min_element(tri.begin(), tri.end()), tri.end());
    out.push_back(tri);
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Whether the segment from `from` to `to` crosses a triangle of `mesh` before the last `end_gap`
// of its length (Möller–Trumbore in double): the reference visibility of a point.
bool segment_blocked(const model::Mesh& mesh, glm::dvec3 from, glm::dvec3 to, double end_gap) {
  const glm::dvec3 dir = to - from;
  auto corner = [&](std::uint32_t v) {
    const float* p = mesh.positions.data() + 3 * std::size_t{v};
    return glm::dvec3(p[0], p[1], p[2]);
  };
  for (std::size_t t = 0; t < mesh.triangles.size(); t += 3) {
    const glm::dvec3 a = corner(mesh.triangles[t]), b = corner(mesh.triangles[t + 1]),
                     c = corner(mesh.triangles[t + 2]);
    const glm::dvec3 e1 = b - a, e2 = c - a, p = glm::cross(dir, e2);
    const double det = glm::dot(e1, p);
    if (std::abs(det) < 1e-15) continue;
    const glm::dvec3 s = from - a;
    const double u = glm::dot(s, p) / det;
    if (u < 0 || u > 1) continue;
    const glm::dvec3 q = glm::cross(s, e1);
    const double v = glm::dot(dir, q) / det;
    if (v < 0 || u + v > 1) continue;
    const double hit = glm::dot(e2, q) / det;
    if (hit > 0 && hit < 1 - end_gap) return true;
  }
  return false;
}

// Hidden-surface coarsening against ray casting on the full-resolution surface: on a spiral shell,
// which hides parts of itself from the side as well as its far half, a vertex the field coarsens lies
// behind the surface, and most vertices that lie behind it are coarsened. The depths come from a
// coarse occupancy cut, so the bounds leave room for its error (and the reference counts a ray that
// grazes the vertex's own neighbourhood as blocked).
TEST(ViewExtract, HiddenSurfaceCoarseningFindsWhatRayCastingFindsHidden) {
  eval::GenerateOptions o;
  o.shape = eval::Shape::kShell;
  o.target_triangles = 6'000;
  const auto b = build(eval::generate_mesh(o));
  ASSERT_NE(b, nullptr);
  for (const glm::vec3 axis : {glm::vec3(0, 0, 1), glm::normalize(glm::vec3(1, 0.5f, 0.3f))}) {
    view::ViewRequest r;
    r.camera = camera_along(b->input.positions, axis, 1.0f);
    r.grid = {256, 256};
    r.allowed.error = 1.0f;
    r.allowed.outside_view_factor = 1.0f;
    r.allowed.hidden_factor = 4.0f;
    r.dynamic = false;
    r.allowed_error_on_demand = false;
    view::ViewExtractor x(b->mt, *b->levels);
    cut::Refiner refiner(b->mt);
    cut::CutMesh cut;
    run(x, r, refiner, cut);
    const std::span<const float> field = x.vertex_allowed_error();
    const glm::dvec3 eye = glm::inverse(glm::dmat4(r.camera.view))[3];
    std::size_t in_view = 0, blocked = 0, coarsened = 0, coarsened_blocked = 0;
    for (std::uint32_t v = 0; v < b->mt.vertex_count(); ++v) {
      const float* p = b->mt.positions.data() + 3 * std::size_t{v};
      if (x.mapping().map_point(p[0], p[1], p[2]) == view::kNoCell) continue;
      ++in_view;
      ASSERT_TRUE(field[v] == 1.0f || field[v] == 4.0f) << field[v];
      const bool is_blocked = segment_blocked(b->input, eye, glm::dvec3(p[0], p[1], p[2]), 1e-3);
      blocked += is_blocked;
      coarsened += field[v] == 4.0f;
      coarsened_blocked += field[v] == 4.0f && is_blocked;
    }
    char counts[160];
    std::snprintf(counts, sizeof counts,
                  "axis %.2f,%.2f,%.2f: %zu in view, %zu blocked, %zu coarsened, %zu of them blocked", axis.x,
                  axis.y, axis.z, in_view, blocked, coarsened, coarsened_blocked);
    std::printf("%s\n", counts);
    SCOPED_TRACE(counts);
    EXPECT_GT(blocked, in_view / 3);  // a scene with much to hide
    EXPECT_GE(coarsened_blocked, coarsened - coarsened / 100);
    EXPECT_GE(coarsened, blocked * 6 / 10);
  }
}

TEST(ViewExtract, OccupancyCutGrowsAsTheModelFillsMoreOfTheGrid) {
  eval::GenerateOptions o;
  o.target_triangles = 200'000;
  auto b = build(eval::generate_mesh(o));
  ASSERT_NE(b, nullptr);
  ASSERT_GE(b->levels->levels().size(), 3u);
  // Each level's compact mesh is a cut of the model: its positions are the model's at its ids, and
  // mapped back to model ids its triangles are the budgeted cut of that size.
  for (const view::OccupancyLevel& level : b->levels->levels()) {
    ASSERT_EQ(level.positions.size(), 3 * level.model_ids.size());
    for (std::size_t i = 0; i < level.model_ids.size(); ++i) {
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(level.positions[3 * i + c], b->mt.positions[3 * level.model_ids[i] + c]);
    }
    cut::CutMesh cut;
    cut::refine_budget(b->mt, cut::AllowedError::everywhere(0.0f), level.triangle_count(), cut);
    cut::CutMesh compact;
    for (const std::uint32_t local : level.cut_triangles())
      compact.triangles.push_back(level.model_ids.at(local));
    EXPECT_EQ(triangle_set(compact), triangle_set(cut));
    EXPECT_TRUE(level.closed);
  }
  view::ViewExtractor x(b->mt, *b->levels);
  std::size_t previous = 0;
  for (std::uint32_t side : {16u, 64u, 256u, 1024u}) {
    view::ViewRequest r;
    r.camera = front_camera(b->input, 1.0f);
    r.grid = {side, side};
    x.map(r);
    const std::size_t triangles = x.occupancy();
    // At least one triangle per four covered cells, from the precomputed levels.
    EXPECT_GE(triangles, previous) << side;
    EXPECT_GE(
        static_cast<double>(triangles),
        std::min(0.25 * x.covered_cells(), static_cast<double>(b->levels->levels().back().triangle_count())));
    previous = triangles;
  }
  EXPECT_GT(previous, b->levels->levels().front().triangle_count());
}

TEST(ViewExtract, DragonOccupancyLevelsAreCappedAndClosed) {
  // The scan has holes: each occupancy level gets caps that close it, so a request rasterises one
  // side only. The caps add cells only where a hole shows in the projection: from six views along
  // the axes the capped levels' occupancy contains the cut's own and adds at most a few cells (none,
  // when this test was written).
  const Built* b = dragon();
  if (!b) GTEST_SKIP() << "dragon mesh not found";
  std::vector<view::ProjectedCorner> scratch;
  for (const view::OccupancyLevel& level : b->levels->levels()) {
    if (level.triangle_count() > 70'000) break;
    ASSERT_TRUE(level.closed) << level.triangle_count();
    EXPECT_GT(level.cap_triangles, 0u);
    for (const glm::vec3 axis : {glm::vec3(0, 0, 1), glm::vec3(0, 0, -1), glm::vec3(1, 0, 0),
                                 glm::vec3(-1, 0, 0), glm::vec3(0, 1, 0.01f), glm::vec3(0, -1, 0.01f)}) {
      const view::ViewMapping mapping(camera_along(b->mt.positions, axis, 1.0f), view::GridSize{256, 256});
      std::vector<std::uint8_t> own(mapping.grid().cell_count()), capped(own.size());
      view::rasterize_occupancy_compact(mapping, level.positions, level.cut_triangles(), own, {}, scratch);
      view::rasterize_occupancy_compact(mapping, level.positions, level.triangles, capped, {}, scratch, true);
      std::size_t object = 0, added = 0;
      for (std::size_t c = 0; c < own.size(); ++c) {
        ASSERT_TRUE(own[c] == 0 || capped[c] != 0) << "cell " << c;
        object += own[c];
        added += own[c] == 0 && capped[c] != 0;
      }
      EXPECT_GT(object, 1000u);
      EXPECT_LE(added, object / 200) << level.triangle_count() << " triangles, view " << axis.x << ","
                                     << axis.y << "," << axis.z;
    }
  }
}

// The session tests' scene: a generated 30k-triangle mesh (one MT build per process) seen from the
// front, and turned by 0.3 rad for a second view.
struct SessionScene {
  const Built* built;
  view::Camera front, turned;
};
SessionScene session_scene() {
  static const std::unique_ptr<Built> built = [] {
    eval::GenerateOptions o;
    o.target_triangles = 30'000;
    return build(eval::generate_mesh(o));
  }();
  if (!built) return {nullptr, {}, {}};
  const view::Camera front = front_camera(built->input, 1.0f);
  view::Camera turned = front;
  turned.view = glm::rotate(front.view, 0.3f, glm::vec3(0, 1, 0));
  return {built.get(), front, turned};
}

// A session's gaze path (same view, foci moved: occupancy and silhouette transform reused, allowed
// error recomputed only where the focus multiplier changed, the refinement told which vertices
// changed) must give exactly what a fresh extraction from the root gives, request after request,
// for every falloff law, in model units and in pixels, with the camera changing now and then; and
// for the viewing clients' default, a foveal law from the bound itself (f = 1, growing past 1)
// without a silhouette, with and without hidden-surface coarsening (whose depths the gazes reuse).
TEST(ViewExtract, SessionGazePathEqualsAFreshExtractionEveryTime) {
  const auto [b, camera, other] = session_scene();
  ASSERT_NE(b, nullptr);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> unit(0.1f, 0.9f);
  // 64² has fewer cells than the mesh has vertices (the field tabulates per cell), 160² more.
  struct Focus {
    view::FalloffLaw law;
    float factor;
    bool silhouette;
    float hidden = 1.0f;
  };
  for (const auto [law, factor, silhouette, hidden] :
       {Focus{view::FalloffLaw::kStep, 0.1f, true}, Focus{view::FalloffLaw::kLinear, 0.1f, true},
        Focus{view::FalloffLaw::kSmoothstep, 0.1f, true}, Focus{view::FalloffLaw::kFoveal, 0.1f, true},
        Focus{view::FalloffLaw::kFoveal, 1.0f, false},
        Focus{view::FalloffLaw::kFoveal, 1.0f, false, 16.0f}}) {
    for (const view::ErrorUnits units : {view::ErrorUnits::kModel, view::ErrorUnits::kScreenPixels}) {
      for (const std::uint32_t side : {64u, 160u}) {
        for (const view::DistanceMetric metric :
             {view::DistanceMetric::kChamfer5711, view::DistanceMetric::kChamfer34,
              view::DistanceMetric::kEuclidean}) {
          // The other transforms for one law and grid: a pixel step costs each its own number of units.
          if (metric != view::DistanceMetric::kChamfer5711 &&
              (law != view::FalloffLaw::kStep || side != 160u))
            continue;
          view::ViewRequest r;
          r.camera = camera;
          r.grid = {side, side};
          r.allowed.metric = metric;
          r.allowed.units = units;
          r.allowed.error = units == view::ErrorUnits::kModel ? 0.02f : 1.0f;
          r.allowed.criteria[view::Criterion::kSilhouette].reset();
          if (silhouette)
            r.allowed.criteria[view::Criterion::kSilhouette] =
                view::RegionLaw{view::FalloffLaw::kStep, 2.0f, 0.25f};
          r.allowed.criteria[view::Criterion::kFocus] = view::RegionLaw{law, 8.0f, factor, 16.0f};
          r.allowed.hidden_factor = hidden;
          view::ViewExtractor session_extractor(b->mt, *b->levels), fresh_extractor(b->mt, *b->levels);
          view::ViewCache session;
          cut::Refiner kept(b->mt);
          cut::CutMesh cut, expected;
          std::size_t reused = 0, recomputed = 0;
          for (int step = 0; step < 12; ++step) {
            r.points[view::Criterion::kFocus] = {{unit(rng), unit(rng)}};
            if (step == 5) r.camera = other;  // a new view: everything again, then gazes on it
            run(session_extractor, r, kept, cut, &session);
            EXPECT_EQ(session.reused(), step != 0 && step != 5) << "step " << step;
            if (session.reused()) ++reused, recomputed += session.changed_vertices();

            run_fresh(fresh_extractor, b->mt, r, expected);
            const auto a = session_extractor.vertex_allowed_error(),
                       e = fresh_extractor.vertex_allowed_error();
            ASSERT_EQ(a.size(), e.size());
            // The session knows the allowed error of every vertex its cut reads (new views and gazes
            // ask for those only), and knows it right.
            kept.for_each_cut_vertex([&](std::uint32_t v) {
              ASSERT_EQ(std::memcmp(&a[v], &e[v], sizeof(float)), 0)
                  << "allowed error of vertex " << v << " differs at step " << step << ", law " << int(law)
                  << ", metric " << int(metric);
            });
            ASSERT_EQ(triangle_set(cut), triangle_set(expected)) << "step " << step << ", law " << int(law);
            // No more than four times as many as the cut reads (a few more vertices than nodes).
            EXPECT_LE(session.known_vertices(), 4 * (kept.cut_nodes().size() + b->mt.root_triangle_count()));
          }
          EXPECT_EQ(reused, 10u);
          // The step law changes only cells near the old and new foci: far fewer vertices than all.
          if (law == view::FalloffLaw::kStep) {
            EXPECT_LT(recomputed, reused * b->mt.vertex_count() / 4);
          }
        }
      }
    }
  }
}

TEST(ViewExtract, SessionForgetsWhatItsCutNoLongerReadsAndStaysExact) {
  // A session's gazes sweep a small fine region across the screen: each cut reads vertices the
  // last ones did not, so what the session knows would grow with every gaze. It stays within four
  // times what the cut reads (the rest is forgotten, and asked for again when a later cut reads it),
  // and every cut equals a fresh extraction's.
  const auto [b, camera, other] = session_scene();
  ASSERT_NE(b, nullptr);
  view::ViewRequest r;
  r.camera = camera;
  r.grid = {128, 128};
  r.allowed.units = view::ErrorUnits::kScreenPixels;
  r.allowed.error = 8.0f;
  r.allowed.criteria[view::Criterion::kFocus] = view::RegionLaw{view::FalloffLaw::kStep, 6.0f, 0.02f};
  view::ViewExtractor session_extractor(b->mt, *b->levels), fresh_extractor(b->mt, *b->levels);
  view::ViewCache session;
  cut::Refiner kept(b->mt);
  cut::CutMesh cut, expected;
  std::size_t most_known = 0;
  for (int step = 0; step < 60; ++step) {
    // Left to right and back, row by row.
    const float t = static_cast<float>(step % 20) / 19.0f;
    r.points[view::Criterion::kFocus] = {
        {0.15f + 0.7f * (step / 20 % 2 ? 1.0f - t : t), 0.3f + 0.2f * static_cast<float>(step / 20)}};
    run(session_extractor, r, kept, cut, &session);
    EXPECT_EQ(session.reused(), step != 0);
    run_fresh(fresh_extractor, b->mt, r, expected);
    ASSERT_EQ(triangle_set(cut), triangle_set(expected)) << "step " << step;
    EXPECT_LE(session.known_vertices(), 4 * (kept.cut_nodes().size() + b->mt.root_triangle_count()));
    most_known = std::max(most_known, session.known_vertices());
  }
  EXPECT_GT(session.forgets(), 0u);
  EXPECT_LT(most_known, b->mt.vertex_count() / 2);
  EXPECT_GT(session_extractor.vertices_computed(), 0u);
}

TEST(ViewExtract, SessionBudgetedGazesEqualBudgetedRefinementFromTheRoot) {
  // A budgeted session: a new view refines worst-first from the root and keeps a threshold's cut,
  // each gaze on it moves that cut; every result equals the budgeted refinement of a fresh static
  // extraction (grid, transforms, field and refinement from nothing).
  const auto [b, camera, other] = session_scene();
  ASSERT_NE(b, nullptr);
  std::mt19937 rng(13);
  std::uniform_real_distribution<float> unit(0.1f, 0.9f);
  view::ViewRequest r;
  r.camera = camera;
  r.grid = {160, 160};
  r.allowed.units = view::ErrorUnits::kScreenPixels;
  r.allowed.error = 0.25f;
  r.allowed.criteria[view::Criterion::kSilhouette] = view::RegionLaw{view::FalloffLaw::kStep, 2.0f, 0.25f};
  r.allowed.criteria[view::Criterion::kFocus] =
      view::RegionLaw{view::FalloffLaw::kSmoothstep, 8.0f, 0.1f, 16.0f};
  view::ViewExtractor session_extractor(b->mt, *b->levels), fresh_extractor(b->mt, *b->levels);
  view::ViewCache session;
  cut::Refiner kept(b->mt);
  cut::CutMesh cut, expected, unbounded;
  std::size_t binding = 0;
  for (int step = 0; step < 16; ++step) {
    r.points[view::Criterion::kFocus] = {{unit(rng), unit(rng)}};
    if (step == 8) {
      // A new view, keeping full resolution along the silhouette: those triangles rank first.
      r.camera = other;
      r.allowed.criteria[view::Criterion::kSilhouette] = view::RegionLaw{view::FalloffLaw::kStep, 2.0f, 0.0f};
    }
    r.budget = step < 12 ? 2'500 : 3'000;  // a new budget starts from the root as well
    run(session_extractor, r, kept, cut, &session);
    EXPECT_EQ(session.reused(), step != 0 && step != 8) << "step " << step;

    // The fresh extraction computes every vertex's allowed error; the session's new views ask
    // for those they read.
    run_fresh(fresh_extractor, b->mt, r, expected);
    ASSERT_EQ(triangle_set(cut), triangle_set(expected)) << "step " << step;
    EXPECT_LE(cut.triangle_count(), *r.budget);
    view::ViewRequest error_bound = r;
    error_bound.budget.reset();
    run_fresh(fresh_extractor, b->mt, error_bound, unbounded);
    binding += unbounded.triangle_count() > *r.budget;
  }
  EXPECT_EQ(binding, 16u);              // every gaze's error-bound cut was larger than the budget
  EXPECT_EQ(kept.budget_starts(), 3u);  // the two new views and the new budget
}

}  // namespace
}  // namespace mtlod::core

// End to end through the core (issue 4, "Must show"): the 871k dragon's MT, a camera, the grid stages
// (occupancy from a coarse cut, 5-7-11 transforms, labels, allowed error) and static refinement.
// Silhouette mode with f = 0 and d = 2 px keeps every triangle touching the contour band at full
// resolution while the rest is coarser; in focus mode triangle density falls away from the focus.
#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "core/allowed_error.hpp"
#include "core/distance_transform.hpp"
#include "core/labels.hpp"
#include "core/occupancy.hpp"
#include "core/refine.hpp"
#include "core/view_grid.hpp"
#include "tests/core/cut_validator.hpp"
#include "tests/core/mt_fixtures.hpp"

namespace mtlod::core {
namespace {

struct DragonView {
  const mtlod::test::MtCase* c = nullptr;
  ViewMapping mapping;
  float radius = 0.0f;
  std::vector<std::uint8_t> occupancy;
  std::vector<std::uint32_t> cells;
  std::vector<float> clip_w;

  // The dragon framed from the front at 256²; the occupancy comes from a coarse uniform cut (error
  // 0.3 × the bounding radius: about 9k triangles), as a request would use a coarse or previous cut.
  explicit DragonView(const mtlod::test::MtCase* dragon) : c(dragon) {
    const Mt& mt = c->mt;
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (std::size_t v = 0; v < mt.vertex_count(); ++v) {
      const glm::vec3 p(mt.positions[3 * v], mt.positions[3 * v + 1], mt.positions[3 * v + 2]);
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
    const glm::vec3 centre = 0.5f * (lo + hi);
    radius = 0.5f * glm::length(hi - lo);
    Camera camera;
    camera.view = glm::lookAt(centre + glm::vec3(0.0f, 0.0f, 2.6f * radius), centre, glm::vec3(0, 1, 0));
    camera.projection = glm::perspective(glm::radians(45.0f), 1.0f, 0.1f * radius, 10.0f * radius);
    mapping = ViewMapping(camera, GridSize{256, 256});
    CutMesh coarse;
    refine_static(mt, AllowedError::everywhere(0.3f * radius), coarse);
    occupancy.resize(mapping.grid().cell_count());
    rasterize_occupancy(mapping, mt.positions, coarse.triangles, occupancy);
    cells.resize(mt.vertex_count());
    clip_w.resize(mt.vertex_count());
    map_vertices(mapping, mt.positions, cells, clip_w);
  }
};

TEST(ViewRefine, DragonSilhouetteBandIsAtFullResolutionAndTheRestIsCoarser) {
  const mtlod::test::MtCase* c = mtlod::test::scan_case("dragon-vrip-871k.ply");
  if (!c) GTEST_SKIP() << "dragon-vrip-871k.ply absent";
  const DragonView view(c);
  const GridSize grid = view.mapping.grid();
  std::vector<std::uint16_t> dt(grid.cell_count());
  chamfer_5_7_11(view.occupancy, grid, dt);
  AllowedErrorOptions options;
  options.error = 0.1f * view.radius;  // alone, a cut of about 50k triangles
  options.use_silhouette = true;
  options.silhouette = {FalloffLaw::kStep, 2.0f, 0.0f, 0.0f, 2.3f};  // f = 0, d = 2 px
  std::vector<float> allowed(c->mt.vertex_count());
  compute_vertex_allowed_error(view.mapping, options, {dt, {}, {}, c->mt.positions, {}}, allowed);
  CutMesh cut;
  refine_static(c->mt, AllowedError::from_vertices(allowed), cut);
  EXPECT_TRUE(mtlod::test::validate_cut(c->reference, cut.triangles));

  // Full resolution = an input triangle. Every cut triangle with a vertex labelled ≤ 2 px (raw 10)
  // must be one; the others may not be.
  const auto input = mtlod::test::triangle_set(c->mesh.triangles);
  std::vector<std::uint32_t> labels(c->mt.vertex_count());
  label_vertices(view.cells, dt, labels);
  std::size_t band = 0, coarser = 0;
  for (std::size_t t = 0; t < cut.triangle_count(); ++t) {
    const std::uint32_t* tri = cut.triangles.data() + 3 * t;
    const std::uint32_t label = std::min({labels[tri[0]], labels[tri[1]], labels[tri[2]]});
    const bool original =
        std::binary_search(input.begin(), input.end(), mtlod::test::canonical(tri[0], tri[1], tri[2]));
    if (label <= 10) {
      ASSERT_TRUE(original) << "triangle " << t << " with label " << label << " is not at full resolution";
      ++band;
    } else {
      coarser += !original;
    }
  }
  EXPECT_GT(band, 1000u);
  EXPECT_GT(coarser, 1000u);  // away from the contour the cut is simplified
  EXPECT_LT(cut.triangle_count(), c->mesh.triangle_count() / 2);
}

TEST(ViewRefine, DragonFocusTriangleDensityFallsWithDistanceFromTheFocus) {
  const mtlod::test::MtCase* c = mtlod::test::scan_case("dragon-vrip-871k.ply");
  if (!c) GTEST_SKIP() << "dragon-vrip-871k.ply absent";
  const DragonView view(c);
  const GridSize grid = view.mapping.grid();
  const std::vector<std::uint32_t> foci = {focus_cell(grid, 0.5f, 0.5f)};
  std::vector<std::uint16_t> focus(grid.cell_count());
  DistanceTransformer().chamfer_from_cells(DistanceMetric::kChamfer5711, foci, grid, focus);
  AllowedErrorOptions options;
  options.error = 0.15f * view.radius;  // alone, a cut of about 26k triangles
  options.use_focus = true;
  options.focus = {FalloffLaw::kLinear, 10.0f, 0.05f, 60.0f, 2.3f};
  std::vector<float> allowed(c->mt.vertex_count());
  compute_vertex_allowed_error(view.mapping, options, {{}, focus, {}, c->mt.positions, {}}, allowed);
  CutMesh cut;
  refine_static(c->mt, AllowedError::from_vertices(allowed), cut);
  EXPECT_TRUE(mtlod::test::validate_cut(c->reference, cut.triangles));
  // Triangles per object cell in rings of 20 px around the focus, by their first vertex's cell.
  constexpr int kRings = 5;
  double triangles[kRings] = {}, cells_in_ring[kRings] = {};
  for (std::size_t cell = 0; cell < grid.cell_count(); ++cell) {
    const int ring = focus[cell] / 100;
    if (ring < kRings && view.occupancy[cell] != 0) cells_in_ring[ring] += 1;
  }
  for (std::size_t t = 0; t < cut.triangle_count(); ++t) {
    const std::uint32_t cell = view.cells[cut.triangles[3 * t]];
    if (cell == kNoCell) continue;
    const int ring = focus[cell] / 100;
    if (ring < kRings) triangles[ring] += 1;
  }
  for (int ring = 0; ring + 1 < kRings; ++ring) {
    ASSERT_GT(cells_in_ring[ring], 0.0);
    const double inner = triangles[ring] / cells_in_ring[ring];
    const double outer = triangles[ring + 1] / cells_in_ring[ring + 1];
    EXPECT_GT(inner, outer) << "ring " << ring << " (" << 20 * ring << "–" << 20 * (ring + 1) << " px)";
  }
}

}  // namespace
}  // namespace mtlod::core

// Allowed error (core/ARCHITECTURE.md §1.5): each law at hand-computed labels, the stricter
// criterion wins, the pixel bound converts with depth, coarsening factors apply where they should, the
// lazy field equals the full one, and the per-vertex minimum reproduces the papers' triangle law.
#include "core/view/allowed_error.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <vector>

#include "core/view/occupancy.hpp"
#include "tests/core/test_scenes.hpp"

namespace mtlod::core {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

TEST(LawFactor, StepIsFactorInsideAndOneOutside) {
  const view::RegionLaw step{view::FalloffLaw::kStep, 2.0f, 0.25f, 16.0f, 2.3f};
  EXPECT_EQ(view::law_factor(step, 0.0f, 0.0f), 0.25f);
  EXPECT_EQ(view::law_factor(step, 2.0f, 0.0f), 0.25f);  // label ≤ d is inside
  EXPECT_EQ(view::law_factor(step, 2.2f, 0.0f), 1.0f);
  EXPECT_EQ(view::law_factor(step, kInf, 0.0f), 1.0f);  // unlabeled
}

TEST(LawFactor, LinearAndSmoothstepRampFromFactorToOne) {
  // d = 2, ramp 4 px, f = 0.2. At 4 px, halfway: linear 0.2 + 0.8·0.5 = 0.6. At 3 px, t = 0.25:
  // smoothstep 0.25²·(3 − 0.5) = 0.15625, so 0.2 + 0.8·0.15625 = 0.325. All values are exact in float.
  const view::RegionLaw linear{view::FalloffLaw::kLinear, 2.0f, 0.2f, 4.0f, 2.3f};
  const view::RegionLaw smooth{view::FalloffLaw::kSmoothstep, 2.0f, 0.2f, 4.0f, 2.3f};
  EXPECT_EQ(view::law_factor(linear, 1.0f, 0.0f), 0.2f);
  EXPECT_FLOAT_EQ(view::law_factor(linear, 4.0f, 0.0f), 0.6f);  // 0.2f + 0.8f·0.5f rounds within 1 ulp
  EXPECT_EQ(view::law_factor(linear, 6.0f, 0.0f), 1.0f);
  EXPECT_EQ(view::law_factor(linear, 50.0f, 0.0f), 1.0f);
  EXPECT_FLOAT_EQ(view::law_factor(smooth, 3.0f, 0.0f), 0.325f);
  EXPECT_FLOAT_EQ(view::law_factor(smooth, 4.0f, 0.0f), 0.6f);  // smoothstep(0.5) = 0.5
  EXPECT_EQ(view::law_factor(smooth, 6.0f, 0.0f), 1.0f);
}

TEST(LawFactor, FovealGrowsLinearlyWithEccentricity) {
  // A grid pixel subtending tan(2.3°)/10 at the centre: 10 px is 2.3° of eccentricity, where the
  // acuity model doubles the allowed error: f = 0.1 → 0.2. 20 px is atan(2·tan 2.3°) ≈ 4.5966°.
  // Tolerance: float tan/atan round-trips (~1e-6 relative).
  const float tan_per_px = std::tan(2.3f * std::numbers::pi_v<float> / 180.0f) / 10.0f;
  const view::RegionLaw foveal{view::FalloffLaw::kFoveal, 0.0f, 0.1f, 0.0f, 2.3f};
  EXPECT_NEAR(view::eccentricity_deg(10.0f, tan_per_px), 2.3f, 1e-5f);
  EXPECT_EQ(view::law_factor(foveal, 0.0f, tan_per_px), 0.1f);
  EXPECT_NEAR(view::law_factor(foveal, 10.0f, tan_per_px), 0.2f, 1e-6f);
  const double e20 = std::atan(2.0 * std::tan(2.3 * std::numbers::pi / 180.0)) * 180.0 / std::numbers::pi;
  EXPECT_NEAR(view::law_factor(foveal, 20.0f, tan_per_px), 0.1 * (1.0 + e20 / 2.3), 1e-6);
  EXPECT_EQ(view::law_factor(foveal, 1000.0f, tan_per_px), 1.0f);  // capped at the base error
}

TEST(LawFactor, FovealFromTheBaseErrorGrowsWithoutACap) {
  // f = 1: the base error is the bound at the focus, and it grows as the minimum angle of resolution
  // does, 1 + e/e2, however far out (the default criteria of mtlod-gaze, mtlod-load and the viewer).
  const float tan_per_px = std::tan(2.3f * std::numbers::pi_v<float> / 180.0f) / 10.0f;
  const view::RegionLaw foveal{view::FalloffLaw::kFoveal, 0.0f, 1.0f, 0.0f, 2.3f};
  EXPECT_EQ(view::law_factor(foveal, 0.0f, tan_per_px), 1.0f);
  EXPECT_NEAR(view::law_factor(foveal, 10.0f, tan_per_px), 2.0f, 1e-5f);
  const double e1000 = std::atan(100.0 * std::tan(2.3 * std::numbers::pi / 180.0)) * 180.0 / std::numbers::pi;
  EXPECT_NEAR(view::law_factor(foveal, 1000.0f, tan_per_px), 1.0 + e1000 / 2.3, 1e-4);
  EXPECT_GT(view::law_factor(foveal, 1000.0f, tan_per_px), 30.0f);
}

TEST(LawFactor, PastItsReachEveryLawIsExactlyOne) {
  // Every distance beyond law_reach_px, in steps of a fifth of a pixel, gives exactly 1; and the reach
  // is tight: a pixel short of it the multiplier is not 1 yet.
  const float tan_per_px = std::tan(2.3f * std::numbers::pi_v<float> / 180.0f) / 10.0f;
  using view::FalloffLaw;
  for (const view::RegionLaw law : {view::RegionLaw{FalloffLaw::kStep, 8.0f, 0.1f, 0.0f, 2.3f},
                                    view::RegionLaw{FalloffLaw::kStep, 3.0f, 4.0f},
                                    view::RegionLaw{FalloffLaw::kLinear, 8.0f, 0.1f, 16.0f},
                                    view::RegionLaw{FalloffLaw::kLinear, 2.0f, 3.0f, 7.5f},
                                    view::RegionLaw{FalloffLaw::kSmoothstep, 20.0f, 0.25f, 13.0f},
                                    view::RegionLaw{FalloffLaw::kFoveal, 0.0f, 0.1f, 0.0f, 2.3f},
                                    view::RegionLaw{FalloffLaw::kFoveal, 0.0f, 0.7f, 0.0f, 1.0f},
                                    view::RegionLaw{FalloffLaw::kFoveal, 0.0f, 0.999f, 0.0f, 2.3f}}) {
    const std::optional<float> reach = view::law_reach_px(law, tan_per_px);
    ASSERT_TRUE(reach) << int(law.law) << " " << law.factor;
    for (float d = *reach + 0.01f; d < *reach + 400.0f; d += 0.2f)
      ASSERT_EQ(view::law_factor(law, d, tan_per_px), 1.0f)
          << int(law.law) << " " << law.factor << " at " << d;
    EXPECT_NE(view::law_factor(law, std::max(*reach - 1.0f, 0.0f), tan_per_px), 1.0f)
        << int(law.law) << " " << law.factor;
  }
  // A foveal law from the base error up never comes back to 1.
  EXPECT_FALSE(view::law_reach_px(view::RegionLaw{FalloffLaw::kFoveal, 0.0f, 1.0f, 0.0f, 2.3f}, tan_per_px));
}

TEST(LawFactor, NeglectRegionRaisesTheError) {
  const view::RegionLaw neglect{view::FalloffLaw::kStep, 3.0f, 4.0f, 0.0f, 2.3f};
  EXPECT_EQ(view::law_factor(neglect, 3.0f, 0.0f), 4.0f);
  EXPECT_EQ(view::law_factor(neglect, 3.2f, 0.0f), 1.0f);
}

// A 16×16 grid over a 90° perspective view from the origin down −z; transforms are set by hand.
struct HandScene {
  view::ViewMapping mapping;
  std::vector<std::uint16_t> silhouette, focus, neglect;
  HandScene() {
    view::Camera camera;
    camera.view = glm::lookAt(glm::vec3(0, 0, 0), glm::vec3(0, 0, -1), glm::vec3(0, 1, 0));
    camera.projection = glm::perspective(glm::radians(90.0f), 1.0f, 0.1f, 100.0f);
    mapping = view::ViewMapping(camera, view::GridSize{16, 16});
    silhouette.assign(256, 100);
    focus.assign(256, 100);
    neglect.assign(256, 100);
  }
};

TEST(AllowedError, StricterOfSilhouetteAndFocusWins) {
  HandScene scene;
  // Vertex 0 at depth 4 in the view centre: cell (8, 8).
  const std::vector<float> positions = {0.0f, 0.0f, -4.0f};
  const std::uint32_t cell = scene.mapping.map_point(0.0f, 0.0f, -4.0f);
  ASSERT_EQ(cell, scene.mapping.grid().cell(8, 8));
  view::AllowedErrorOptions options;
  options.error = 2.0f;
  options.criteria[view::Criterion::kSilhouette] =
      view::RegionLaw{view::FalloffLaw::kStep, 2.0f, 0.5f, 0.0f, 2.3f};
  options.criteria[view::Criterion::kFocus] =
      view::RegionLaw{view::FalloffLaw::kStep, 3.0f, 0.25f, 0.0f, 2.3f};
  const view::AllowedErrorInputs inputs{{scene.silhouette, scene.focus, {}}, positions, {}, {}};
  std::vector<float> out(1);
  // Label 10 (2 px) is inside the silhouette band only: 2·0.5.
  scene.silhouette[cell] = 10;
  view::compute_vertex_allowed_error(scene.mapping, options, inputs, out);
  EXPECT_EQ(out[0], 1.0f);
  // Also within 3 px of the focus (label 15): the stricter 0.25 wins.
  scene.focus[cell] = 15;
  view::compute_vertex_allowed_error(scene.mapping, options, inputs, out);
  EXPECT_EQ(out[0], 0.5f);
  // Outside both: the base error.
  scene.silhouette[cell] = 11;
  scene.focus[cell] = 16;
  view::compute_vertex_allowed_error(scene.mapping, options, inputs, out);
  EXPECT_EQ(out[0], 2.0f);
  // A neglect region multiplies: inside it (label 0) the base error is raised 4×.
  options.criteria[view::Criterion::kNeglect] =
      view::RegionLaw{view::FalloffLaw::kStep, 2.0f, 4.0f, 0.0f, 2.3f};
  scene.neglect[cell] = 0;
  const view::AllowedErrorInputs with_neglect{
      {scene.silhouette, scene.focus, scene.neglect}, positions, {}, {}};
  view::compute_vertex_allowed_error(scene.mapping, options, with_neglect, out);
  EXPECT_EQ(out[0], 8.0f);
}

TEST(AllowedError, PixelBoundConvertsWithDepth) {
  // 90° field of view, 1000 px tall screen, 2 px bound, vertex at depth 5:
  // 2 · 2·5·tan(45°)/1000 = 0.02 model units. A vertex behind the eye gets +inf.
  // Tolerance: P[1][1] = 1/tan(π/4) is 1 up to float rounding, and 0.02 is not exact in float.
  HandScene scene;
  const std::vector<float> positions = {0.5f, 0.5f, -5.0f, 0.0f, 0.0f, 3.0f, 40.0f, 0.0f, -5.0f};
  view::AllowedErrorOptions options;
  options.error = 2.0f;
  options.units = view::ErrorUnits::kScreenPixels;
  options.viewport_height_px = 1000.0f;
  std::vector<float> out(3);
  view::compute_vertex_allowed_error(scene.mapping, options, {{}, positions, {}, {}}, out);
  EXPECT_NEAR(out[0], 0.02f, 1e-8f);
  EXPECT_EQ(out[1], kInf);
  EXPECT_NEAR(out[2], 0.02f, 1e-8f);  // off the grid but in front: same depth, same bound
  // Without viewport_height_px the grid's 16 rows are the pixels: 2 · 10/16 = 1.25.
  options.viewport_height_px = 0.0f;
  view::compute_vertex_allowed_error(scene.mapping, options, {{}, positions, {}, {}}, out);
  EXPECT_NEAR(out[0], 1.25f, 1e-6f);
}

TEST(AllowedError, FrustumAndBackFaceCoarsening) {
  HandScene scene;
  // Vertex 0 in view facing the camera, vertex 1 off the grid, vertex 2 in view facing away, vertex 3
  // on the rim (normal ⟂ view direction).
  const std::vector<float> positions = {0, 0, -4, 40, 0, -4, 0.1f, 0, -4, 0, 0.2f, -4};
  const std::vector<float> normals = {0, 0, 1, 0, 0, 1, 0, 0, -1, 0, 1, 0};
  view::AllowedErrorOptions options;
  options.error = 1.0f;
  options.outside_view_factor = 8.0f;
  options.back_face_factor = 3.0f;
  std::vector<float> out(4);
  view::compute_vertex_allowed_error(scene.mapping, options, {{}, positions, normals, {}}, out);
  EXPECT_EQ(out, (std::vector<float>{1.0f, 8.0f, 3.0f, 1.0f}));
}

TEST(AllowedError, HiddenSurfaceCoarseningComparesDepthWithTheVisibleSurface) {
  HandScene scene;
  // The visible surface at depth 4 everywhere but in cell (3, 8), which sees the background. Vertices:
  // 0 on the surface; 1 behind it within the 1 % margin; 2 behind it beyond the margin; 3 just as far
  // but in the background's cell; 4 just as far, off the grid; 5 in front of the surface.
  std::vector<float> visible(256, 4.0f);
  const std::uint32_t background = scene.mapping.grid().cell(3, 8);
  visible[background] = kInf;
  // x = −(1 − 2·3.5/16)·depth puts a vertex at the centre of column 3, y = 0 in row 8.
  const float column3 = -(1.0f - 7.0f / 16.0f);
  const std::vector<float> positions = {0,           0, -4, 0,  0, -4.03f, 0, 0, -4.2f,
                                        column3 * 6, 0, -6, 40, 0, -6,     0, 0, -3};
  ASSERT_EQ(scene.mapping.map_point(column3 * 6, 0, -6), background);
  view::AllowedErrorOptions options;
  options.error = 1.0f;
  options.outside_view_factor = 8.0f;
  options.hidden_factor = 5.0f;
  std::vector<float> out(6);
  view::compute_vertex_allowed_error(scene.mapping, options, {{}, positions, {}, visible}, out);
  EXPECT_EQ(out, (std::vector<float>{1.0f, 1.0f, 5.0f, 1.0f, 8.0f, 1.0f}));
  // Off without the depths, and with a factor of 1.
  view::compute_vertex_allowed_error(scene.mapping, options, {{}, positions, {}, {}}, out);
  EXPECT_EQ(out, (std::vector<float>{1.0f, 1.0f, 1.0f, 1.0f, 8.0f, 1.0f}));
  options.hidden_factor = 1.0f;
  view::compute_vertex_allowed_error(scene.mapping, options, {{}, positions, {}, visible}, out);
  EXPECT_EQ(out, (std::vector<float>{1.0f, 1.0f, 1.0f, 1.0f, 8.0f, 1.0f}));
}

// A sphere seen in perspective on a 96² grid, with its silhouette transform and room for a focus
// transform.
struct SphereView {
  test::Scene sphere = test::uv_sphere(1.0f, 24, 48);
  view::ViewMapping mapping;
  view::GridSize grid;
  view::DistanceTransformer transformer;
  std::vector<std::uint16_t> silhouette, focus;
  SphereView() {
    view::Camera camera;
    camera.view = glm::lookAt(glm::vec3(0.4f, 0.3f, 3.0f), glm::vec3(0, 0, 0), glm::vec3(0, 1, 0));
    camera.projection = glm::perspective(glm::radians(50.0f), 1.0f, 0.1f, 10.0f);
    mapping = view::ViewMapping(camera, view::GridSize{96, 96});
    std::vector<std::uint8_t> occupancy(mapping.grid().cell_count());
    view::rasterize_occupancy(mapping, sphere.positions, sphere.triangles, occupancy);
    silhouette.resize(occupancy.size());
    transformer.chamfer(view::DistanceMetric::kChamfer5711, occupancy, mapping.grid(), silhouette);
    grid = mapping.grid();
    focus.resize(grid.cell_count());
  }
};

TEST(AllowedError, LazyVertexEqualsFullArray) {
  // A sphere seen in perspective, silhouette + focus + back-face, pixel bound: every vertex's lazy value
  // equals the full pass bit for bit (same projection arithmetic).
  SphereView view;
  const std::vector<std::uint32_t> foci = {view::focus_cell(view.grid, 0.4f, 0.45f)};
  view.transformer.chamfer_from_cells(view::DistanceMetric::kChamfer5711, foci, view.grid, view.focus);
  view::AllowedErrorOptions options;
  options.error = 1.5f;
  options.units = view::ErrorUnits::kScreenPixels;
  options.criteria[view::Criterion::kSilhouette] = view::RegionLaw{};
  options.criteria[view::Criterion::kFocus] =
      view::RegionLaw{view::FalloffLaw::kFoveal, 0.0f, 0.1f, 0.0f, 2.3f};
  options.back_face_factor = 2.0f;
  view::AllowedErrorField field;
  field.bind(view.mapping, options,
             {{view.silhouette, view.focus, {}}, view.sphere.positions, view.sphere.normals, {}});
  std::vector<float> full(view.sphere.vertex_count());
  field.compute_all(full);
  std::size_t distinct = 0;
  for (std::uint32_t v = 0; v < full.size(); ++v) {
    ASSERT_EQ(field.vertex_allowed_error(v), full[v]) << "vertex " << v;
    distinct += full[v] != full[0];
  }
  EXPECT_GT(distinct, full.size() / 4);  // the laws actually vary over the sphere
}

TEST(AllowedError, AFieldReusedOverLawsAndFociEqualsAFreshOneEveryTime) {
  // A field keeps its law tables between requests (gazes reuse them); whatever came before, its
  // values equal those of a field bound for the first time: same law with foci nearer and farther
  // (larger labels extend the table), then other laws, metrics and fields of view.
  SphereView view;
  struct Step {
    float x, y;
    view::RegionLaw focus_law;
    view::DistanceMetric metric;
    float fovy_deg;
  };
  const view::RegionLaw foveal{view::FalloffLaw::kFoveal, 0.0f, 0.1f, 0.0f, 2.3f};
  const view::RegionLaw linear{view::FalloffLaw::kLinear, 4.0f, 0.2f, 12.0f, 2.3f};
  const std::vector<Step> steps = {
      {0.5f, 0.5f, foveal, view::DistanceMetric::kChamfer5711, 0.0f},    // centre: small labels
      {0.02f, 0.03f, foveal, view::DistanceMetric::kChamfer5711, 0.0f},  // corner: larger labels, table grows
      {0.45f, 0.5f, foveal, view::DistanceMetric::kChamfer5711, 0.0f},   // back: the longer table stays
      {0.45f, 0.5f, linear, view::DistanceMetric::kChamfer5711, 0.0f},   // another law
      {0.45f, 0.5f, linear, view::DistanceMetric::kChamfer34, 0.0f},     // another metric (same labels)
      {0.45f, 0.5f, foveal, view::DistanceMetric::kChamfer34, 70.0f},    // another field of view
  };
  view::AllowedErrorField reused;
  std::vector<float> kept(view.sphere.vertex_count()), fresh_values(view.sphere.vertex_count());
  for (std::size_t i = 0; i < steps.size(); ++i) {
    const Step& step = steps[i];
    const std::vector<std::uint32_t> foci = {view::focus_cell(view.grid, step.x, step.y)};
    view.transformer.chamfer_from_cells(step.metric, foci, view.grid, view.focus);
    view::AllowedErrorOptions options;
    options.error = 1.5f;
    options.units = view::ErrorUnits::kScreenPixels;
    options.metric = step.metric;
    options.fovy_deg = step.fovy_deg;
    options.criteria[view::Criterion::kSilhouette] = view::RegionLaw{};
    options.criteria[view::Criterion::kFocus] = step.focus_law;
    const view::AllowedErrorInputs inputs{{view.silhouette, view.focus, {}}, view.sphere.positions, {}, {}};
    reused.bind(view.mapping, options, inputs);
    reused.compute_all(kept);
    view::AllowedErrorField fresh;
    fresh.bind(view.mapping, options, inputs);
    fresh.compute_all(fresh_values);
    ASSERT_EQ(kept, fresh_values) << "step " << i;
    for (std::uint32_t c = 0; c < view.grid.cell_count(); c += 7)
      ASSERT_EQ(reused.gaze_factor(c), fresh.gaze_factor(c));
  }
}

TEST(AllowedError, TriangleMinimumEqualsLawOfTriangleLabel) {
  // The contract with the refiner: min over a triangle's vertices of the per-vertex allowed error is
  // the papers' e·f if label(t) ≤ d else e, with label(t) the minimum vertex label (step law,
  // silhouette mode, model units, on a sphere).
  const test::Scene sphere = test::uv_sphere(1.5f, 30, 60);
  const view::ViewMapping mapping = test::ortho_camera(2.0f, 64);
  const view::GridSize grid = mapping.grid();
  std::vector<std::uint8_t> occupancy(grid.cell_count());
  view::rasterize_occupancy(mapping, sphere.positions, sphere.triangles, occupancy);
  std::vector<std::uint16_t> dt(grid.cell_count());
  view::chamfer_5_7_11(occupancy, grid, dt);
  view::AllowedErrorOptions options;
  options.error = 0.01f;
  options.criteria[view::Criterion::kSilhouette] =
      view::RegionLaw{view::FalloffLaw::kStep, 3.0f, 0.25f, 0.0f, 2.3f};
  std::vector<float> allowed(sphere.vertex_count());
  view::compute_vertex_allowed_error(mapping, options, {{dt}, sphere.positions, {}, {}}, allowed);
  const std::size_t n = sphere.vertex_count();
  std::vector<std::uint32_t> cells(n), labels(n), triangle_labels(sphere.triangles.size() / 3);
  std::vector<float> clip_w(n);
  view::map_vertices(mapping, sphere.positions, cells, clip_w);
  view::label_vertices(cells, dt, labels);
  view::label_triangles(sphere.triangles, labels, triangle_labels);
  std::size_t inside = 0;
  for (std::size_t t = 0; t < triangle_labels.size(); ++t) {
    const std::uint32_t* tri = sphere.triangles.data() + 3 * t;
    const float by_vertices = std::min({allowed[tri[0]], allowed[tri[1]], allowed[tri[2]]});
    const bool in_region = triangle_labels[t] <= 15;  // d = 3 px = 15 raw
    ASSERT_EQ(by_vertices, in_region ? 0.01f * 0.25f : 0.01f) << "triangle " << t;
    inside += in_region;
  }
  EXPECT_GT(inside, 0u);
  EXPECT_LT(inside, triangle_labels.size());
}

}  // namespace
}  // namespace mtlod::core

// Grid mapping (core/ARCHITECTURE.md §1.1): known cameras, points and cells; points behind the
// camera or off the grid get no cell, and the hand-written projection equals GLM's matrix product.
#include "core/view/view_grid.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

namespace mtlod::core {
namespace {

// Orthographic camera on the z axis seeing [-2, 2]²: ndc = (x/2, y/2), so on an 8×8 grid
// i = floor((x + 2)·2) and j = floor((2 − y)·2).
view::ViewMapping ortho_mapping() {
  view::Camera camera;
  camera.view = glm::lookAt(glm::vec3(0, 0, 5), glm::vec3(0, 0, 0), glm::vec3(0, 1, 0));
  camera.projection = glm::ortho(-2.0f, 2.0f, -2.0f, 2.0f, 0.1f, 10.0f);
  return view::ViewMapping(camera, view::GridSize{8, 8});
}

// Perspective camera at the origin looking down −z with a 90° field of view: ndc = (x, y) / −z, so on a
// 10×10 grid i = floor((x/−z + 1)·5), j = floor((1 − y/−z)·5), and clip.w = −z.
view::ViewMapping perspective_mapping() {
  view::Camera camera;
  camera.view = glm::lookAt(glm::vec3(0, 0, 0), glm::vec3(0, 0, -1), glm::vec3(0, 1, 0));
  camera.projection = glm::perspective(glm::radians(90.0f), 1.0f, 0.1f, 100.0f);
  return view::ViewMapping(camera, view::GridSize{10, 10});
}

TEST(ViewMapping, OrthographicCameraPutsKnownPointsInKnownCells) {
  const view::ViewMapping mapping = ortho_mapping();
  const view::GridSize grid = mapping.grid();
  float w = 0.0f;
  EXPECT_EQ(mapping.map_point(0.0f, 0.0f, 0.0f, &w), grid.cell(4, 4));
  EXPECT_EQ(w, 1.0f);                                                // orthographic: clip.w is 1
  EXPECT_EQ(mapping.map_point(-1.9f, 1.9f, 0.0f), grid.cell(0, 0));  // (0.2, 0.2)
  EXPECT_EQ(mapping.map_point(1.9f, -1.9f, 0.0f), grid.cell(7, 7));  // (7.8, 7.8)
  EXPECT_EQ(mapping.map_point(0.3f, 0.6f, 1.0f), grid.cell(4, 2));   // (4.6, 2.8); depth does not matter
  EXPECT_EQ(mapping.map_point(-2.0f, 0.0f, 0.0f), grid.cell(0, 4));  // left edge: x = 0 is in cell 0
}

TEST(ViewMapping, OffGridPointsHaveNoCell) {
  const view::ViewMapping mapping = ortho_mapping();
  EXPECT_EQ(mapping.map_point(2.5f, 0.0f, 0.0f), view::kNoCell);
  EXPECT_EQ(mapping.map_point(2.0f, 0.0f, 0.0f), view::kNoCell);  // x = W exactly is past the last cell
  EXPECT_EQ(mapping.map_point(0.0f, -2.1f, 0.0f), view::kNoCell);
  EXPECT_EQ(mapping.map_point(0.0f, 2.0001f, 0.0f), view::kNoCell);
}

TEST(ViewMapping, PerspectiveCameraPutsKnownPointsInKnownCells) {
  const view::ViewMapping mapping = perspective_mapping();
  const view::GridSize grid = mapping.grid();
  float w = 0.0f;
  EXPECT_EQ(mapping.map_point(0.0f, 0.0f, -5.0f, &w), grid.cell(5, 5));
  EXPECT_EQ(w, 5.0f);
  EXPECT_EQ(mapping.map_point(2.0f, 1.0f, -4.0f, &w), grid.cell(7, 3));  // ndc (0.5, 0.25): (7.5, 3.75)
  EXPECT_EQ(w, 4.0f);
  EXPECT_EQ(mapping.map_point(-30.0f, -30.0f, -31.0f), grid.cell(0, 9));  // ndc ≈ (−0.968, −0.968)
  EXPECT_EQ(mapping.map_point(6.0f, 0.0f, -5.0f), view::kNoCell);         // ndc.x = 1.2
}

TEST(ViewMapping, PointsBehindTheCameraHaveNoCell) {
  const view::ViewMapping mapping = perspective_mapping();
  float w = 0.0f;
  EXPECT_EQ(mapping.map_point(0.0f, 0.0f, 5.0f, &w), view::kNoCell);
  EXPECT_EQ(w, -5.0f);
  EXPECT_EQ(mapping.map_point(0.0f, 0.0f, 0.0f), view::kNoCell);  // clip.w = 0: on the eye plane
  // Behind the camera and mirrored into the grid's range by the division: still no cell.
  EXPECT_EQ(mapping.map_point(1.0f, 1.0f, 4.0f), view::kNoCell);
}

TEST(ViewMapping, HandWrittenProjectionEqualsGlmMatrixProduct) {
  // A skewed camera and random points, some behind it or off the grid; 1003 points so the 4-wide loop
  // has a scalar tail. The summation order is GLM's, so cells and depths are equal bit for bit.
  view::Camera camera;
  camera.model =
      glm::rotate(glm::scale(glm::mat4(1.0f), glm::vec3(1.5f, 0.7f, 1.1f)), 0.4f, glm::vec3(1, 2, 3));
  camera.view = glm::lookAt(glm::vec3(0.3f, 1.2f, 2.5f), glm::vec3(0.1f, 0.0f, -0.2f), glm::vec3(0, 1, 0));
  camera.projection = glm::perspective(glm::radians(50.0f), 1.3f, 0.05f, 20.0f);
  const view::ViewMapping mapping(camera, view::GridSize{317, 243});
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-3.0f, 3.0f);
  std::vector<float> positions(3 * 1003);
  for (float& p : positions) p = u(rng);
  std::vector<std::uint32_t> cells(1003);
  std::vector<float> clip_w(1003);
  view::map_vertices(mapping, positions, cells, clip_w);
  const glm::mat4 mvp = camera.projection * camera.view * camera.model;
  std::size_t with_cell = 0, behind = 0;
  for (std::size_t v = 0; v < 1003; ++v) {
    const glm::vec4 clip =
        mvp * glm::vec4(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2], 1.0f);
    const glm::vec3 ndc = glm::vec3(clip) / clip.w;
    const float fx = std::floor((ndc.x + 1.0f) / 2.0f * 317.0f),
                fy = std::floor((1.0f - ndc.y) / 2.0f * 243.0f);
    const bool inside = clip.w > 0.0f && fx >= 0.0f && fx < 317.0f && fy >= 0.0f && fy < 243.0f;
    const std::uint32_t expected =
        inside ? static_cast<std::uint32_t>(fy) * 317u + static_cast<std::uint32_t>(fx) : view::kNoCell;
    ASSERT_EQ(cells[v], expected) << "vertex " << v;
    ASSERT_EQ(clip_w[v], clip.w) << "vertex " << v;
    EXPECT_EQ(mapping.map_point(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]), expected);
    with_cell += inside;
    behind += clip.w <= 0.0f;
  }
  // The scene must exercise all three cases for the comparison to mean something.
  EXPECT_GT(with_cell, 100u);
  EXPECT_GT(behind, 10u);
  EXPECT_GT(1003 - with_cell - behind, 10u);
}

TEST(ViewMapping, PixelSizeInModelUnitsFollowsDepthAndFieldOfView) {
  // 90° perspective, 10 px tall: one pixel at depth 5 spans 2·5·tan(45°)/10 = 1 model unit.
  // Tolerance: P[1][1] = 1/tan(π/4) is 1 only up to float rounding (a few ulp).
  const view::ViewMapping perspective = perspective_mapping();
  EXPECT_NEAR(perspective.model_units_per_pixel(5.0f, 10.0f), 1.0f, 1e-6f);
  EXPECT_NEAR(perspective.model_units_per_pixel(5.0f, 1000.0f), 0.01f, 1e-8f);
  // Orthographic over 4 units and 8 px: 0.5 units per pixel at any depth (P[1][1] = 2/4 exactly).
  EXPECT_EQ(ortho_mapping().model_units_per_pixel(1.0f, 8.0f), 0.5f);
}

TEST(ViewMapping, LargestStretchIsTheLargestSingularValue) {
  EXPECT_NEAR(view::largest_stretch(glm::mat4(1)), 1.0f, 1e-6f);
  const glm::mat4 rotation = glm::rotate(glm::mat4(1), 1.1f, glm::vec3(1, 2, 3));
  EXPECT_NEAR(view::largest_stretch(glm::translate(rotation, glm::vec3(5, 6, 7))), 1.0f, 1e-5f);
  EXPECT_NEAR(view::largest_stretch(glm::scale(rotation, glm::vec3(3))), 3.0f, 1e-5f);
  // Non-uniform: a rotation on each side leaves the singular values (1, 5, 2).
  const glm::mat4 skewed = glm::rotate(glm::mat4(1), -0.4f, glm::vec3(0, 1, 1)) *
                           glm::scale(glm::mat4(1), glm::vec3(1, 5, 2)) * rotation;
  EXPECT_NEAR(view::largest_stretch(skewed), 5.0f, 1e-4f);
  glm::mat4 broken(1);
  broken[1][2] = std::nanf("");
  EXPECT_EQ(view::largest_stretch(broken), 0.0f);
}

TEST(ViewMapping, PixelSizeIsInTheModelsUnitsUnderAScalingMatrix) {
  // The 90° camera's pixel at depth 5 on a 10 px viewport spans 1 eye unit; a model scaled ×4 by its
  // matrix (or by a view that folds the model matrix in) has 4 of its units in each eye unit.
  const view::ViewMapping plain = perspective_mapping();
  for (const bool in_view : {false, true}) {
    view::Camera camera;
    camera.view = glm::lookAt(glm::vec3(0, 0, 0), glm::vec3(0, 0, -1), glm::vec3(0, 1, 0));
    camera.projection = glm::perspective(glm::radians(90.0f), 1.0f, 0.1f, 100.0f);
    const glm::mat4 scale = glm::scale(glm::rotate(glm::mat4(1), 0.7f, glm::vec3(0, 1, 0)), glm::vec3(4.0f));
    if (in_view)
      camera.view = camera.view * scale;
    else
      camera.model = scale;
    const view::ViewMapping scaled(camera, view::GridSize{10, 10});
    EXPECT_NEAR(scaled.model_view_stretch(), 4.0f, 1e-5f);
    EXPECT_NEAR(scaled.model_units_per_pixel(5.0f, 10.0f), 0.25f, 1e-6f);
  }
  // A rigid view keeps the exact conversion.
  EXPECT_EQ(plain.model_view_stretch(), 1.0f);
}

TEST(ViewMapping, EyeInModelSpace) {
  // Tolerance: the eye comes out of a float matrix inverse (relative error ~1e-6).
  view::Camera camera;
  camera.model = glm::translate(glm::mat4(1.0f), glm::vec3(1, 0, 0));
  camera.view = glm::lookAt(glm::vec3(1, 2, 3), glm::vec3(0, 0, 0), glm::vec3(0, 1, 0));
  camera.projection = glm::perspective(glm::radians(60.0f), 1.0f, 0.1f, 10.0f);
  const glm::vec4 eye = view::ViewMapping(camera, view::GridSize{4, 4}).eye_model();
  // The model is shifted by +1 in x, so the world eye (1, 2, 3) is (0, 2, 3) in model space.
  EXPECT_NEAR(eye.x, 0.0f, 1e-5f);
  EXPECT_NEAR(eye.y, 2.0f, 1e-5f);
  EXPECT_NEAR(eye.z, 3.0f, 1e-5f);
  EXPECT_EQ(eye.w, 1.0f);
  // Orthographic: a direction towards the viewer, +z for a camera on the +z axis.
  const glm::vec4 dir = ortho_mapping().eye_model();
  EXPECT_NEAR(dir.z, 1.0f, 1e-6f);
  EXPECT_EQ(dir.w, 0.0f);
}

TEST(FocusCell, NormalisedViewportCoordinatesMapToCells) {
  const view::GridSize grid{10, 20};
  EXPECT_EQ(view::focus_cell(grid, 0.0f, 0.0f), grid.cell(0, 0));
  EXPECT_EQ(view::focus_cell(grid, 0.55f, 0.5f), grid.cell(5, 10));
  EXPECT_EQ(view::focus_cell(grid, 1.0f, 1.0f), grid.cell(9, 19));  // the far edge belongs to the last cell
  EXPECT_EQ(view::focus_cell(grid, -0.01f, 0.5f), view::kNoCell);
  EXPECT_EQ(view::focus_cell(grid, 0.5f, 1.5f), view::kNoCell);
}

}  // namespace
}  // namespace mtlod::core

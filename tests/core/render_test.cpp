// The evaluation's software rasteriser (core/render): coverage of a square of known size, the
// z-buffer (the nearer of two overlapping squares wins whatever the order), per-triangle colours,
// the wireframe overlay on the shared diagonal, the colour ramp's ends, the depth output, smooth
// shading from vertex normals and area-weighted normals.
#include "core/eval/render.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>

#include "core/view/view_grid.hpp"
#include "tests/core/test_scenes.hpp"

namespace mtlod::core {
namespace {

using test::add_rectangle;
using test::ortho_camera;

std::array<std::uint8_t, 3> pixel(const std::vector<std::uint8_t>& rgb, int size, int i, int j) {
  const std::size_t c = 3 * (std::size_t(j) * size + i);
  return {rgb[c], rgb[c + 1], rgb[c + 2]};
}

TEST(Render, SquareCoversKnownPixelsWithItsColour) {
  const view::ViewMapping mapping = ortho_camera(1.0f, 100);
  std::vector<float> p;
  std::vector<std::uint32_t> t;
  add_rectangle(p, t, -0.5f, -0.5f, 0.5f, 0.5f, 0.0f);  // grid [25, 75]²: 50 × 50 pixel centres
  std::vector<std::uint8_t> rgb(3 * 100 * 100);
  eval::RenderOptions options;
  options.shading = false;
  EXPECT_EQ(eval::render_mesh(mapping, p, t, {}, options, rgb), 2500u);
  std::size_t coloured = 0;
  for (int j = 0; j < 100; ++j)
    for (int i = 0; i < 100; ++i) coloured += pixel(rgb, 100, i, j) != options.background;
  EXPECT_EQ(coloured, 2500u);
  EXPECT_EQ(pixel(rgb, 100, 30, 60), options.base_color);
  // Facing the camera, the headlight gives full brightness: shading leaves the colour unchanged.
  options.shading = true;
  eval::render_mesh(mapping, p, t, {}, options, rgb);
  EXPECT_EQ(pixel(rgb, 100, 30, 60), options.base_color);
}

TEST(Render, NearerSurfaceWinsInEitherOrder) {
  const view::ViewMapping mapping = ortho_camera(1.0f, 64);
  std::vector<float> p;
  std::vector<std::uint32_t> t;
  add_rectangle(p, t, -0.8f, -0.8f, 0.4f, 0.4f, 0.0f);  // far (z = 0, camera at z = 5)
  add_rectangle(p, t, -0.4f, -0.4f, 0.8f, 0.8f, 1.0f);  // near, overlapping the centre
  const std::vector<std::uint8_t> colours = {255, 0, 0,   255, 0, 0,
                                             0,   0, 255, 0,   0, 255};  // far red, near blue
  eval::RenderOptions options;
  options.shading = false;
  std::vector<std::uint8_t> rgb(3 * 64 * 64);
  eval::render_mesh(mapping, p, t, {{}, colours}, options, rgb);
  const std::array<std::uint8_t, 3> red{255, 0, 0}, blue{0, 0, 255};
  EXPECT_EQ(pixel(rgb, 64, 32, 32), blue);  // the overlap
  EXPECT_EQ(pixel(rgb, 64, 10, 50), red);   // the far square alone (lower left)
  // Reversed triangle order: the same picture.
  std::vector<std::uint32_t> reversed = {t.begin() + 6, t.end()};
  reversed.insert(reversed.end(), t.begin(), t.begin() + 6);
  const std::vector<std::uint8_t> reversed_colours = {0, 0, 255, 0, 0, 255, 255, 0, 0, 255, 0, 0};
  std::vector<std::uint8_t> rgb2(rgb.size());
  eval::render_mesh(mapping, p, reversed, {{}, reversed_colours}, options, rgb2);
  EXPECT_EQ(rgb, rgb2);
}

TEST(Render, WireframeMarksTheDiagonal) {
  const view::ViewMapping mapping = ortho_camera(1.0f, 100);
  std::vector<float> p;
  std::vector<std::uint32_t> t;
  add_rectangle(p, t, -0.5f, -0.5f, 0.5f, 0.5f, 0.0f);
  eval::RenderOptions options;
  options.shading = false;
  options.wireframe = true;
  options.wire_width_px = 0.75f;
  std::vector<std::uint8_t> rgb(3 * 100 * 100);
  eval::render_mesh(mapping, p, t, {}, options, rgb);
  // The diagonal from grid (25, 75) to (75, 25) passes through pixel centre (50.5, 49.5).
  EXPECT_EQ(pixel(rgb, 100, 50, 49), options.wire_color);
  // Pixel (40, 40) is about 7 px from the diagonal and 15 px from the border: surface colour.
  EXPECT_EQ(pixel(rgb, 100, 40, 40), options.base_color);
  // Border pixels: centre 0.5 px from the edge is within the 0.75 px half width, 1.5 px is not.
  EXPECT_EQ(pixel(rgb, 100, 25, 60), options.wire_color);
  EXPECT_EQ(pixel(rgb, 100, 26, 60), options.base_color);
}

TEST(Render, RampEndsAreBlueAndRed) {
  EXPECT_EQ(eval::ramp_color(0.0f), (std::array<std::uint8_t, 3>{0, 0, 255}));
  EXPECT_EQ(eval::ramp_color(1.0f), (std::array<std::uint8_t, 3>{255, 0, 0}));
  EXPECT_EQ(eval::ramp_color(0.5f), (std::array<std::uint8_t, 3>{0, 255, 0}));
  EXPECT_EQ(eval::ramp_color(7.0f), eval::ramp_color(1.0f));
}

TEST(Render, DepthIsTheEyeSpaceDistanceOfTheNearestSurface) {
  // Orthographic camera at z = 5: the square at z = 0 is 5 away, the one at z = 1 is 4 away.
  const view::ViewMapping mapping = ortho_camera(1.0f, 64);
  std::vector<float> p;
  std::vector<std::uint32_t> t;
  add_rectangle(p, t, -0.8f, -0.8f, 0.4f, 0.4f, 0.0f);
  add_rectangle(p, t, -0.4f, -0.4f, 0.8f, 0.8f, 1.0f);
  std::vector<std::uint8_t> rgb(3 * 64 * 64);
  std::vector<float> depth(64 * 64);
  const std::size_t covered = eval::render_mesh(mapping, p, t, {}, {}, rgb, depth);
  // Through ndc z in float: a few ulps of the [−1, 1] range times (far − near)/2.
  EXPECT_NEAR(depth[32 * 64 + 32], 4.0f, 1e-5f);  // the overlap: the near square
  EXPECT_NEAR(depth[50 * 64 + 10], 5.0f, 1e-5f);  // the far square alone
  EXPECT_EQ(depth[2 * 64 + 2], std::numeric_limits<float>::infinity());
  std::size_t finite = 0;
  for (const float d : depth) finite += std::isfinite(d);
  EXPECT_EQ(finite, covered);
  // Asking for depth changes no pixel.
  std::vector<std::uint8_t> rgb2(rgb.size());
  eval::render_mesh(mapping, p, t, {}, {}, rgb2);
  EXPECT_EQ(rgb, rgb2);

  // Perspective: a square facing the eye at distance 5 has depth 5 everywhere (depth along the
  // axis, not the distance to the eye, which grows off the axis).
  view::Camera camera;
  camera.view = glm::lookAt(glm::vec3(0, 0, 5), glm::vec3(0, 0, 0), glm::vec3(0, 1, 0));
  camera.projection = glm::perspective(glm::radians(40.0f), 1.0f, 1.0f, 10.0f);
  const view::ViewMapping perspective(camera, {64, 64});
  eval::render_mesh(perspective, p, t, {}, {}, rgb, depth);
  EXPECT_NEAR(depth[40 * 64 + 20], 5.0f, 1e-4f);
  EXPECT_NEAR(depth[32 * 64 + 32], 4.0f, 1e-4f);
}

TEST(Render, SmoothShadingInterpolatesTheVertexNormals) {
  const view::ViewMapping mapping = ortho_camera(1.0f, 100);
  std::vector<float> p;
  std::vector<std::uint32_t> t;
  add_rectangle(p, t, -0.5f, -0.5f, 0.5f, 0.5f, 0.0f);  // corners 0, 3 on the left, 1, 2 on the right
  eval::RenderOptions options;
  std::vector<std::uint8_t> flat(3 * 100 * 100), smooth(flat.size());
  eval::render_mesh(mapping, p, t, {}, options, flat);

  // The face's own normal at every corner: the flat picture.
  const std::vector<float> facing = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  options.vertex_normals = facing;
  eval::render_mesh(mapping, p, t, {}, options, smooth);
  EXPECT_EQ(smooth, flat);

  // Normals tilted 60° from the view direction: |cos| = ½, shade 0.25 + 0.75·½ = 0.625.
  const float s60 = std::sin(glm::radians(60.0f)), c60 = 0.5f;
  const std::vector<float> tilted = {0, s60, c60, 0, s60, c60, 0, s60, c60, 0, s60, c60};
  options.vertex_normals = tilted;
  eval::render_mesh(mapping, p, t, {}, options, smooth);
  EXPECT_EQ(pixel(smooth, 100, 40, 60),
            (std::array<std::uint8_t, 3>{128, 125, 119}));  // 205, 200, 190 × 0.625

  // (0, 0, 1) on the left corners, (1, 0, 0) on the right: a quarter of the way across, the
  // interpolated normal is (¼, 0, ¾) (linear in x, so both triangles reproduce it) and
  // |cos| = 0.75/√(0.0625 + 0.5625) = 0.948683, shade 0.961512.
  const std::vector<float> turning = {0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 0, 1};
  options.vertex_normals = turning;
  eval::render_mesh(mapping, p, t, {}, options, smooth);
  // Pixel column 37: centre 37.5, a quarter of the way from 25 to 75. 205, 200, 190 × 0.961512.
  EXPECT_EQ(pixel(smooth, 100, 37, 30), (std::array<std::uint8_t, 3>{197, 192, 183}));
  EXPECT_EQ(pixel(smooth, 100, 37, 70), (std::array<std::uint8_t, 3>{197, 192, 183}));
}

TEST(Render, SmoothShadingIsPerspectiveCorrect) {
  // A quad tilted in depth (z = 1.5·x, nearer on the right) seen in perspective from (0, 0, 5), its
  // normal turning from (0, 0, 1) on the left edge to (1, 0, 0) on the right. A pixel's shade must be
  // that of the surface point its ray hits, found here by intersecting the ray with the plane; the
  // screen-space interpolation differs by 20 to 40 grey levels at these pixels.
  view::Camera camera;
  camera.view = glm::lookAt(glm::vec3(0, 0, 5), glm::vec3(0, 0, 0), glm::vec3(0, 1, 0));
  camera.projection = glm::perspective(glm::radians(40.0f), 1.0f, 1.0f, 10.0f);
  const view::ViewMapping mapping(camera, {100, 100});
  const std::vector<float> p = {-1, -0.5f, -1.5f, 1, -0.5f, 1.5f, 1, 0.5f, 1.5f, -1, 0.5f, -1.5f};
  const std::vector<std::uint32_t> t = {0, 1, 2, 0, 2, 3};
  const std::vector<float> normals = {0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 0, 1};
  eval::RenderOptions options;
  options.vertex_normals = normals;
  std::vector<std::uint8_t> rgb(3 * 100 * 100);
  eval::render_mesh(mapping, p, t, {}, options, rgb);
  const double tan20 = std::tan(20.0 * 3.14159265358979323846 / 180);
  for (const auto& [i, j] : {std::pair{60, 50}, std::pair{45, 50}, std::pair{70, 48}}) {
    // The ray through the pixel centre: direction (ndc.x·tan 20°, ndc.y·tan 20°, −1) from the eye.
    const double dx = ((i + 0.5) / 50 - 1) * tan20, dy = (1 - (j + 0.5) / 50) * tan20;
    const double s = 5 / (1 + 1.5 * dx);  // 5 − s = 1.5·s·dx: where it meets the plane
    const double x = s * dx, y = s * dy, z = 5 - s;
    const double u = (x + 1) / 2;  // across the quad, left to right
    const double n[3] = {u, 0, 1 - u}, view[3] = {-x, -y, 5 - z};
    const double cos = std::abs(n[0] * view[0] + n[2] * view[2]) /
                       (std::hypot(n[0], n[1], n[2]) * std::hypot(view[0], view[1], view[2]));
    const double shade = 0.25 + 0.75 * cos;
    const auto got = pixel(rgb, 100, i, j);
    for (int k = 0; k < 3; ++k)  // the renderer rounds to the nearest grey level
      EXPECT_NEAR(got[k], options.base_color[k] * shade, 0.51) << i << "," << j << " channel " << k;
  }
}

TEST(Render, AreaWeightedNormals) {
  // Two triangles sharing the edge (0,0,0)–(0,1,0): one of area 1 in the plane z = 0 facing +z, one
  // of area 2 in the plane x = 0 facing +x. The shared corners get (2, 0, 1)/√5; vertex 4 is on no
  // triangle.
  const std::vector<float> p = {0, 0, 0, 2, 0, 0, 0, 1, 0, 0, 0, 4, 9, 9, 9};
  const std::vector<std::uint32_t> t = {0, 1, 2, 0, 2, 3};
  std::vector<float> n(p.size());
  eval::area_weighted_normals(p, t, n);
  const float k = 1.0f / std::sqrt(5.0f);
  for (const int v : {0, 2}) {
    EXPECT_NEAR(n[3 * v], 2 * k, 1e-6f);
    EXPECT_EQ(n[3 * v + 1], 0.0f);
    EXPECT_NEAR(n[3 * v + 2], k, 1e-6f);
  }
  EXPECT_EQ((std::vector<float>(n.begin() + 3, n.begin() + 6)), (std::vector<float>{0, 0, 1}));
  EXPECT_EQ((std::vector<float>(n.begin() + 9, n.begin() + 12)), (std::vector<float>{1, 0, 0}));
  EXPECT_EQ((std::vector<float>(n.begin() + 12, n.end())), (std::vector<float>{0, 0, 0}));
}

}  // namespace
}  // namespace mtlod::core

// The evaluation's software rasteriser (core/render): coverage of a square of known size, the
// z-buffer (the nearer of two overlapping squares wins whatever the order), per-triangle colours,
// the wireframe overlay on the shared diagonal, and the colour ramp's ends.
#include "core/eval/render.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "core/view_grid.hpp"
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
  const ViewMapping mapping = ortho_camera(1.0f, 100);
  std::vector<float> p;
  std::vector<std::uint32_t> t;
  add_rectangle(p, t, -0.5f, -0.5f, 0.5f, 0.5f, 0.0f);  // grid [25, 75]²: 50 × 50 pixel centres
  std::vector<std::uint8_t> rgb(3 * 100 * 100);
  RenderOptions options;
  options.shading = false;
  EXPECT_EQ(render_mesh(mapping, p, t, {}, options, rgb), 2500u);
  std::size_t coloured = 0;
  for (int j = 0; j < 100; ++j)
    for (int i = 0; i < 100; ++i) coloured += pixel(rgb, 100, i, j) != options.background;
  EXPECT_EQ(coloured, 2500u);
  EXPECT_EQ(pixel(rgb, 100, 30, 60), options.base_color);
  // Facing the camera, the headlight gives full brightness: shading leaves the colour unchanged.
  options.shading = true;
  render_mesh(mapping, p, t, {}, options, rgb);
  EXPECT_EQ(pixel(rgb, 100, 30, 60), options.base_color);
}

TEST(Render, NearerSurfaceWinsInEitherOrder) {
  const ViewMapping mapping = ortho_camera(1.0f, 64);
  std::vector<float> p;
  std::vector<std::uint32_t> t;
  add_rectangle(p, t, -0.8f, -0.8f, 0.4f, 0.4f, 0.0f);  // far (z = 0, camera at z = 5)
  add_rectangle(p, t, -0.4f, -0.4f, 0.8f, 0.8f, 1.0f);  // near, overlapping the centre
  const std::vector<std::uint8_t> colours = {255, 0, 0,   255, 0, 0,
                                             0,   0, 255, 0,   0, 255};  // far red, near blue
  RenderOptions options;
  options.shading = false;
  std::vector<std::uint8_t> rgb(3 * 64 * 64);
  render_mesh(mapping, p, t, {{}, colours}, options, rgb);
  const std::array<std::uint8_t, 3> red{255, 0, 0}, blue{0, 0, 255};
  EXPECT_EQ(pixel(rgb, 64, 32, 32), blue);  // the overlap
  EXPECT_EQ(pixel(rgb, 64, 10, 50), red);   // the far square alone (lower left)
  // Reversed triangle order: the same picture.
  std::vector<std::uint32_t> reversed = {t.begin() + 6, t.end()};
  reversed.insert(reversed.end(), t.begin(), t.begin() + 6);
  const std::vector<std::uint8_t> reversed_colours = {0, 0, 255, 0, 0, 255, 255, 0, 0, 255, 0, 0};
  std::vector<std::uint8_t> rgb2(rgb.size());
  render_mesh(mapping, p, reversed, {{}, reversed_colours}, options, rgb2);
  EXPECT_EQ(rgb, rgb2);
}

TEST(Render, WireframeMarksTheDiagonal) {
  const ViewMapping mapping = ortho_camera(1.0f, 100);
  std::vector<float> p;
  std::vector<std::uint32_t> t;
  add_rectangle(p, t, -0.5f, -0.5f, 0.5f, 0.5f, 0.0f);
  RenderOptions options;
  options.shading = false;
  options.wireframe = true;
  options.wire_width_px = 0.75f;
  std::vector<std::uint8_t> rgb(3 * 100 * 100);
  render_mesh(mapping, p, t, {}, options, rgb);
  // The diagonal from grid (25, 75) to (75, 25) passes through pixel centre (50.5, 49.5).
  EXPECT_EQ(pixel(rgb, 100, 50, 49), options.wire_color);
  // Pixel (40, 40) is about 7 px from the diagonal and 15 px from the border: surface colour.
  EXPECT_EQ(pixel(rgb, 100, 40, 40), options.base_color);
  // Border pixels: centre 0.5 px from the edge is within the 0.75 px half width, 1.5 px is not.
  EXPECT_EQ(pixel(rgb, 100, 25, 60), options.wire_color);
  EXPECT_EQ(pixel(rgb, 100, 26, 60), options.base_color);
}

TEST(Render, RampEndsAreBlueAndRed) {
  EXPECT_EQ(ramp_color(0.0f), (std::array<std::uint8_t, 3>{0, 0, 255}));
  EXPECT_EQ(ramp_color(1.0f), (std::array<std::uint8_t, 3>{255, 0, 0}));
  EXPECT_EQ(ramp_color(0.5f), (std::array<std::uint8_t, 3>{0, 255, 0}));
  EXPECT_EQ(ramp_color(7.0f), ramp_color(1.0f));
}

}  // namespace
}  // namespace mtlod::core

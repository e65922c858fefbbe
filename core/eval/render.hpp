// A small software rasteriser for the evaluation's figures (tests/evaluation): z-buffered triangles
// through a view mapping, flat (headlight Lambert) shading, an optional wireframe overlay that the
// z-buffer hides like the surface, and colours per vertex or per triangle (the papers' figure 2
// labels, figure 5 Hausdorff colour map). Writes an RGB byte image; core/io/image_io makes the PNG.
// For the image-space metrics (core/eval/image_metrics) it also shades smoothly from given vertex
// normals, so that a cut, whose vertices are the model's, is lit with the model's own normals, and
// it hands out the depth of every pixel.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

namespace mtlod::core::view {
class ViewMapping;  // core/view/view_grid.hpp
}  // namespace mtlod::core::view

namespace mtlod::core::eval {

struct RenderOptions {
  std::array<std::uint8_t, 3> background{255, 255, 255};
  std::array<std::uint8_t, 3> base_color{205, 200, 190};  // surface colour when no colours are given
  bool shading = true;         // multiply by 0.25 + 0.75·|cos| of the view ray and the face normal
  bool wireframe = false;      // draw the visible triangle edges
  float wire_width_px = 0.5f;  // half width of a wire line, pixels
  std::array<std::uint8_t, 3> wire_color{40, 40, 40};
  // Smooth shading: x, y, z per vertex (indexed like positions; any length, zero gives the dark
  // 0.25). The normal and the view ray are interpolated perspective-correctly to each pixel and the
  // same headlight law applied there. Empty: flat shading from the face normal.
  std::span<const float> vertex_normals;
};

// Optional colours: per_vertex (3 bytes per vertex, interpolated across the triangle) or
// per_triangle (3 bytes per triangle); per_triangle wins when both are given.
struct RenderColors {
  std::span<const std::uint8_t> per_vertex;
  std::span<const std::uint8_t> per_triangle;
};

// Renders (positions, triangles) through mapping into rgb (3·mapping.grid().cell_count() bytes, row
// major, top row first), nearest surface wins. A pixel is drawn when its centre lies in a projected
// triangle; triangles with a corner at or behind the eye plane are skipped. Returns the number of
// pixels the mesh covers. depth, when not empty (one float per pixel), receives the eye-space depth
// of the visible surface (−z_eye in the camera's units, ViewMapping::eye_depth_from_ndc_z) and +inf
// where no triangle covers the pixel.
std::size_t render_mesh(const view::ViewMapping& mapping, std::span<const float> positions,
                        std::span<const std::uint32_t> triangles, const RenderColors& colors,
                        const RenderOptions& options, std::span<std::uint8_t> rgb,
                        std::span<float> depth = {});

// Area-weighted vertex normals of (positions, triangles): the sum of the (unnormalised, so
// area-weighted) face normals around each vertex, scaled to unit length; a vertex on no triangle, or
// whose faces cancel, gets (0, 0, 0). normals holds positions.size() floats.
void area_weighted_normals(std::span<const float> positions, std::span<const std::uint32_t> triangles,
                           std::span<float> normals);

// The colour ramp of the figures for t in [0, 1] (clamped): blue → cyan → green → yellow → red, the
// usual Hausdorff-distance palette (MESH, Metro). NaN gives grey.
std::array<std::uint8_t, 3> ramp_color(float t);

// Twice the signed area of the triangle (a, b, p): positive when p lies left of a→b. The
// rasterisers' inside test and barycentric weights.
inline double edge_function(double ax, double ay, double bx, double by, double px, double py) {
  return (bx - ax) * (py - ay) - (by - ay) * (px - ax);
}

}  // namespace mtlod::core::eval

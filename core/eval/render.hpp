// A small software rasteriser for the evaluation's figures (tests/evaluation): z-buffered triangles
// through a view mapping, flat (headlight Lambert) shading, an optional wireframe overlay that the
// z-buffer hides like the surface, and colours per vertex or per triangle (the papers' figure 2
// labels, figure 5 Hausdorff colour map). Writes an RGB byte image; core/io/image_io makes the PNG.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

namespace mtlod::core {

class ViewMapping;  // core/view_grid.hpp

struct RenderOptions {
  std::array<std::uint8_t, 3> background{255, 255, 255};
  std::array<std::uint8_t, 3> base_color{205, 200, 190};  // surface colour when no colours are given
  bool shading = true;         // multiply by 0.25 + 0.75·|cos| of the view ray and the face normal
  bool wireframe = false;      // draw the visible triangle edges
  float wire_width_px = 0.5f;  // half width of a wire line, pixels
  std::array<std::uint8_t, 3> wire_color{40, 40, 40};
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
// pixels the mesh covers.
std::size_t render_mesh(const ViewMapping& mapping, std::span<const float> positions,
                        std::span<const std::uint32_t> triangles, const RenderColors& colors,
                        const RenderOptions& options, std::span<std::uint8_t> rgb);

// The colour ramp of the figures for t in [0, 1] (clamped): blue → cyan → green → yellow → red, the
// usual Hausdorff-distance palette (MESH, Metro). NaN gives grey.
std::array<std::uint8_t, 3> ramp_color(float t);

}  // namespace mtlod::core

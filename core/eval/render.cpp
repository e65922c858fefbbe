// Software rasteriser for the evaluation figures (see render.hpp).
#include "core/eval/render.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <vector>

#include <glm/geometric.hpp>

#include "core/view/view_grid.hpp"

namespace mtlod::core::eval {
namespace {

// Headlight shade of one pixel from interpolated vertex normals: persp holds the screen-space
// barycentric weights of the corners divided by their clip.w, which renormalised are the
// perspective-correct weights of the surface point (screen-space weights would bend the shading of
// large triangles seen at an angle, and cuts have large triangles).
float smooth_shade(std::span<const float> normals, const std::uint32_t* corners, const float* const p[3],
                   const glm::vec4& eye, std::array<double, 3> persp) {
  const double total = persp[0] + persp[1] + persp[2];
  glm::vec3 n(0.0f), point(0.0f);
  for (int k = 0; k < 3; ++k) {
    const float b = float(persp[k] / total);
    const float* nk = normals.data() + 3 * std::size_t{corners[k]};
    n += b * glm::vec3(nk[0], nk[1], nk[2]);
    point += b * glm::vec3(p[k][0], p[k][1], p[k][2]);
  }
  const glm::vec3 view = glm::vec3(eye) - eye.w * point;
  const float len = glm::length(n) * glm::length(view);
  return len > 0 ? 0.25f + 0.75f * std::abs(glm::dot(n, view)) / len : 0.25f;
}

}  // namespace

std::array<std::uint8_t, 3> ramp_color(float t) {
  if (std::isnan(t)) return {128, 128, 128};
  t = std::clamp(t, 0.0f, 1.0f);
  // Five stops, linear in between.
  static constexpr float kStops[5][3] = {{0, 0, 255}, {0, 255, 255}, {0, 255, 0}, {255, 255, 0}, {255, 0, 0}};
  const float x = t * 4.0f;
  const int k = std::min(3, int(x));
  const float f = x - float(k);
  std::array<std::uint8_t, 3> out;
  for (int c = 0; c < 3; ++c)
    out[c] = std::uint8_t(std::lround(kStops[k][c] + f * (kStops[k + 1][c] - kStops[k][c])));
  return out;
}

// One loop over the triangles: the projected corners, the area, the flat shade and the edge
// lengths of a triangle are what its pixel loop reads, and splitting it would pass them all.
std::size_t render_mesh(const view::ViewMapping& mapping, std::span<const float> positions,
                        std::span<const std::uint32_t> triangles, const RenderColors& colors,
                        const RenderOptions& options, std::span<std::uint8_t> rgb,
                        std::span<float> depth_out) {
  const view::GridSize grid = mapping.grid();
  assert(rgb.size() == 3 * grid.cell_count());
  assert(depth_out.empty() || depth_out.size() == grid.cell_count());
  assert(options.vertex_normals.empty() || options.vertex_normals.size() == positions.size());
  const bool smooth = options.shading && !options.vertex_normals.empty();
  for (std::size_t c = 0; c < grid.cell_count(); ++c)
    for (int k = 0; k < 3; ++k) rgb[3 * c + k] = options.background[k];
  std::vector<float> depth(grid.cell_count(), std::numeric_limits<float>::infinity());
  const glm::vec4 eye = mapping.eye_model();

  for (std::size_t t = 0; t < triangles.size() / 3; ++t) {
    double gx[3], gy[3], gz[3], gw[3];
    bool visible = true;
    const float* p[3];
    for (int k = 0; k < 3; ++k) {
      p[k] = positions.data() + 3 * std::size_t{triangles[3 * t + k]};
      float cx, cy, cw;
      mapping.clip_xyw(p[k][0], p[k][1], p[k][2], cx, cy, cw);
      if (!(cw > 0.0f)) visible = false;
      const view::GridPoint g = mapping.to_grid(cx, cy, cw);
      gx[k] = g.x, gy[k] = g.y, gz[k] = mapping.clip_z(p[k][0], p[k][1], p[k][2]) / cw, gw[k] = cw;
    }
    if (!visible) continue;
    const double area = edge_function(gx[0], gy[0], gx[1], gy[1], gx[2], gy[2]);
    if (!(std::abs(area) > 0.0)) continue;

    // Headlight shading from the face normal and the ray to the eye at the centroid.
    float shade = 1.0f;
    if (options.shading && !smooth) {
      const glm::vec3 a(p[0][0], p[0][1], p[0][2]), b(p[1][0], p[1][1], p[1][2]),
          c(p[2][0], p[2][1], p[2][2]);
      const glm::vec3 n = glm::cross(b - a, c - a);
      const glm::vec3 view = glm::vec3(eye) - eye.w * (a + b + c) / 3.0f;
      const float len = glm::length(n) * glm::length(view);
      shade = len > 0 ? 0.25f + 0.75f * std::abs(glm::dot(n, view)) / len : 0.25f;
    }
    const double len01 = std::hypot(gx[1] - gx[0], gy[1] - gy[0]),
                 len12 = std::hypot(gx[2] - gx[1], gy[2] - gy[1]),
                 len20 = std::hypot(gx[0] - gx[2], gy[0] - gy[2]);
    const double lo_x = std::min({gx[0], gx[1], gx[2]}), hi_x = std::max({gx[0], gx[1], gx[2]});
    const double lo_y = std::min({gy[0], gy[1], gy[2]}), hi_y = std::max({gy[0], gy[1], gy[2]});
    const int i0 = std::max(0, int(std::ceil(lo_x - 0.5))),
              i1 = std::min(int(grid.width) - 1, int(std::floor(hi_x - 0.5)));
    const int j0 = std::max(0, int(std::ceil(lo_y - 0.5))),
              j1 = std::min(int(grid.height) - 1, int(std::floor(hi_y - 0.5)));
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        const double px = i + 0.5, py = j + 0.5;
        // Barycentric weights of corners 2, 0, 1 (the edge opposite each), positive inside.
        const double w2 = edge_function(gx[0], gy[0], gx[1], gy[1], px, py) / area;
        const double w0 = edge_function(gx[1], gy[1], gx[2], gy[2], px, py) / area;
        const double w1 = edge_function(gx[2], gy[2], gx[0], gy[0], px, py) / area;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const float z = float(w0 * gz[0] + w1 * gz[1] + w2 * gz[2]);
        const std::size_t cell = grid.cell(std::uint32_t(i), std::uint32_t(j));
        if (!(z < depth[cell])) continue;
        depth[cell] = z;
        std::uint8_t* out = &rgb[3 * cell];
        if (smooth)
          shade = smooth_shade(options.vertex_normals, triangles.data() + 3 * t, p, eye,
                               {w0 / gw[0], w1 / gw[1], w2 / gw[2]});
        // Distance to each edge in pixels: |edge function| / edge length = w·|area| / length.
        const double wire =
            std::min({w2 * std::abs(area) / len01, w0 * std::abs(area) / len12, w1 * std::abs(area) / len20});
        if (options.wireframe && wire < options.wire_width_px) {
          for (int k = 0; k < 3; ++k) out[k] = options.wire_color[k];
          continue;
        }
        for (int k = 0; k < 3; ++k) {
          double colour = options.base_color[k];
          if (!colors.per_triangle.empty()) {
            colour = colors.per_triangle[3 * t + k];
          } else if (!colors.per_vertex.empty()) {
            colour = w0 * colors.per_vertex[3 * std::size_t{triangles[3 * t]} + k] +
                     w1 * colors.per_vertex[3 * std::size_t{triangles[3 * t + 1]} + k] +
                     w2 * colors.per_vertex[3 * std::size_t{triangles[3 * t + 2]} + k];
          }
          out[k] = std::uint8_t(std::clamp(std::lround(colour * shade), 0l, 255l));
        }
      }
    }
  }
  if (!depth_out.empty())
    for (std::size_t c = 0; c < depth.size(); ++c)
      depth_out[c] = std::isinf(depth[c]) ? depth[c] : mapping.eye_depth_from_ndc_z(depth[c]);
  return grid.cell_count() -
         std::size_t(std::count(depth.begin(), depth.end(), std::numeric_limits<float>::infinity()));
}

void area_weighted_normals(std::span<const float> positions, std::span<const std::uint32_t> triangles,
                           std::span<float> normals) {
  assert(normals.size() == positions.size());
  std::vector<double> sum(positions.size(), 0.0);
  for (std::size_t t = 0; t < triangles.size() / 3; ++t) {
    const std::size_t v[3] = {triangles[3 * t], triangles[3 * t + 1], triangles[3 * t + 2]};
    double e1[3], e2[3];
    for (int k = 0; k < 3; ++k)
      e1[k] = double(positions[3 * v[1] + k]) - positions[3 * v[0] + k],
      e2[k] = double(positions[3 * v[2] + k]) - positions[3 * v[0] + k];
    // The cross product's length is twice the area: summing it weights each face by its area.
    const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                         e1[0] * e2[1] - e1[1] * e2[0]};
    for (const std::size_t corner : v)
      for (int k = 0; k < 3; ++k) sum[3 * corner + k] += n[k];
  }
  for (std::size_t v = 0; v < positions.size() / 3; ++v) {
    const double len = std::hypot(sum[3 * v], sum[3 * v + 1], sum[3 * v + 2]);
    for (int k = 0; k < 3; ++k) normals[3 * v + k] = len > 0 ? float(sum[3 * v + k] / len) : 0.0f;
  }
}

}  // namespace mtlod::core::eval

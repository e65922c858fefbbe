// Silhouette masks, XOR and contour distances (see silhouette_metrics.hpp).
#include "core/eval/silhouette_metrics.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <vector>

#include "core/eval/render.hpp"
#include "core/view/distance_transform.hpp"
#include "core/view/view_grid.hpp"

namespace mtlod::core::eval {
namespace {

// Projects the three corners of triangle t; false when one is at or behind the eye plane.
bool project_triangle(const view::ViewMapping& mapping, std::span<const float> positions,
                      std::span<const std::uint32_t> triangles, std::size_t t, view::GridPoint out[3]) {
  for (int k = 0; k < 3; ++k) {
    const float* p = positions.data() + 3 * std::size_t{triangles[3 * t + k]};
    float cx, cy, cw;
    mapping.clip_xyw(p[0], p[1], p[2], cx, cy, cw);
    if (!(cw > 0.0f)) return false;
    out[k] = mapping.to_grid(cx, cy, cw);
  }
  return true;
}

double point_segment_2d(double px, double py, double ax, double ay, double bx, double by) {
  const double dx = bx - ax, dy = by - ay, len2 = dx * dx + dy * dy;
  const double t = len2 > 0 ? std::clamp(((px - ax) * dx + (py - ay) * dy) / len2, 0.0, 1.0) : 0.0;
  const double qx = ax + t * dx - px, qy = ay + t * dy - py;
  return std::sqrt(qx * qx + qy * qy);
}

// Distances from the contour pixels of `from` to the nearest contour pixel of `to`.
ContourDistance contour_distance(std::span<const std::uint8_t> from_contour,
                                 std::span<const std::uint8_t> to_contour, view::GridSize grid,
                                 std::vector<std::uint8_t>& seeds, std::vector<std::uint32_t>& dt) {
  ContourDistance out;
  for (std::size_t c = 0; c < seeds.size(); ++c) seeds[c] = to_contour[c] ? 0 : 1;
  view::euclidean_squared(seeds, grid, dt);
  double sum = 0.0;
  for (std::size_t c = 0; c < from_contour.size(); ++c) {
    if (!from_contour[c]) continue;
    const double d = dt[c] == view::kEuclideanUnreached ? std::numeric_limits<double>::infinity()
                                                        : std::sqrt(double(dt[c]));
    out.max_px = std::max(out.max_px, d);
    sum += d;
    ++out.pixels;
  }
  if (out.pixels > 0) out.mean_px = sum / double(out.pixels);
  return out;
}

}  // namespace

std::size_t rasterize_silhouette(const view::ViewMapping& mapping, std::span<const float> positions,
                                 std::span<const std::uint32_t> triangles, std::span<std::uint8_t> mask) {
  const view::GridSize grid = mapping.grid();
  assert(mask.size() == grid.cell_count());
  std::fill(mask.begin(), mask.end(), std::uint8_t{0});
  view::GridPoint g[3];
  for (std::size_t t = 0; t < triangles.size() / 3; ++t) {
    if (!project_triangle(mapping, positions, triangles, t, g)) continue;
    const double area = edge_function(g[0].x, g[0].y, g[1].x, g[1].y, g[2].x, g[2].y);
    if (!(std::abs(area) > 0.0)) continue;
    // Pixel centres (i + 0.5, j + 0.5) inside the bounding box; both windings count.
    const double lo_x = std::min({g[0].x, g[1].x, g[2].x}), hi_x = std::max({g[0].x, g[1].x, g[2].x});
    const double lo_y = std::min({g[0].y, g[1].y, g[2].y}), hi_y = std::max({g[0].y, g[1].y, g[2].y});
    const int i0 = std::max(0, int(std::ceil(lo_x - 0.5))),
              i1 = std::min(int(grid.width) - 1, int(std::floor(hi_x - 0.5)));
    const int j0 = std::max(0, int(std::ceil(lo_y - 0.5))),
              j1 = std::min(int(grid.height) - 1, int(std::floor(hi_y - 0.5)));
    const double sign = area > 0 ? 1.0 : -1.0;
    for (int j = j0; j <= j1; ++j) {
      for (int i = i0; i <= i1; ++i) {
        const double px = i + 0.5, py = j + 0.5;
        if (sign * edge_function(g[0].x, g[0].y, g[1].x, g[1].y, px, py) >= 0 &&
            sign * edge_function(g[1].x, g[1].y, g[2].x, g[2].y, px, py) >= 0 &&
            sign * edge_function(g[2].x, g[2].y, g[0].x, g[0].y, px, py) >= 0)
          mask[grid.cell(std::uint32_t(i), std::uint32_t(j))] = 1;
      }
    }
  }
  return std::size_t(std::count(mask.begin(), mask.end(), std::uint8_t{1}));
}

std::size_t xor_count(std::span<const std::uint8_t> a, std::span<const std::uint8_t> b,
                      std::span<std::uint8_t> diff) {
  assert(a.size() == b.size());
  assert(diff.empty() || diff.size() == a.size());
  std::size_t count = 0;
  for (std::size_t c = 0; c < a.size(); ++c) {
    const bool differs = (a[c] != 0) != (b[c] != 0);
    count += differs;
    if (!diff.empty()) diff[c] = differs;
  }
  return count;
}

std::size_t extract_contour(std::span<const std::uint8_t> mask, view::GridSize grid,
                            std::span<std::uint8_t> contour) {
  assert(mask.size() == grid.cell_count() && contour.size() == mask.size());
  std::size_t count = 0;
  const auto object = [&](std::int64_t i, std::int64_t j) {
    return i >= 0 && j >= 0 && i < std::int64_t(grid.width) && j < std::int64_t(grid.height) &&
           mask[std::size_t(j) * grid.width + std::size_t(i)] != 0;
  };
  for (std::int64_t j = 0; j < std::int64_t(grid.height); ++j) {
    for (std::int64_t i = 0; i < std::int64_t(grid.width); ++i) {
      const bool on =
          object(i, j) && !(object(i - 1, j) && object(i + 1, j) && object(i, j - 1) && object(i, j + 1));
      contour[std::size_t(j) * grid.width + std::size_t(i)] = on;
      count += on;
    }
  }
  return count;
}

SilhouetteError compare_silhouettes(std::span<const std::uint8_t> mask_a,
                                    std::span<const std::uint8_t> mask_b, view::GridSize grid) {
  assert(mask_a.size() == grid.cell_count() && mask_b.size() == grid.cell_count());
  SilhouetteError out;
  out.xor_pixels = xor_count(mask_a, mask_b);
  out.pixels_a = grid.cell_count() - std::size_t(std::count(mask_a.begin(), mask_a.end(), std::uint8_t{0}));
  out.pixels_b = grid.cell_count() - std::size_t(std::count(mask_b.begin(), mask_b.end(), std::uint8_t{0}));
  std::vector<std::uint8_t> contour_a(grid.cell_count()), contour_b(grid.cell_count()),
      seeds(grid.cell_count());
  std::vector<std::uint32_t> dt(grid.cell_count());
  extract_contour(mask_a, grid, contour_a);
  extract_contour(mask_b, grid, contour_b);
  out.a_to_b = contour_distance(contour_a, contour_b, grid, seeds, dt);
  out.b_to_a = contour_distance(contour_b, contour_a, grid, seeds, dt);
  return out;
}

std::size_t triangles_near_point(const view::ViewMapping& mapping, std::span<const float> positions,
                                 std::span<const std::uint32_t> triangles, float x_px, float y_px,
                                 float radius_px, std::span<std::uint8_t> in_region) {
  assert(in_region.size() == triangles.size() / 3);
  std::size_t count = 0;
  view::GridPoint g[3];
  for (std::size_t t = 0; t < in_region.size(); ++t) {
    in_region[t] = 0;
    if (!project_triangle(mapping, positions, triangles, t, g)) continue;
    const double e0 = edge_function(g[0].x, g[0].y, g[1].x, g[1].y, x_px, y_px);
    const double e1 = edge_function(g[1].x, g[1].y, g[2].x, g[2].y, x_px, y_px);
    const double e2 = edge_function(g[2].x, g[2].y, g[0].x, g[0].y, x_px, y_px);
    // A degenerate projection has no inside (every point on its line would pass the sign test).
    const bool flat = !(std::abs(edge_function(g[0].x, g[0].y, g[1].x, g[1].y, g[2].x, g[2].y)) > 0.0);
    const bool inside = !flat && ((e0 >= 0 && e1 >= 0 && e2 >= 0) || (e0 <= 0 && e1 <= 0 && e2 <= 0));
    const double d = inside ? 0.0
                            : std::min({point_segment_2d(x_px, y_px, g[0].x, g[0].y, g[1].x, g[1].y),
                                        point_segment_2d(x_px, y_px, g[1].x, g[1].y, g[2].x, g[2].y),
                                        point_segment_2d(x_px, y_px, g[2].x, g[2].y, g[0].x, g[0].y)});
    if (d <= radius_px) in_region[t] = 1, ++count;
  }
  return count;
}

}  // namespace mtlod::core::eval

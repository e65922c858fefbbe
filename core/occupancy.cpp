// Conservative rasterization for the occupancy image (DESIGN.md §1.2). Each triangle is clipped to
// the half-space in front of the camera, then walked row by row: the cells of row j that it meets are
// those between the smallest and largest x of (triangle ∩ strip j ≤ y ≤ j+1), which for a convex
// polygon are found among its corners inside the strip and its edges' crossings of the strip's two
// lines. This is exact for the closed triangle, so a triangle smaller than a cell marks its cell.
#include "core/occupancy.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <limits>

namespace mtlod::core {

namespace {

// A projected corner: grid coordinates and ndc.z (affine in screen space, so it interpolates).
struct Corner {
  double x, y, ndc_z;
};

// Homogeneous corner before the division, for clipping.
struct ClipCorner {
  double x, y, z, w;
};

// Sutherland–Hodgman against w ≥ kMinClipW: a triangle becomes at most a quadrilateral.
int clip_to_front(const std::array<ClipCorner, 3>& in, std::array<ClipCorner, 4>& out) {
  int count = 0;
  for (int k = 0; k < 3; ++k) {
    const ClipCorner& a = in[k];
    const ClipCorner& b = in[(k + 1) % 3];
    const bool a_in = a.w >= kMinClipW, b_in = b.w >= kMinClipW;
    if (a_in) out[count++] = a;
    if (a_in != b_in) {
      const double t = (kMinClipW - a.w) / (b.w - a.w);
      out[count++] = {a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), a.z + t * (b.z - a.z), kMinClipW};
    }
  }
  return count;
}

class Rasterizer {
 public:
  Rasterizer(GridSize grid, std::span<std::uint8_t> occupancy, std::span<float> depth,
             const ViewMapping& mapping)
      : grid_(grid), occupancy_(occupancy), depth_(depth), mapping_(mapping) {}

  // Marks the cells met by a convex polygon of 3 or 4 corners. Returns whether any cell was marked.
  bool fill(const Corner* corners, int count) {
    double ymin = corners[0].y, ymax = corners[0].y;
    for (int k = 1; k < count; ++k) {
      ymin = std::min(ymin, corners[k].y);
      ymax = std::max(ymax, corners[k].y);
    }
    // Half-open cells: a polygon reaching y = H exactly touches no row, one starting at y = 0 does.
    if (!(ymax >= 0.0 && ymin < grid_.height)) return false;
    const auto row_first = static_cast<std::uint32_t>(std::max(0.0, std::floor(ymin)));
    const auto row_last = static_cast<std::uint32_t>(std::min<double>(grid_.height - 1, std::floor(ymax)));
    const bool with_depth = !depth_.empty();
    Plane plane{};
    if (with_depth) plane = fit_plane(corners, count);
    bool marked = false;
    for (std::uint32_t j = row_first; j <= row_last; ++j) {
      const double y0 = std::max<double>(j, ymin), y1 = std::min<double>(j + 1.0, ymax);
      double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin;
      for (int k = 0; k < count; ++k) {
        const Corner& a = corners[k];
        const Corner& b = corners[(k + 1) % count];
        if (a.y >= y0 && a.y <= y1) {
          xmin = std::min(xmin, a.x);
          xmax = std::max(xmax, a.x);
        }
        // Crossings of the strip's lines by edge (a, b); horizontal edges have both ends counted above.
        if (a.y != b.y) {
          for (const double line : {y0, y1}) {
            if ((a.y - line) * (b.y - line) < 0.0) {
              const double x = a.x + (line - a.y) / (b.y - a.y) * (b.x - a.x);
              xmin = std::min(xmin, x);
              xmax = std::max(xmax, x);
            }
          }
        }
      }
      if (!(xmax >= 0.0 && xmin < grid_.width)) continue;
      const auto first = static_cast<std::uint32_t>(std::max(0.0, std::floor(xmin)));
      const auto last = static_cast<std::uint32_t>(std::min<double>(grid_.width - 1, std::floor(xmax)));
      std::uint8_t* row = occupancy_.data() + std::size_t{j} * grid_.width;
      std::fill(row + first, row + last + 1, std::uint8_t{1});
      if (with_depth) {
        float* depth_row = depth_.data() + std::size_t{j} * grid_.width;
        for (std::uint32_t i = first; i <= last; ++i) {
          const double z =
              std::clamp(plane.a * (i + 0.5) + plane.b * (j + 0.5) + plane.c, plane.zmin, plane.zmax);
          depth_row[i] = std::min(depth_row[i], mapping_.eye_depth_from_ndc_z(static_cast<float>(z)));
        }
      }
      marked = true;
    }
    return marked;
  }

 private:
  struct Plane {
    double a, b, c, zmin, zmax;
  };
  // ndc_z = a·x + b·y + c through the first three corners (all corners lie on it); a flat
  // constant when the projection is degenerate.
  static Plane fit_plane(const Corner* p, int count) {
    Plane plane{0.0, 0.0, p[0].ndc_z, p[0].ndc_z, p[0].ndc_z};
    for (int k = 1; k < count; ++k) {
      plane.zmin = std::min(plane.zmin, p[k].ndc_z);
      plane.zmax = std::max(plane.zmax, p[k].ndc_z);
    }
    const double ux = p[1].x - p[0].x, uy = p[1].y - p[0].y, uz = p[1].ndc_z - p[0].ndc_z;
    const double vx = p[2].x - p[0].x, vy = p[2].y - p[0].y, vz = p[2].ndc_z - p[0].ndc_z;
    const double det = ux * vy - uy * vx;
    if (std::abs(det) < 1e-12) {
      plane.c = plane.zmin;  // seen edge-on: its nearest depth everywhere
      return plane;
    }
    plane.a = (uz * vy - uy * vz) / det;
    plane.b = (ux * vz - uz * vx) / det;
    plane.c = p[0].ndc_z - plane.a * p[0].x - plane.b * p[0].y;
    return plane;
  }

  GridSize grid_;
  std::span<std::uint8_t> occupancy_;
  std::span<float> depth_;
  const ViewMapping& mapping_;
};

}  // namespace

std::size_t rasterize_occupancy(const ViewMapping& mapping, std::span<const float> positions,
                                std::span<const std::uint32_t> triangles, std::span<std::uint8_t> occupancy,
                                std::span<float> depth) {
  const GridSize grid = mapping.grid();
  assert(triangles.size() % 3 == 0 && occupancy.size() == grid.cell_count());
  assert(depth.empty() || depth.size() == grid.cell_count());
  std::fill(occupancy.begin(), occupancy.end(), std::uint8_t{0});
  std::fill(depth.begin(), depth.end(), std::numeric_limits<float>::infinity());
  Rasterizer rasterizer(grid, occupancy, depth, mapping);
  const double width = grid.width, height = grid.height;
  std::size_t marking = 0;
  for (std::size_t t = 0; t < triangles.size(); t += 3) {
    std::array<ClipCorner, 3> clip;
    bool all_front = true;
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t v = triangles[t + k];
      assert(3 * std::size_t{v} + 2 < positions.size());
      const float* p = positions.data() + 3 * std::size_t{v};
      float cx, cy, cw;
      mapping.clip_xyw(p[0], p[1], p[2], cx, cy, cw);
      clip[k] = {cx, cy, mapping.clip_z(p[0], p[1], p[2]), cw};
      all_front &= cw >= kMinClipW;
    }
    std::array<ClipCorner, 4> front;
    int count = 3;
    if (all_front) {
      std::copy(clip.begin(), clip.end(), front.begin());
    } else {
      count = clip_to_front(clip, front);
      if (count < 3) continue;  // entirely behind the camera
    }
    // The grid coordinates of ViewMapping::to_grid, in double for the clipped, far-flung corners.
    Corner corners[4];
    for (int k = 0; k < count; ++k) {
      const ClipCorner& c = front[k];
      corners[k] = {(c.x / c.w + 1.0) * 0.5 * width, (1.0 - c.y / c.w) * 0.5 * height, c.z / c.w};
    }
    marking += rasterizer.fill(corners, count) ? 1 : 0;
  }
  return marking;
}

std::size_t mark_depth_discontinuities(std::span<const float> depth, GridSize grid, float relative_jump,
                                       std::span<std::uint8_t> image) {
  assert(depth.size() == grid.cell_count() && image.size() == grid.cell_count());
  std::size_t marked = 0;
  // Seeding the farther cell makes the nearer surface's cell next to the jump get label 5, as an
  // object cell next to the background does at the external silhouette.
  auto compare = [&](std::size_t a, std::size_t b) {
    const float da = depth[a], db = depth[b];
    if (!(std::isfinite(da) && std::isfinite(db))) return;  // background: the external silhouette's job
    const float nearer = std::min(da, db);
    if (std::abs(da - db) <= relative_jump * nearer) return;
    const std::size_t farther = da > db ? a : b;
    if (image[farther] != 0) {
      image[farther] = 0;
      ++marked;
    }
  };
  for (std::size_t j = 0; j < grid.height; ++j) {
    for (std::size_t i = 0; i < grid.width; ++i) {
      const std::size_t c = j * grid.width + i;
      if (i + 1 < grid.width) compare(c, c + 1);
      if (j + 1 < grid.height) compare(c, c + grid.width);
    }
  }
  return marked;
}

}  // namespace mtlod::core

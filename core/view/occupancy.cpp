// Occupancy by conservative rasterization (core/ARCHITECTURE.md §1.2). Each triangle is clipped to
// the half-space in front of the camera, then walked row by row: the cells of row j that it meets are
// those between the smallest and largest x of (triangle ∩ strip j ≤ y ≤ j+1), which for a convex
// polygon are found among its corners inside the strip and its edges' crossings of the strip's two
// lines. This is exact for the closed triangle, so a triangle smaller than a cell marks its cell.
// Triangles in front of the camera whose box lies inside the grid and spans at most 16 cells a side
// (nearly all of an occupancy cut's) take a faster exact test instead, cell by cell (fill_small).
#include "core/view/occupancy.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace mtlod::core::view {

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

// floor(x) for a coordinate, clamped to ±2^30 first (far beyond any grid): without SSE4.1 std::floor
// is a libm call, and it ran several times per triangle.
inline double floor_clamped(double x) {
  x = std::clamp(x, -1073741824.0, 1073741824.0);
  const auto t = static_cast<double>(static_cast<std::int64_t>(x));
  return t > x ? t - 1.0 : t;
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
    const auto row_first = static_cast<std::uint32_t>(std::max(0.0, floor_clamped(ymin)));
    const auto row_last = static_cast<std::uint32_t>(std::min<double>(grid_.height - 1, floor_clamped(ymax)));
    const bool with_depth = !depth_.empty();
    Plane plane{};
    if (with_depth) plane = fit_plane(corners, count);
    // Edge slopes dx/dy once per polygon; horizontal edges never cross a strip line strictly.
    double slope[4];
    for (int k = 0; k < count; ++k) {
      const Corner& a = corners[k];
      const Corner& b = corners[(k + 1) % count];
      slope[k] = a.y != b.y ? (b.x - a.x) / (b.y - a.y) : 0.0;
    }
    // Unclamped: a polygon running off the grid's top or bottom is not in a single row.
    const bool single_row = floor_clamped(ymin) == floor_clamped(ymax);
    bool marked = false;
    for (std::uint32_t j = row_first; j <= row_last; ++j) {
      double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin;
      if (single_row) {
        // The whole polygon lies in this row (most cut triangles are about a cell in size).
        for (int k = 0; k < count; ++k) {
          xmin = std::min(xmin, corners[k].x);
          xmax = std::max(xmax, corners[k].x);
        }
      } else {
        const double y0 = std::max<double>(j, ymin), y1 = std::min<double>(j + 1.0, ymax);
        for (int k = 0; k < count; ++k) {
          const Corner& a = corners[k];
          const Corner& b = corners[(k + 1) % count];
          if (a.y >= y0 && a.y <= y1) {
            xmin = std::min(xmin, a.x);
            xmax = std::max(xmax, a.x);
          }
          // Crossings of the strip's lines by edge (a, b); an end on a line was counted above.
          for (const double line : {y0, y1}) {
            if ((a.y - line) * (b.y - line) < 0.0) {
              const double x = a.x + (line - a.y) * slope[k];
              xmin = std::min(xmin, x);
              xmax = std::max(xmax, x);
            }
          }
        }
      }
      if (!(xmax >= 0.0 && xmin < grid_.width)) continue;
      const auto first = static_cast<std::uint32_t>(std::max(0.0, floor_clamped(xmin)));
      const auto last = static_cast<std::uint32_t>(std::min<double>(grid_.width - 1, floor_clamped(xmax)));
      std::uint8_t* row = occupancy_.data() + std::size_t{j} * grid_.width;
      // Spans are mostly a few cells: a plain loop beats a call to memset.
      if (last - first < 16) {
        for (std::uint32_t i = first; i <= last; ++i) row[i] = 1;
      } else {
        std::fill(row + first, row + last + 1, std::uint8_t{1});
      }
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

// Small triangles wholly inside the grid (most of an occupancy cut's), by the separating-axis test
// cell by cell: a cell of the triangle's box is met when, for each edge, the edge function's
// largest value over the closed cell reaches the inside. In double, in coordinates relative to the
// box's first cell, so every term is exact or rounds at the 1e-16 level, as the strip walk does.
// The box is cells [i0, i1] × [j0, j1] of the grid. Returns false, having marked nothing, for a
// degenerate triangle or a box over 16 cells on a side (the strip walk takes those); otherwise true,
// with `marked` telling whether any cell was marked.
bool fill_small(const ProjectedCorner& a, const ProjectedCorner& b, const ProjectedCorner& c,
                std::uint32_t i0, std::uint32_t i1, std::uint32_t j0, std::uint32_t j1, GridSize grid,
                std::uint8_t* occupancy, bool& marked) {
  constexpr std::uint32_t kSide = 16;
  if (i1 - i0 >= kSide || j1 - j0 >= kSide) return false;
  const double p[3][2] = {{double(a.gx) - i0, double(a.gy) - j0},
                          {double(b.gx) - i0, double(b.gy) - j0},
                          {double(c.gx) - i0, double(c.gy) - j0}};
  const double area2 = (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[1][1] - p[0][1]) * (p[2][0] - p[0][0]);
  if (area2 == 0.0) return false;
  const double orientation = area2 > 0.0 ? 1.0 : -1.0;
  // Edge k from p[k] to p[k+1]: e(x, y) = A·x + B·y + C ≥ 0 inside; its largest value over the cell
  // [i, i+1] × [j, j+1] is A·i + B·j + C + max(A, 0) + max(B, 0).
  double edge_a[3], edge_b[3], edge_c[3];
  for (int k = 0; k < 3; ++k) {
    const double* from = p[k];
    const double* to = p[(k + 1) % 3];
    edge_a[k] = -orientation * (to[1] - from[1]);
    edge_b[k] = orientation * (to[0] - from[0]);
    edge_c[k] =
        -(edge_a[k] * from[0] + edge_b[k] * from[1]) + std::max(edge_a[k], 0.0) + std::max(edge_b[k], 0.0);
  }
  const std::uint32_t columns = i1 - i0 + 1, rows = j1 - j0 + 1;
  // A row's cells met, one bit per column, then written as bytes.
  std::uint32_t any = 0;
#if defined(__SSE2__)
  // Bits become bytes 16 at a time, OR-ed into the row (cells past the box get 0 | their value),
  // when 16 bytes from the box's last row's first cell stay inside the grid: no loop per bit, whose
  // trip count the branch predictor cannot guess.
  const bool whole_rows = std::size_t{j1} * grid.width + i0 + 16 <= grid.cell_count();
  const __m128i bit_of_byte = _mm_set_epi8(-128, 64, 32, 16, 8, 4, 2, 1, -128, 64, 32, 16, 8, 4, 2, 1);
  const __m128i one = _mm_set1_epi8(1);
  // Two columns per register: A·i for columns (2m, 2m+1), per edge, once per triangle.
  const std::uint32_t pairs = (columns + 1) / 2;
  __m128d edge_a_i[3][kSide / 2];
  for (int k = 0; k < 3; ++k) {
    for (std::uint32_t m = 0; m < pairs; ++m)
      edge_a_i[k][m] = _mm_mul_pd(_mm_set1_pd(edge_a[k]), _mm_set_pd(2.0 * m + 1, 2.0 * m));
  }
  const __m128d zero = _mm_setzero_pd();
#endif
  for (std::uint32_t dj = 0; dj < rows; ++dj) {
    double row_c[3];
    for (int k = 0; k < 3; ++k) row_c[k] = edge_b[k] * dj + edge_c[k];
    std::uint32_t bits = 0;
#if defined(__SSE2__)
    const __m128d c0 = _mm_set1_pd(row_c[0]), c1 = _mm_set1_pd(row_c[1]), c2 = _mm_set1_pd(row_c[2]);
    for (std::uint32_t m = 0; m < pairs; ++m) {
      const __m128d inside = _mm_and_pd(_mm_and_pd(_mm_cmpge_pd(_mm_add_pd(edge_a_i[0][m], c0), zero),
                                                   _mm_cmpge_pd(_mm_add_pd(edge_a_i[1][m], c1), zero)),
                                        _mm_cmpge_pd(_mm_add_pd(edge_a_i[2][m], c2), zero));
      bits |= static_cast<std::uint32_t>(_mm_movemask_pd(inside)) << (2 * m);
    }
    bits &= (1u << columns) - 1;
#else
    for (std::uint32_t di = 0; di < columns; ++di) {
      const bool inside = (edge_a[0] * di + row_c[0] >= 0.0) & (edge_a[1] * di + row_c[1] >= 0.0) &
                          (edge_a[2] * di + row_c[2] >= 0.0);
      bits |= std::uint32_t{inside} << di;
    }
#endif
    any |= bits;
    std::uint8_t* row = occupancy + std::size_t{j0 + dj} * grid.width + i0;
#if defined(__SSE2__)
    if (whole_rows) {
      const __m128i spread = _mm_set_epi64x(static_cast<long long>((bits >> 8) * 0x0101010101010101ull),
                                            static_cast<long long>((bits & 0xff) * 0x0101010101010101ull));
      const __m128i set = _mm_and_si128(_mm_cmpeq_epi8(_mm_and_si128(spread, bit_of_byte), bit_of_byte), one);
      auto* cells = reinterpret_cast<__m128i*>(row);
      _mm_storeu_si128(cells, _mm_or_si128(_mm_loadu_si128(cells), set));
      continue;
    }
#endif
    for (; bits != 0; bits &= bits - 1) row[std::countr_zero(bits)] = 1;
  }
  marked = any != 0;
  return true;
}

inline ProjectedCorner project(const ViewMapping& mapping, const float* p, bool with_depth) {
  ProjectedCorner c{};
  mapping.clip_xyw(p[0], p[1], p[2], c.cx, c.cy, c.cw);
  c.cz = with_depth ? mapping.clip_z(p[0], p[1], p[2]) : 0.0f;
  if (c.cw >= kMinClipW) {
    // Computed exactly as the vertex mapping does (float), so a vertex's own cell is always marked
    // by its triangles.
    const GridPoint g = mapping.to_grid(c.cx, c.cy, c.cw);
    c.gx = g.x, c.gy = g.y, c.ndc_z = c.cz / c.cw;
  }
  return c;
}

// Twice the signed area of a projected triangle, with the exact sign: in double the difference of
// two floats is exact (unless one is over 2^28 times the other) and so is the product of two such
// differences, so only the final subtraction rounds, and rounding keeps its sign.
inline double signed_area2(const ProjectedCorner& a, const ProjectedCorner& b, const ProjectedCorner& c) {
  return (double(b.gx) - a.gx) * (double(c.gy) - a.gy) - (double(b.gy) - a.gy) * (double(c.gx) - a.gx);
}

// The rasterisation loop over triangle_count triangles; corner(t, k) gives corner k of triangle t.
// cull_positive: skip triangles of positive signed area (see rasterize_occupancy_compact's closed).
template <class CornerOf>
std::size_t rasterize(const ViewMapping& mapping, std::size_t triangle_count, CornerOf&& corner,
                      std::span<std::uint8_t> occupancy, std::span<float> depth, bool cull_positive = false) {
  const GridSize grid = mapping.grid();
  assert(occupancy.size() == grid.cell_count());
  assert(depth.empty() || depth.size() == grid.cell_count());
  std::fill(occupancy.begin(), occupancy.end(), std::uint8_t{0});
  std::fill(depth.begin(), depth.end(), std::numeric_limits<float>::infinity());
  Rasterizer rasterizer(grid, occupancy, depth, mapping);
  const double width = grid.width, height = grid.height;
  const float width_f = static_cast<float>(grid.width), height_f = static_cast<float>(grid.height);
  std::size_t marking = 0;
  const bool with_depth = !depth.empty();
  for (std::size_t t = 0; t < triangle_count; ++t) {
    const ProjectedCorner& a = corner(t, 0);
    const ProjectedCorner& b = corner(t, 1);
    const ProjectedCorner& c = corner(t, 2);
    const bool all_front = a.cw >= kMinClipW && b.cw >= kMinClipW && c.cw >= kMinClipW;
    if (cull_positive && signed_area2(a, b, c) > 0.0) continue;
    if (all_front && !with_depth) {
      // Most triangles of an occupancy cut are about a cell in size: one inside a single cell of
      // the grid marks just that cell.
      const float x0 = std::min({a.gx, b.gx, c.gx}), x1 = std::max({a.gx, b.gx, c.gx});
      const float y0 = std::min({a.gy, b.gy, c.gy}), y1 = std::max({a.gy, b.gy, c.gy});
      if (x0 >= 0.0f && y0 >= 0.0f && x1 < width_f && y1 < height_f) {
        // Non-negative here, so truncation is floor.
        const auto i0 = static_cast<std::uint32_t>(x0), i1 = static_cast<std::uint32_t>(x1);
        const auto j0 = static_cast<std::uint32_t>(y0), j1 = static_cast<std::uint32_t>(y1);
        if (i0 == i1 && j0 == j1) {
          occupancy[grid.cell(i0, j0)] = 1;
          ++marking;
          continue;
        }
        bool marked = false;
        if (fill_small(a, b, c, i0, i1, j0, j1, grid, occupancy.data(), marked)) {
          marking += marked ? 1 : 0;
          continue;
        }
      }
    }
    Corner corners[4];
    int count = 3;
    if (all_front) {
      corners[0] = {a.gx, a.gy, a.ndc_z};
      corners[1] = {b.gx, b.gy, b.ndc_z};
      corners[2] = {c.gx, c.gy, c.ndc_z};
    } else {
      const std::array<ClipCorner, 3> clip = {ClipCorner{a.cx, a.cy, a.cz, a.cw},
                                              ClipCorner{b.cx, b.cy, b.cz, b.cw},
                                              ClipCorner{c.cx, c.cy, c.cz, c.cw}};
      std::array<ClipCorner, 4> front;
      count = clip_to_front(clip, front);
      if (count < 3) continue;  // entirely behind the camera
      // Clipped corners can be far off the grid: double precision.
      for (int k = 0; k < count; ++k) {
        const ClipCorner& f = front[k];
        corners[k] = {(f.x / f.w + 1.0) * 0.5 * width, (1.0 - f.y / f.w) * 0.5 * height, f.z / f.w};
      }
    }
    marking += rasterizer.fill(corners, count) ? 1 : 0;
  }
  return marking;
}

}  // namespace

std::size_t rasterize_occupancy(const ViewMapping& mapping, std::span<const float> positions,
                                std::span<const std::uint32_t> triangles, std::span<std::uint8_t> occupancy,
                                std::span<float> depth) {
  assert(triangles.size() % 3 == 0);
  const bool with_depth = !depth.empty();
  ProjectedCorner scratch[3];
  auto corner = [&](std::size_t t, int k) -> const ProjectedCorner& {
    const std::uint32_t v = triangles[3 * t + k];
    assert(3 * std::size_t{v} + 2 < positions.size());
    scratch[k] = project(mapping, positions.data() + 3 * std::size_t{v}, with_depth);
    return scratch[k];
  };
  return rasterize(mapping, triangles.size() / 3, corner, occupancy, depth);
}

std::size_t rasterize_occupancy_compact(const ViewMapping& mapping, std::span<const float> positions,
                                        std::span<const std::uint32_t> triangles,
                                        std::span<std::uint8_t> occupancy, std::span<float> depth,
                                        std::vector<ProjectedCorner>& scratch, bool closed) {
  assert(triangles.size() % 3 == 0 && positions.size() % 3 == 0);
  const bool with_depth = !depth.empty();
  const std::size_t n = positions.size() / 3;
  scratch.resize(n);
  ProjectedCorner* projected = scratch.data();
  bool all_in_front = true;
  for (std::size_t i = 0; i < n; ++i) {
    projected[i] = project(mapping, positions.data() + 3 * i, with_depth);
    all_in_front &= projected[i].cw >= kMinClipW;
  }
  auto corner = [&](std::size_t t, int k) -> const ProjectedCorner& {
    assert(triangles[3 * t + k] < n);
    return projected[triangles[3 * t + k]];
  };
  // A closed surface projected whole (no corner behind the camera, so no clipping) is a 2-cycle in
  // the plane: at any point off the edges the signed areas of the triangles covering it sum to
  // zero, so every point of a triangle of positive area lies in one of negative (or zero) area,
  // and, the cells being closed, every cell it meets is met by those. Depth needs the nearest
  // surface in each cell, so it rasterises everything.
  return rasterize(mapping, triangles.size() / 3, corner, occupancy, depth,
                   closed && all_in_front && !with_depth);
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

void visible_depth_bound(std::span<const float> depth, GridSize grid, std::span<float> out) {
  assert(depth.size() == grid.cell_count() && out.size() == grid.cell_count());
  constexpr float kOff = std::numeric_limits<float>::infinity();  // off the grid counts as background
  const std::size_t w = grid.width, h = grid.height;
  // Separable: the largest of three along each column into out (reading depth only), then along each
  // row in place, the overwritten left neighbour kept in a scalar. No scratch memory.
  for (std::size_t j = 0; j < h; ++j) {
    const float* d = depth.data() + j * w;
    const float* up = j > 0 ? d - w : nullptr;
    const float* down = j + 1 < h ? d + w : nullptr;
    float* o = out.data() + j * w;
    for (std::size_t i = 0; i < w; ++i) o[i] = std::max({up ? up[i] : kOff, d[i], down ? down[i] : kOff});
  }
  for (std::size_t j = 0; j < h; ++j) {
    float* o = out.data() + j * w;
    float left = kOff;
    for (std::size_t i = 0; i < w; ++i) {
      const float here = o[i];
      o[i] = std::max({left, here, i + 1 < w ? o[i + 1] : kOff});
      left = here;
    }
  }
}

}  // namespace mtlod::core::view

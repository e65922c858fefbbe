// Occupancy (core/ARCHITECTURE.md §1.2; JVRB 2006 §3.1's binary image): a cell is object if
// any projected triangle covers any part of it, background otherwise. Conservative rasterization: a
// triangle smaller than a cell still marks its cell. Per request this runs on a coarse cut of the MT
// (triangles about a cell in size), not on the full-resolution mesh.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/view/grid.hpp"
#include "core/view/view_grid.hpp"

namespace mtlod::core::view {

// Triangles whose corners have clip.w below this are clipped to the plane clip.w = kMinClipW, the
// numerical stand-in for "behind the camera" (clip.w ≤ 0) of the vertex mapping.
inline constexpr float kMinClipW = 1e-5f;

// Rasterizes triangles (three vertex ids each, into positions = x, y, z per vertex) into occupancy,
// grid.cell_count() bytes: 1 for object cells, 0 for background (the whole grid is overwritten).
// A cell (i, j) covers [i, i+1) × [j, j+1) in grid coordinates; a triangle marks every cell its closed
// projection meets, after clipping away the part behind the camera.
// depth: empty, or grid.cell_count() floats receiving per cell the nearest eye depth (−z_eye) of the
// triangles covering it (+inf for background); a triangle's depth in a cell is its plane at the cell
// centre, clamped to the triangle's depth range. Returns the number of triangles that marked a cell.
std::size_t rasterize_occupancy(const ViewMapping& mapping, std::span<const float> positions,
                                std::span<const std::uint32_t> triangles, std::span<std::uint8_t> occupancy,
                                std::span<float> depth = {});

// A vertex as the rasteriser sees it: clip coordinates (float, as the vertex mapping computes them)
// and, in front of the camera, its grid point and ndc depth.
struct ProjectedCorner {
  float cx, cy, cz, cw;
  float gx, gy, ndc_z;
};

// The same occupancy as rasterize_occupancy, but every vertex of `positions` is projected once, into
// `scratch`, instead of once per triangle using it: for a compact mesh whose vertices are all used
// (OccupancyLevel stores its cut this way, its positions copied out of the model so that they are
// read in order rather than gathered from all over it).
// closed: `triangles` form a closed surface, every directed edge (a, b) appearing as often as
// (b, a) (is_closed_surface). Then, when every vertex is in front of the camera and no depth is
// asked for, the triangles facing one way are skipped: the others meet every cell they meet. The
// return value then counts only the triangles rasterised.
std::size_t rasterize_occupancy_compact(const ViewMapping& mapping, std::span<const float> positions,
                                        std::span<const std::uint32_t> triangles,
                                        std::span<std::uint8_t> occupancy, std::span<float> depth,
                                        std::vector<ProjectedCorner>& scratch, bool closed = false);

// Internal silhouettes (core/ARCHITECTURE.md §1.2): for every pair of 4-neighbour object cells whose depths
// differ by more than relative_jump times the nearer one, sets the farther cell of image to 0, so that a
// distance transform of image seeds there too. image is usually a copy of the occupancy; depth comes
// from rasterize_occupancy. Returns the number of cells newly set to 0.
std::size_t mark_depth_discontinuities(std::span<const float> depth, GridSize grid, float relative_jump,
                                       std::span<std::uint8_t> image);

// Hidden-surface coarsening (AllowedErrorInputs::visible_depth): out[c] = the largest depth of cell c
// and its 8 neighbours, +inf where any of them is background or off the grid. A point behind this
// bound lies behind the visible surface wherever in the cell it projects: a cell that a nearer
// surface covers only in part (conservative rasterisation marks it whole) still has a neighbour that
// shows the farther one, and the model's outline keeps every point near it visible.
void visible_depth_bound(std::span<const float> depth, GridSize grid, std::span<float> out);

}  // namespace mtlod::core::view

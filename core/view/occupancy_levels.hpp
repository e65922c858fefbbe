// Precomputed coarse cuts of an MT for the occupancy stage (core/ARCHITECTURE.md §1.2): not
// the full-resolution mesh per request, but a cut whose triangles are about a cell in size. A few cuts of
// growing size are built once per model; a request rasterises the coarsest one with a triangle per four
// covered grid cells, so the occupancy costs a rasterisation, not a refinement. Measured on the dragon at
// 256² (tests/bench/BENCHMARKS.md, "Grid stages", BM_OccupancyFromMtCut256): the 16k level a request takes
// there moves 16 % of the silhouette labels, none by more than a pixel, against the full 871k mesh; the 8k
// level 38 %, none by more; the 4k one 18 % by more.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "core/model/mt.hpp"
#include "core/result.hpp"

namespace mtlod::core::view {

// One coarse cut as a compact mesh for rasterize_occupancy_compact: the positions of its vertices
// (copied from the model, in first-use order, so a request reads them in order instead of gathering
// them from all over the model), its triangles as indices into them, and their model vertex ids.
// Its holes are capped (cap_holes), so that the surface is closed and a request rasterises only
// the triangles facing one way (rasterize_occupancy_compact's `closed`); cap triangles are not part
// of the cut, and cover only cells the cut's own triangles cover from most viewpoints (they close a
// scan's holes; tests/bench/BENCHMARKS.md, "Grid stages", measures the labels against the full mesh).
struct OccupancyLevel {
  std::vector<float> positions;
  std::vector<std::uint32_t> triangles;  // 3 indices into positions per triangle: the cut's, then caps
  std::vector<std::uint32_t> model_ids;  // per vertex: its id in the model
  std::size_t cap_triangles = 0;         // the last ones of `triangles`
  bool closed = false;                   // is_closed_surface(triangles)

  std::size_t triangle_count() const { return triangles.size() / 3 - cap_triangles; }
  // The cut's own triangles, without the caps.
  std::span<const std::uint32_t> cut_triangles() const { return {triangles.data(), 3 * triangle_count()}; }
};

// Whether every directed edge (a, b) of `triangles` (3 vertex ids each) appears as often as (b, a):
// a closed surface, whose triangles facing one way cover the projection of all of them.
bool is_closed_surface(std::span<const std::uint32_t> triangles);
// Caps the holes of a surface: every loop of boundary edges (an edge walked more often one way than
// the other, once per surplus) gets a fan of triangles holding the reversed edges, a loop that
// passes a vertex twice being split there. Afterwards every edge is walked as often both ways
// (is_closed_surface). Returns how many triangles it appended.
std::size_t cap_holes(std::vector<std::uint32_t>& triangles);

class OccupancyLevels {
 public:
  // Cuts with at most 512, 1k, 2k, ... 256k triangles (worst error first; the root when it is
  // larger), stopping early at the full-resolution mesh: at most twice the largest level in all. The
  // small ones serve models that cover few cells, as most instances of a scene do. Fails (kCorrupt)
  // when they reach a block of a mapped file that fails its check.
  static Result<std::unique_ptr<OccupancyLevels>> make(const model::Mt& mt);

  // The coarsest level with at least covered_cells / 4 triangles (the finest when none has as many).
  const OccupancyLevel& for_covered_cells(double covered_cells) const;
  std::span<const OccupancyLevel> levels() const { return levels_; }
  std::size_t memory_bytes() const;

 private:
  OccupancyLevels() = default;
  std::vector<OccupancyLevel> levels_;  // coarse to fine
};

}  // namespace mtlod::core::view

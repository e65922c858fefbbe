// Precomputed coarse cuts of a Multi-Tessellation for the occupancy stage (DESIGN.md §1.2; issue:
// "not from the full-resolution mesh per request: use a cut whose triangles are about a cell in
// size"). A few cuts of growing size are built once per model; a request rasterises the coarsest
// one whose error is below one grid cell, so the occupancy costs a rasterisation, not a refinement.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/mt.hpp"

namespace mtlod::core {

struct OccupancyLevel {
  float max_error = 0;                   // largest triangle error of the cut, model units
  std::vector<std::uint32_t> triangles;  // 3 vertex ids per triangle
};

class OccupancyLevels {
 public:
  // Cuts with at most 2k, 8k, 32k, 128k and 512k triangles (worst error first), stopping early at
  // the full-resolution mesh.
  explicit OccupancyLevels(const Mt& mt);

  // The coarsest level whose max_error ≤ error, or the finest level when none is that fine.
  const OccupancyLevel& for_error(float error) const;
  std::span<const OccupancyLevel> levels() const { return levels_; }
  std::size_t memory_bytes() const;

 private:
  std::vector<OccupancyLevel> levels_;  // coarse to fine
};

}  // namespace mtlod::core

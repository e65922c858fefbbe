// The view's W×H grid (core/ARCHITECTURE.md §1.1): its size, the "no cell" sentinel and the
// row-major cell numbering shared by the view mapping, occupancy, distance transforms and labels.
#pragma once

#include <cstddef>
#include <cstdint>

namespace mtlod::core::view {

// Requests may ask for any grid up to this many cells per side; the 16-bit chamfer transforms rely on
// it (the largest 5-7-11 distance on a 4096² grid is 4095·7 = 28665 < kChamferUnreached).
inline constexpr std::uint32_t kMaxGridSide = 4096;

// A vertex behind the camera or outside the grid has no cell.
inline constexpr std::uint32_t kNoCell = 0xFFFFFFFFu;

struct GridSize {
  std::uint32_t width = 0;   // cells per row (i runs 0..width-1, left to right)
  std::uint32_t height = 0;  // rows (j runs 0..height-1, top to bottom)

  std::size_t cell_count() const { return std::size_t{width} * height; }
  bool valid() const { return width >= 1 && height >= 1 && width <= kMaxGridSide && height <= kMaxGridSide; }
  // Row-major id of cell (i, j); both must be in range.
  std::uint32_t cell(std::uint32_t i, std::uint32_t j) const { return j * width + i; }
};

// The cells [x0, x1) × [y0, y1) of a grid.
struct CellRect {
  std::uint32_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  bool empty() const { return x0 >= x1 || y0 >= y1; }
  std::uint32_t width() const { return x1 - x0; }
  std::uint32_t height() const { return y1 - y0; }
};

}  // namespace mtlod::core::view

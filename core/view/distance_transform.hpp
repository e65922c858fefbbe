// Grid distance transforms (core/ARCHITECTURE.md §1.3). The papers' transform is the two-pass
// chamfer with the 5×5 mask of weights 5 (edge), 7 (diagonal) and 11 (knight): Algorithm 1 and Table 1
// of JVRB 2006 (papers/000), also used from a focus in DGCI 2006 (papers/002). The 3-4 chamfer, city
// block, chessboard and exact Euclidean transforms are options beside it.
//
// Convention for every transform here: the input is a byte image over the grid, and its ZERO cells
// are the seeds (distance 0). In silhouette mode the image is the occupancy itself (background = 0,
// object ≠ 0), exactly the papers' binary image; focus mode seeds the focus cells instead.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "core/view/grid.hpp"

namespace mtlod::core::view {

enum class DistanceMetric : std::uint8_t {
  kChamfer5711,  // the papers' mask; 5 units per pixel step
  kChamfer34,    // 3 units per pixel step, 4 per diagonal
  kCityBlock,    // 4-neighbour steps of 1
  kChessboard,   // 8-neighbour steps of 1
  kEuclidean,    // exact; raw values are squared distances in cells²
};
inline constexpr std::size_t kDistanceMetricCount = 5;

// One move of a chamfer mask: the neighbour at (x + dx, y + dy) offers its value + weight.
struct ChamferStep {
  std::int8_t dx;
  std::int8_t dy;
  std::uint16_t weight;
};

// The forward halves of the masks (Table 1's bold weights for 5-7-11): the neighbours visited before
// a cell in a top-to-bottom, left-to-right scan. The backward halves are the same steps negated. The
// last step of every table is the in-row neighbour (−1, 0).
// clang-format off
inline constexpr std::array<ChamferStep, 8> kChamfer5711Forward{{
                  {-1, -2, 11},             {1, -2, 11},                   // knights, two rows up
    {-2, -1, 11}, {-1, -1, 7},  {0, -1, 5}, {1, -1, 7},  {2, -1, 11},      // the row above
                  {-1,  0, 5},                                             // the left neighbour
}};
inline constexpr std::array<ChamferStep, 4> kChamfer34Forward{{
    {-1, -1, 4}, {0, -1, 3}, {1, -1, 4},
    {-1,  0, 3},
}};
inline constexpr std::array<ChamferStep, 2> kCityBlockForward{{
                 {0, -1, 1},
    {-1,  0, 1},
}};
inline constexpr std::array<ChamferStep, 4> kChessboardForward{{
    {-1, -1, 1}, {0, -1, 1}, {1, -1, 1},
    {-1,  0, 1},
}};
// clang-format on

// Value of a chamfer cell that no seed reaches (an image without zero cells). Every real distance on
// a grid of at most kMaxGridSide² cells is smaller (5-7-11: at most 4095·7 = 28665).
inline constexpr std::uint16_t kChamferUnreached = 0x7FFF;
// Value of a Euclidean cell that no seed reaches.
inline constexpr std::uint32_t kEuclideanUnreached = 0xFFFFFFFFu;

// Raw units per pixel step along a row: 5, 3, 1, 1, and 1 for the Euclidean transform, whose raw
// value is a squared distance (see distance_px).
std::uint32_t units_per_pixel(DistanceMetric metric);
// A raw transform value in pixels (cells): raw / units_per_pixel, or sqrt(raw) for kEuclidean.
float distance_px(std::uint32_t raw, DistanceMetric metric);
// The largest raw value whose distance is ≤ threshold_px pixels (threshold_px ≥ 0), so "label ≤ d
// pixels" becomes the integer test raw ≤ raw_threshold(d): floor(5·d) for 5-7-11, floor(d²) for kEuclidean.
std::uint32_t raw_threshold(float threshold_px, DistanceMetric metric);

// One-off transforms. image and out hold grid.cell_count() cells, row-major; grid.valid() holds.
// out[c] = mask distance from c to the nearest zero cell of image (kChamferUnreached if none).
void chamfer_5_7_11(std::span<const std::uint8_t> image, GridSize grid, std::span<std::uint16_t> out);
void chamfer_3_4(std::span<const std::uint8_t> image, GridSize grid, std::span<std::uint16_t> out);
void city_block(std::span<const std::uint8_t> image, GridSize grid, std::span<std::uint16_t> out);
void chessboard(std::span<const std::uint8_t> image, GridSize grid, std::span<std::uint16_t> out);
// out[c] = exact squared Euclidean distance (in cells²) from c to the nearest zero cell of image, or
// kEuclideanUnreached if none (Meijster, Roerdink and Hesselink's two-phase algorithm, 2000).
void euclidean_squared(std::span<const std::uint8_t> image, GridSize grid, std::span<std::uint32_t> out);

// The per-worker object: same results as the one-off functions, but keeps its padded scratch
// buffers between requests, so after the first request of a given grid size nothing is allocated.
class DistanceTransformer {
 public:
  // Chamfer transform (metric must not be kEuclidean) seeded by the zero cells of image.
  void chamfer(DistanceMetric metric, std::span<const std::uint8_t> image, GridSize grid,
               std::span<std::uint16_t> out);
  // Chamfer transform seeded by a list of cells (focus mode: one or several foci; kNoCell entries
  // are skipped). With no seed every cell is kChamferUnreached.
  void chamfer_from_cells(DistanceMetric metric, std::span<const std::uint32_t> seed_cells, GridSize grid,
                          std::span<std::uint16_t> out);
  void euclidean_squared(std::span<const std::uint8_t> image, GridSize grid, std::span<std::uint32_t> out);
  void euclidean_squared_from_cells(std::span<const std::uint32_t> seed_cells, GridSize grid,
                                    std::span<std::uint32_t> out);

  // Labels of any metric as the allowed-error laws read them: the chamfer transform of `metric`, or
  // for kEuclidean the exact distance in fifths of a pixel (the 5-per-pixel scale of the papers'
  // labels, read as 5-7-11 units; fits 16 bits on grids up to 4096²). Seeded by the zero cells of
  // image, or by a list of cells.
  void labels(DistanceMetric metric, std::span<const std::uint8_t> image, GridSize grid,
              std::span<std::uint16_t> out);
  void labels_from_cells(DistanceMetric metric, std::span<const std::uint32_t> seed_cells, GridSize grid,
                         std::span<std::uint16_t> out);
  // The same computed over a rectangle of the grid (not empty) that holds every seed: its cells get
  // the labels the whole grid's transform gives them (a shortest path of mask moves between two cells
  // stays in their bounding box, as does the straight line), every other cell kChamferUnreached. A
  // focus whose law ends within a few dozen cells costs that square instead of the grid.
  void labels_from_cells_within(DistanceMetric metric, std::span<const std::uint32_t> seed_cells,
                                GridSize grid, CellRect rect, std::span<std::uint16_t> out);

  // Runs the chamfer passes cell by cell (the portable code used without SSE2) instead of 8 cells at
  // a time. Same results; for tests and comparisons.
  void set_scalar(bool scalar) { scalar_ = scalar; }

  // Constrained chamfer (core/ARCHITECTURE.md §1.3): distance from the seeds along paths of mask
  // moves whose cells are all passable (passable[c] ≠ 0, e.g. the occupancy, so a focus's distance
  // spreads only over the object). Seed cells count as passable. Cells no such path reaches are
  // kChamferUnreached. The two passes repeat until a round changes nothing or max_rounds rounds ran;
  // returns the rounds run (a path that turns back against the scan order needs one more round).
  // metric must not be kEuclidean.
  std::size_t chamfer_constrained(DistanceMetric metric, std::span<const std::uint32_t> seed_cells,
                                  std::span<const std::uint8_t> passable, GridSize grid,
                                  std::span<std::uint16_t> out, std::size_t max_rounds = 256);

 private:
  void prepare_padded(GridSize grid);
  void run_chamfer(DistanceMetric metric, GridSize grid, std::span<std::uint16_t> out);
  void run_euclidean(GridSize grid, std::span<std::uint32_t> out);

 public:
  // Bytes of scratch memory held.
  std::size_t memory_bytes() const {
    return padded_.capacity() * 2 + passable_.capacity() + (column_.capacity() + rect_out_.capacity()) * 2 +
           (envelope_.capacity() + squared_.capacity() + rect_seeds_.capacity()) * 4;
  }

 private:
  std::vector<std::uint16_t> padded_;      // chamfer grid with 2 cells of +inf on every side
  std::size_t stride_ = 0;                 // padded row length
  bool scalar_ = false;                    // set_scalar
  std::vector<std::uint8_t> passable_;     // chamfer_constrained: padded passable mask (padding blocked)
  std::vector<std::uint16_t> column_;      // Euclidean phase 1: distance to the nearest seed in the column
  std::vector<std::uint32_t> envelope_;    // Euclidean phase 2: s and t of the lower envelope
  std::vector<std::uint32_t> squared_;     // labels(): the Euclidean transform before rounding
  std::vector<std::uint32_t> rect_seeds_;  // labels_from_cells_within: the seeds in the rectangle's cells
  std::vector<std::uint16_t> rect_out_;    // labels_from_cells_within: the rectangle's labels
};

}  // namespace mtlod::core::view

// Backprojection (core/ARCHITECTURE.md §1.4). Labels hold at every level of detail because an MT's
// vertices are a subset of the original ones, so they are computed once per request on the
// original vertices and read by any cut.
#include "core/view/labels.hpp"

#include <algorithm>
#include <cassert>

namespace mtlod::core::view {

namespace {

template <class DtValue>
void label_all(std::span<const std::uint32_t> vertex_cells, std::span<const DtValue> dt,
               std::span<std::uint32_t> vertex_labels) {
  assert(vertex_cells.size() == vertex_labels.size());
  for (std::size_t v = 0; v < vertex_cells.size(); ++v) vertex_labels[v] = cell_label(dt, vertex_cells[v]);
}

}  // namespace

void label_vertices(std::span<const std::uint32_t> vertex_cells, std::span<const std::uint16_t> dt,
                    std::span<std::uint32_t> vertex_labels) {
  label_all(vertex_cells, dt, vertex_labels);
}

void label_vertices(std::span<const std::uint32_t> vertex_cells, std::span<const std::uint32_t> dt,
                    std::span<std::uint32_t> vertex_labels) {
  label_all(vertex_cells, dt, vertex_labels);
}

void label_triangles(std::span<const std::uint32_t> triangles, std::span<const std::uint32_t> vertex_labels,
                     std::span<std::uint32_t> triangle_labels) {
  assert(triangles.size() % 3 == 0 && triangle_labels.size() == triangles.size() / 3);
  for (std::size_t t = 0; t < triangle_labels.size(); ++t) {
    triangle_labels[t] = std::min({vertex_labels[triangles[3 * t]], vertex_labels[triangles[3 * t + 1]],
                                   vertex_labels[triangles[3 * t + 2]]});
  }
}

std::size_t region_triangles(std::span<const std::uint32_t> triangle_labels, std::uint32_t threshold_raw,
                             std::span<std::uint8_t> in_region) {
  assert(in_region.size() == triangle_labels.size());
  // The sentinels are above every raw threshold a request can give (≤ 4096² for Euclidean).
  std::size_t count = 0;
  for (std::size_t t = 0; t < triangle_labels.size(); ++t) {
    in_region[t] = triangle_labels[t] <= threshold_raw && triangle_labels[t] < kLabelUnreached ? 1 : 0;
    count += in_region[t];
  }
  return count;
}

}  // namespace mtlod::core::view

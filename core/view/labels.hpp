// Label backprojection (core/ARCHITECTURE.md §1.4; JVRB 2006 §3.3, DGCI 2006 §3): a vertex's label
// is the distance-transform value of its cell, a triangle's label the minimum over its vertices ("the
// minimum distance of the vertices of a face"). Labels are raw transform units (5 per pixel step for
// 5-7-11, squared cells for the Euclidean transform); distance_px converts them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "core/view/distance_transform.hpp"
#include "core/view/grid.hpp"
#include "core/view/view_grid.hpp"

namespace mtlod::core::view {

// Label of a vertex without a cell (behind the camera or off the grid). The largest value, so a
// triangle with at least one vertex in view takes that vertex's label.
inline constexpr std::uint32_t kLabelNoCell = 0xFFFFFFFFu;
// Label of a vertex whose cell no seed reaches (e.g. silhouette mode on an all-object grid).
inline constexpr std::uint32_t kLabelUnreached = 0xFFFFFFFEu;

// Label of one cell of a chamfer grid (kChamferUnreached becomes kLabelUnreached) or a Euclidean grid.
inline std::uint32_t cell_label(std::span<const std::uint16_t> dt, std::uint32_t cell) {
  if (cell == kNoCell) return kLabelNoCell;
  const std::uint16_t raw = dt[cell];
  return raw == kChamferUnreached ? kLabelUnreached : raw;
}
inline std::uint32_t cell_label(std::span<const std::uint32_t> dt, std::uint32_t cell) {
  if (cell == kNoCell) return kLabelNoCell;
  const std::uint32_t raw = dt[cell];
  return raw == kEuclideanUnreached ? kLabelUnreached : raw;
}

// vertex_labels[v] = label of vertex_cells[v] in dt (a W×H transform); both spans have one entry per
// vertex. vertex_cells comes from map_vertices.
void label_vertices(std::span<const std::uint32_t> vertex_cells, std::span<const std::uint16_t> dt,
                    std::span<std::uint32_t> vertex_labels);
void label_vertices(std::span<const std::uint32_t> vertex_cells, std::span<const std::uint32_t> dt,
                    std::span<std::uint32_t> vertex_labels);

// Lazy labelling of a single vertex: projects it and reads its cell. For refinements that touch few
// of the model's vertices. positions holds x, y, z per vertex.
template <class DtValue>
std::uint32_t vertex_label(const ViewMapping& mapping, std::span<const float> positions, std::uint32_t vertex,
                           std::span<const DtValue> dt) {
  const float* p = positions.data() + 3 * std::size_t{vertex};
  return cell_label(dt, mapping.map_point(p[0], p[1], p[2]));
}

// triangle_labels[t] = min of the labels of triangle t's three vertices. triangles holds three vertex
// ids per triangle; triangle_labels has triangles.size()/3 entries.
void label_triangles(std::span<const std::uint32_t> triangles, std::span<const std::uint32_t> vertex_labels,
                     std::span<std::uint32_t> triangle_labels);

// Region (core/ARCHITECTURE.md §1.5): in_region[t] = 1 if triangle_labels[t] ≤ threshold_raw, else 0.
// threshold_raw is in raw units; raw_threshold(d_px, metric) converts a threshold in pixels.
// Returns the number of triangles in the region.
std::size_t region_triangles(std::span<const std::uint32_t> triangle_labels, std::uint32_t threshold_raw,
                             std::span<std::uint8_t> in_region);

}  // namespace mtlod::core::view

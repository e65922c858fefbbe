// Accessors of the in-memory Multi-Tessellation (core/ARCHITECTURE.md §2).
#include "core/model/mt.hpp"

#include <algorithm>
#include <cassert>

namespace mtlod::core::model {

Mt::Mt(MtArrays arrays) {
  auto owned = std::make_shared<const MtArrays>(std::move(arrays));
  const MtArrays& a = *owned;
  positions = a.positions;
  normals = a.normals;
  colors = a.colors;
  node_vertex = a.node_vertex;
  node_error = a.node_error;
  node_triangle_offsets = a.node_triangle_offsets;
  node_parent_offsets = a.node_parent_offsets;
  node_parents = a.node_parents;
  triangle_corners = a.triangle_corners;
  root_first_corner = a.root_first_corner;
  triangle_remover = a.triangle_remover;
  bounds = bounds_of(positions);
  input_triangles = std::uint32_t(std::count(triangle_remover.begin(), triangle_remover.end(), kNoNode));
  storage_ = std::move(owned);
}

MtArrays Mt::arrays() const {
  auto copy = [](auto span) {
    return std::vector<typename decltype(span)::value_type>(span.begin(), span.end());
  };
  MtArrays a;
  a.positions = copy(positions);
  a.normals = copy(normals);
  a.colors = copy(colors);
  a.node_vertex = copy(node_vertex);
  a.node_error = copy(node_error);
  a.node_triangle_offsets = copy(node_triangle_offsets);
  a.node_parent_offsets = copy(node_parent_offsets);
  a.node_parents = copy(node_parents);
  a.triangle_corners = copy(triangle_corners);
  a.root_first_corner = copy(root_first_corner);
  a.triangle_remover = copy(triangle_remover);
  return a;
}

std::uint32_t Mt::triangle_creator(std::uint32_t t) const {
  assert(t < triangle_count());
  // The first offset greater than t ends the creator's range.
  const auto it = std::upper_bound(node_triangle_offsets.begin(), node_triangle_offsets.end(), t);
  return static_cast<std::uint32_t>(it - node_triangle_offsets.begin()) - 1;
}

void Mt::triangle_vertices(std::uint32_t t, std::uint32_t out[3]) const {
  const std::uint32_t n = triangle_creator(t);
  out[0] = first_corner(TriangleId{t}, NodeId{n});
  out[1] = triangle_corners[2 * std::size_t{t}];
  out[2] = triangle_corners[2 * std::size_t{t} + 1];
}

bool Mt::vertices_in_node_order() const {
  if (mapped()) return true;  // format 2 requires it, and each block is checked for it
  for (std::size_t n = 2; n < node_count(); ++n)
    if (node_vertex[n] != node_vertex[n - 1] + 1) return false;
  return true;
}

std::size_t Mt::array_bytes() const {
  auto bytes = [](const auto& v) { return v.size() * sizeof(v[0]); };
  return bytes(positions) + bytes(normals) + bytes(colors) + bytes(node_vertex) + bytes(node_error) +
         bytes(node_triangle_offsets) + bytes(node_parent_offsets) + bytes(node_parents) +
         bytes(triangle_corners) + bytes(root_first_corner) + bytes(triangle_remover);
}

}  // namespace mtlod::core::model

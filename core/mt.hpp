// The in-memory Multi-Tessellation (DESIGN.md §2): nodes in topological order (node 0 = root, which
// creates the coarsest mesh), triangles grouped by creating node, per-triangle remover, DAG arcs in
// CSR. Struct-of-arrays with 32-bit ids, as stored in the .mt file (core/FORMAT.md).
//
// Compact storage (≈ 57 bytes per input triangle on real scans):
// - every node n ≥ 1 undoes one half-edge collapse u→v, so all triangles it creates contain its split
//   vertex u = node_vertex[n]; a triangle stores only its two other corners, in counter-clockwise
//   order after u. Root triangles keep their first corner in root_first_corner.
// - all triangles a node removes were created by the same collapse and share one error, so errors are
//   per node: error(t) = node_error[triangle_remover[t]], and 0 for triangles of the input (never
//   removed).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace mtlod::core {

inline constexpr std::uint32_t kNoNode = std::numeric_limits<std::uint32_t>::max();
// "None" for a vertex or a face index (the same value: ids of each kind stay below it).
inline constexpr std::uint32_t kNoVertex = std::numeric_limits<std::uint32_t>::max();
inline constexpr std::uint32_t kNoFace = std::numeric_limits<std::uint32_t>::max();

// Distinct id types where node, triangle and vertex ids meet in one signature.
struct NodeId {
  std::uint32_t value = 0;
};
struct TriangleId {
  std::uint32_t value = 0;
};

struct Mt {
  // Vertices: every vertex of the input. build_mt numbers them as the nodes reach them (the root
  // mesh's R vertices first, then node n's split vertex as R + n − 1, then any vertex no triangle
  // uses) and reports each input vertex's id; nothing here relies on that order (FORMAT.md).
  std::vector<float> positions;      // x, y, z per vertex
  std::vector<float> normals;        // empty, or x, y, z per vertex
  std::vector<std::uint8_t> colors;  // empty, or r, g, b per vertex

  // Nodes (node_count() of them), topological order: every parent has a smaller id.
  std::vector<std::uint32_t> node_vertex;            // split vertex of node n ≥ 1; kNoVertex for the root
  std::vector<float> node_error;                     // error of the triangles node n removes (model units)
  std::vector<std::uint32_t> node_triangle_offsets;  // node_count()+1: node n creates [off[n], off[n+1])
  std::vector<std::uint32_t> node_parent_offsets;    // node_count()+1, CSR into node_parents
  std::vector<std::uint32_t> node_parents;           // distinct creators of the triangles node n removes

  // Triangles (triangle_count() of them), grouped by creating node.
  std::vector<std::uint32_t> triangle_corners;   // 2 per triangle: corners after the first, CCW
  std::vector<std::uint32_t> root_first_corner;  // first corner of each root triangle
  std::vector<std::uint32_t> triangle_remover;   // node that removes it, or kNoNode

  std::size_t vertex_count() const { return positions.size() / 3; }
  std::size_t node_count() const { return node_vertex.size(); }
  std::size_t triangle_count() const { return triangle_remover.size(); }
  std::size_t root_triangle_count() const { return root_first_corner.size(); }
  bool has_normals() const { return !normals.empty(); }
  bool has_colors() const { return !colors.empty(); }

  // Error of triangle t in model units: its remover's error, or 0 for an input triangle.
  float triangle_error(std::uint32_t t) const {
    const std::uint32_t r = triangle_remover[t];
    return r == kNoNode ? 0.0f : node_error[r];
  }
  // First corner of triangle t created by node n (n must be t's creator).
  std::uint32_t first_corner(TriangleId t, NodeId n) const {
    return n.value == 0 ? root_first_corner[t.value] : node_vertex[n.value];
  }
  // Node that creates triangle t (binary search over node_triangle_offsets, O(log nodes)).
  std::uint32_t triangle_creator(std::uint32_t t) const;
  // Writes the three vertex ids of triangle t (counter-clockwise) to out.
  void triangle_vertices(std::uint32_t t, std::uint32_t out[3]) const;

  // Bytes held by all arrays (sizes, not capacities): the loaded footprint.
  std::size_t memory_bytes() const;
  // Whether the split vertices are numbered in node order (node n + 1's is node n's plus one), as
  // build_mt numbers them; files written before it did are valid but refine more slowly.
  bool vertices_in_node_order() const;
};

}  // namespace mtlod::core

// Topology analysis and clean-up of raw scanned meshes.
// Every fix is counted and reported, never done silently: real scans (see the shared meshes'
// README) carry unused vertices, duplicate positions, holes and non-manifold edges.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

#include "core/model/mesh.hpp"

namespace mtlod::core::model {

// Counts over a triangle soup, taken as given (no welding). Edges are undirected vertex-id pairs.
struct TopologyReport {
  std::size_t vertices = 0;
  std::size_t triangles = 0;
  std::size_t unused_vertices = 0;       // referenced by no triangle
  std::size_t duplicate_positions = 0;   // vertices whose exact position an earlier vertex has
  std::size_t degenerate_triangles = 0;  // a repeated vertex id, or zero area
  std::size_t duplicate_triangles = 0;   // same vertex set as an earlier triangle
  std::size_t edges = 0;
  std::size_t boundary_edges = 0;         // used by exactly one triangle
  std::size_t non_manifold_edges = 0;     // used by more than two triangles
  std::size_t inconsistent_edges = 0;     // two triangles walk the edge in the same direction
  std::size_t non_manifold_vertices = 0;  // whose triangle fan is not a single disk or half-disk
  std::size_t boundary_loops = 0;         // closed chains of boundary edges (manifold boundary only)
  std::size_t components = 0;             // triangles connected through shared vertex ids
  std::int64_t euler_characteristic = 0;  // V - E + F over used vertices

  bool is_closed_manifold() const {
    return boundary_edges == 0 && non_manifold_edges == 0 && inconsistent_edges == 0 &&
           non_manifold_vertices == 0 && degenerate_triangles == 0;
  }
  // One line per non-zero defect, for tool summaries.
  std::string summary() const;
};

// positions: x,y,z per vertex; triangles: three ids per triangle, each < positions.size()/3.
TopologyReport analyze_topology(std::span<const float> positions, std::span<const std::uint32_t> triangles);

// Whether triangle t (three ids into positions) is degenerate as clean_mesh drops it: a repeated
// vertex id, or zero area in double precision.
bool is_degenerate_triangle(std::span<const float> positions, const std::uint32_t* t);

struct CleanupOptions {
  bool weld_duplicate_positions = false;  // on for STL, which stores every corner separately
  bool drop_degenerate_triangles = true;  // repeated vertex id or zero area
  bool drop_duplicate_triangles = true;   // same vertex set as an earlier triangle
  bool drop_unused_vertices = true;       // compacts vertex ids, keeping their order
};

struct CleanupSummary {
  std::size_t welded_vertices = 0;
  std::size_t dropped_degenerate_triangles = 0;
  std::size_t dropped_duplicate_triangles = 0;
  std::size_t dropped_unused_vertices = 0;
  bool changed() const {
    return welded_vertices + dropped_degenerate_triangles + dropped_duplicate_triangles +
               dropped_unused_vertices !=
           0;
  }
  std::string summary() const;
};

// Applies the enabled fixes in place, in the order above. Normals and colours follow their vertices.
CleanupSummary clean_mesh(Mesh& mesh, const CleanupOptions& options = {});

}  // namespace mtlod::core::model

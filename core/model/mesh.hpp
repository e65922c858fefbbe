// The indexed triangle mesh every stage of mtlod exchanges: struct-of-arrays, float32 positions,
// optional per-vertex normals and colours, uint32 triangles.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace mtlod::core::model {

struct Mesh {
  std::vector<float> positions;          // x, y, z per vertex
  std::vector<float> normals;            // empty, or x, y, z per vertex
  std::vector<std::uint8_t> colors;      // empty, or r, g, b per vertex
  std::vector<std::uint32_t> triangles;  // three vertex ids per triangle, counter-clockwise

  std::size_t vertex_count() const { return positions.size() / 3; }
  std::size_t triangle_count() const { return triangles.size() / 3; }
  bool has_normals() const { return !normals.empty(); }
  bool has_colors() const { return !colors.empty(); }
};

}  // namespace mtlod::core::model

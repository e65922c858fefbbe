// Axis-aligned bounding box of xyz position triples (the layout of Mesh::positions and
// Mt::positions).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>

namespace mtlod::core::model {

struct Bounds {
  std::array<float, 3> lo{INFINITY, INFINITY, INFINITY};
  std::array<float, 3> hi{-INFINITY, -INFINITY, -INFINITY};

  bool empty() const { return !(lo[0] <= hi[0]); }
  void add(const float* p) {
    for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], p[c]), hi[c] = std::max(hi[c], p[c]);
  }
  std::array<float, 3> centre() const {
    return {0.5f * (lo[0] + hi[0]), 0.5f * (lo[1] + hi[1]), 0.5f * (lo[2] + hi[2])};
  }
  float largest_side() const { return std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]}); }
  float diagonal() const {
    float sum = 0;
    for (int c = 0; c < 3; ++c) sum += (hi[c] - lo[c]) * (hi[c] - lo[c]);
    return std::sqrt(sum);
  }
  float radius() const { return 0.5f * diagonal(); }  // of the sphere around the box
};

// A corner in double, for the interfaces that take std::array<double, 3>.
inline std::array<double, 3> to_double(const std::array<float, 3>& p) {
  return {p[0], p[1], p[2]};
}

// Of every vertex.
inline Bounds bounds_of(std::span<const float> positions) {
  Bounds b;
  for (std::size_t v = 0; v + 3 <= positions.size(); v += 3) b.add(&positions[v]);
  return b;
}

// Of the vertices the triangles use (ids must be in range).
inline Bounds bounds_of(std::span<const float> positions, std::span<const std::uint32_t> triangles) {
  Bounds b;
  for (const std::uint32_t v : triangles) b.add(&positions[3 * std::size_t{v}]);
  return b;
}

}  // namespace mtlod::core::model

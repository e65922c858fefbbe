// Comparing a decoded (quantized, reordered) mesh with the cut it came from: decoded vertices are
// matched to the nearest model vertex through a hashed grid, triangles compared as id triples.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "core/model/bounds.hpp"

namespace mtlod::test {

// For each decoded vertex, the id (among `candidates`) of the nearest model vertex by max-norm;
// fails the test when that distance exceeds `tolerance`. `cell` should be a few tolerances.
inline std::vector<std::uint32_t> match_vertices(std::span<const float> decoded, std::span<const float> model,
                                                 std::span<const std::uint32_t> candidates, float cell,
                                                 float tolerance) {
  auto key = [cell](const float* p) {
    std::array<long, 3> k;
    for (int c = 0; c < 3; ++c) k[c] = std::lround(std::floor(p[c] / cell));
    return k;
  };
  struct KeyHash {
    std::size_t operator()(const std::array<long, 3>& k) const {
      return static_cast<std::size_t>(k[0] * 73856093L ^ k[1] * 19349663L ^ k[2] * 83492791L);
    }
  };
  std::unordered_map<std::array<long, 3>, std::vector<std::uint32_t>, KeyHash> grid;
  for (std::uint32_t v : candidates) grid[key(&model[3 * std::size_t{v}])].push_back(v);
  std::vector<std::uint32_t> match(decoded.size() / 3, UINT32_MAX);
  for (std::size_t i = 0; i < match.size(); ++i) {
    const float* p = &decoded[3 * i];
    const auto k = key(p);
    float best = INFINITY;
    for (long dx = -1; dx <= 1; ++dx)
      for (long dy = -1; dy <= 1; ++dy)
        for (long dz = -1; dz <= 1; ++dz) {
          auto it = grid.find({k[0] + dx, k[1] + dy, k[2] + dz});
          if (it == grid.end()) continue;
          for (std::uint32_t v : it->second) {
            const float* q = &model[3 * std::size_t{v}];
            const float d = std::max({std::abs(p[0] - q[0]), std::abs(p[1] - q[1]), std::abs(p[2] - q[2])});
            if (d < best) best = d, match[i] = v;
          }
        }
    EXPECT_LE(best, tolerance) << "decoded vertex " << i << " is far from every model vertex";
  }
  return match;
}

// Triangles as id triples (through `remap` when given), each rotated to start at its smallest id
// (orientation kept), sorted: equal for the same triangle set in any order.
inline std::vector<std::array<std::uint32_t, 3>> canonical_triangles(
    std::span<const std::uint32_t> triangles, const std::vector<std::uint32_t>* remap = nullptr) {
  std::vector<std::array<std::uint32_t, 3>> out(triangles.size() / 3);
  for (std::size_t t = 0; t < out.size(); ++t) {
    for (int c = 0; c < 3; ++c) out[t][c] = remap ? (*remap)[triangles[3 * t + c]] : triangles[3 * t + c];
    std::rotate(out[t].begin(), std::min_element(out[t].begin(), out[t].end()), out[t].end());
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Largest side of the bounding box of the vertices `triangles` use.
inline float used_extent(std::span<const float> positions, std::span<const std::uint32_t> triangles) {
  return core::model::bounds_of(positions, triangles).largest_side();
}

// Draco quantizes over the encoded vertices' largest extent: one step is extent / (2^bits − 1), and
// a value moves by at most half a step; 0.75 steps leaves room for float rounding.
inline float draco_tolerance(float extent, int position_bits) {
  return 0.75f * extent / static_cast<float>((1 << position_bits) - 1);
}

}  // namespace mtlod::test

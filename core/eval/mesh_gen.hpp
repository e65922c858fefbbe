// Synthetic meshes of any size for scaling tests and benchmarks: a noisy sphere, a terrain height field and a
// parametric sea shell, the papers' shell example. Each generator aims at a target triangle count and is
// deterministic for a seed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/model/mesh.hpp"

namespace mtlod::core::eval {

enum class Shape : std::uint8_t {
  kSphere,   // cube-sphere with radial noise: closed 2-manifold, genus 0, 12·n² triangles
  kTerrain,  // height field over a square: one boundary loop, 2·(n−1)² triangles
  kShell,    // logarithmic-spiral tube, apex and aperture capped: closed 2-manifold, genus 0
};

// Parses "sphere", "terrain" or "shell"; returns false for anything else.
bool parse_shape(std::string_view name, Shape& shape);

struct GenerateOptions {
  Shape shape = Shape::kSphere;
  std::size_t target_triangles = 100'000;  // the result lands within a few percent of this
  std::uint32_t seed = 1;                  // noise phase; same seed, same mesh
  float noise = 0.05f;                     // relative amplitude of the surface noise, 0 for none
  bool colors = false;                     // vertex colours: red, green, blue grow along x, y, z
};

// Generates the shape with outward (counter-clockwise seen from outside) triangles, coloured on
// request. Positions lie within the unit cube scaled to about 1 unit radius.
model::Mesh generate_mesh(const GenerateOptions& options);

}  // namespace mtlod::core::eval

// Small scenes for grid-stage tests (core/ARCHITECTURE.md §1): an axis-aligned rectangle and a UV
// sphere, as flat position and triangle arrays, with the cameras the tests reason about.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "core/view/view_grid.hpp"

namespace mtlod::core::test {

struct Scene {
  std::vector<float> positions;
  std::vector<float> normals;
  std::vector<std::uint32_t> triangles;
  std::size_t vertex_count() const { return positions.size() / 3; }
};

// Appends the rectangle [x0, x1] × [y0, y1] in the plane z, facing +z (counter-clockwise seen from
// +z): four vertices, two triangles.
inline void add_rectangle(std::vector<float>& positions, std::vector<std::uint32_t>& triangles, float x0,
                          float y0, float x1, float y1, float z) {
  const auto base = static_cast<std::uint32_t>(positions.size() / 3);
  // One corner at a time: GCC 12 warns (wrongly) that inserting a list into an empty vector
  // overflows it.
  for (const float corner : {x0, y0, z, x1, y0, z, x1, y1, z, x0, y1, z}) positions.push_back(corner);
  for (const std::uint32_t id : {base, base + 1, base + 2, base, base + 2, base + 3}) triangles.push_back(id);
}

// The same rectangle as a scene of its own, with normals.
inline Scene rectangle(float x0, float y0, float x1, float y1, float z) {
  Scene s;
  add_rectangle(s.positions, s.triangles, x0, y0, x1, y1, z);
  s.normals = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  return s;
}

// UV sphere of the given radius at the origin: `stacks` latitude bands, `slices` longitudes; the
// poles are single vertices. Counter-clockwise seen from outside.
inline Scene uv_sphere(float radius, std::uint32_t stacks, std::uint32_t slices) {
  Scene s;
  auto add = [&s, radius](float x, float y, float z) {
    s.positions.insert(s.positions.end(), {radius * x, radius * y, radius * z});
    s.normals.insert(s.normals.end(), {x, y, z});
  };
  add(0, 1, 0);
  for (std::uint32_t i = 1; i < stacks; ++i) {
    const double phi = std::numbers::pi * i / stacks;
    for (std::uint32_t k = 0; k < slices; ++k) {
      const double theta = 2 * std::numbers::pi * k / slices;
      add(static_cast<float>(std::sin(phi) * std::cos(theta)), static_cast<float>(std::cos(phi)),
          static_cast<float>(-std::sin(phi) * std::sin(theta)));
    }
  }
  add(0, -1, 0);
  const std::uint32_t south = 1 + (stacks - 1) * slices;
  auto ring = [slices](std::uint32_t i, std::uint32_t k) { return 1 + (i - 1) * slices + k % slices; };
  for (std::uint32_t k = 0; k < slices; ++k) {
    s.triangles.insert(s.triangles.end(), {0, ring(1, k), ring(1, k + 1)});
    s.triangles.insert(s.triangles.end(), {south, ring(stacks - 1, k + 1), ring(stacks - 1, k)});
  }
  for (std::uint32_t i = 1; i + 1 < stacks; ++i) {
    for (std::uint32_t k = 0; k < slices; ++k) {
      s.triangles.insert(s.triangles.end(), {ring(i, k), ring(i + 1, k), ring(i + 1, k + 1)});
      s.triangles.insert(s.triangles.end(), {ring(i, k), ring(i + 1, k + 1), ring(i, k + 1)});
    }
  }
  return s;
}

// Orthographic camera on the +z axis seeing [-half, half]² on a side×side grid: model point (x, y)
// has grid coordinates ((x + half)·side/(2·half), (half − y)·side/(2·half)), and clip.w = 1.
inline view::ViewMapping ortho_camera(float half, std::uint32_t side) {
  view::Camera camera;
  camera.view = glm::lookAt(glm::vec3(0, 0, 5), glm::vec3(0, 0, 0), glm::vec3(0, 1, 0));
  camera.projection = glm::ortho(-half, half, -half, half, 0.1f, 10.0f);
  return view::ViewMapping(camera, view::GridSize{side, side});
}

}  // namespace mtlod::core::test

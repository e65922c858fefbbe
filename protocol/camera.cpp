// Cameras for clients and tools (see camera.hpp).
#include "protocol/camera.hpp"

#include <algorithm>
#include <cmath>

#include <glm/ext/matrix_clip_space.hpp>
#include <glm/ext/matrix_transform.hpp>
#include <glm/mat4x4.hpp>

namespace mtlod::protocol {

void look_at_camera(const LookAt& c, double aspect, Matrix4& view, Matrix4& projection) {
  const glm::dvec3 eye(c.eye[0], c.eye[1], c.eye[2]), target(c.target[0], c.target[1], c.target[2]);
  const double distance = std::max(glm::length(target - eye), 1e-9);
  const double near = c.near > 0 ? c.near : distance / 100;
  const double far = c.far > 0 ? c.far : distance * 100;
  const glm::dmat4 v = glm::lookAt(eye, target, glm::dvec3(c.up[0], c.up[1], c.up[2]));
  const glm::dmat4 p = glm::perspective(glm::radians(c.fov_deg), aspect, near, far);
  for (int col = 0; col < 4; ++col) {
    for (int row = 0; row < 4; ++row) {
      view[col * 4 + row] = v[col][row];
      projection[col * 4 + row] = p[col][row];
    }
  }
}

LookAt frame_bounds(const std::array<double, 3>& lo, const std::array<double, 3>& hi, double fov_deg) {
  LookAt c;
  double r2 = 0;
  for (int i = 0; i < 3; ++i) {
    c.target[i] = 0.5 * (lo[i] + hi[i]);
    r2 += 0.25 * (hi[i] - lo[i]) * (hi[i] - lo[i]);
  }
  // The bounding sphere fits the vertical field of view with a little margin.
  const double radius = std::max(std::sqrt(r2), 1e-9);
  const double distance = 1.1 * radius / std::sin(glm::radians(fov_deg) / 2);
  c.eye = {c.target[0], c.target[1], c.target[2] + distance};
  c.fov_deg = fov_deg;
  return c;
}

}  // namespace mtlod::protocol

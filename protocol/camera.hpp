// Cameras for clients and tools: eye/target/up/field of view → the column-major view and
// projection matrices an extract request carries (the conventions of glm::lookAt and glm::perspective).
#pragma once

#include <array>

#include "protocol/messages.hpp"

namespace mtlod::protocol {

struct LookAt {
  std::array<double, 3> eye{0, 0, 3};
  std::array<double, 3> target{0, 0, 0};
  std::array<double, 3> up{0, 1, 0};
  double fov_deg = 45;  // vertical field of view
  double near = 0;      // 0: a hundredth of the eye-target distance
  double far = 0;       // 0: a hundred times the eye-target distance
};

// Fills view and projection for a viewport of the given aspect (width / height).
void look_at_camera(const LookAt& camera, double aspect, Matrix4& view, Matrix4& projection);

// A camera that frames a bounding box from its front (+z), the whole box in view.
LookAt frame_bounds(const std::array<double, 3>& bounds_min, const std::array<double, 3>& bounds_max,
                    double fov_deg = 45);

}  // namespace mtlod::protocol

// What mtlod-load sends: extract requests with random, fixed or scripted cameras and foci, and gaze
// updates, mixed by weights. Pure functions over a seeded generator, so a run can be repeated.
#pragma once

#include <array>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "core/result.hpp"
#include "protocol/messages.hpp"

namespace mtlod::clients {

// One line of a camera script: eye and target in model units, and an optional focus (normalised).
struct ScriptedCamera {
  std::array<double, 3> eye{};
  std::array<double, 3> target{};
  bool has_focus = false;
  std::array<double, 2> focus{0.5, 0.5};
};

// Reads a camera script: one camera per line, "ex,ey,ez,tx,ty,tz" or "ex,ey,ez,tx,ty,tz,fx,fy";
// blank lines and lines starting with '#' are skipped. Errors name the line.
Result<std::vector<ScriptedCamera>> parse_camera_script(const std::string& text);

// Weights of the request kinds, from "extract=3,gaze=1" (either may be left out, meaning 0).
struct Mix {
  double extract = 1;
  double gaze = 0;
};
Result<Mix> parse_mix(const std::string& text);

// A camera orbiting the box's centre: random azimuth, elevation within ±60°, distance between 0.8
// and 1.6 times the one that frames the box. Fills `request.view` and `request.projection`.
void random_orbit_camera(const std::array<double, 3>& bounds_min, const std::array<double, 3>& bounds_max,
                         double fov_deg, std::mt19937_64& rng, protocol::Extract& request);

}  // namespace mtlod::clients

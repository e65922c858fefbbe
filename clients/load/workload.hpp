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

// A served model, or a scene: its bounds (a scene's in the world) and the flags' extract for it.
struct ModelView {
  std::string name;  // the model's, or "scene FILE"
  std::array<double, 3> bounds_min{}, bounds_max{};
  protocol::Extract base;
};

// What the connections send, from mtlod-load's flags.
struct RequestSettings {
  Mix mix;
  bool random_cameras = true;          // --cameras random: orbits around the model or scene
  std::vector<ScriptedCamera> script;  // --cameras FILE: its cameras, cycled; else empty
  bool random_focus = true;            // without a script: each extract gets a random focus point
  double fov_deg = 45;
};

// One connection's requests in order: an extract first, then extracts and gazes (which move the
// focus of the last extract) by the mix's weights. Extracts get a random orbit camera, or the
// script's next camera (the first being `first_camera`, modulo its length), or the base's camera;
// the same seed gives the same sequence.
class RequestSequence {
 public:
  RequestSequence(const ModelView& model, const RequestSettings& settings, std::uint64_t seed,
                  std::size_t first_camera);

  protocol::Request next();

 private:
  const ModelView& model_;
  const RequestSettings& settings_;
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> unit_{0.1, 0.9};  // focus coordinates
  std::uniform_real_distribution<double> pick_;            // the kind, by weight
  std::size_t script_index_;
  bool has_view_ = false;
};

// A camera orbiting the box's centre: random azimuth, elevation within ±60°, distance between 0.8
// and 1.6 times the one that frames the box. Fills `request.view` and `request.projection`.
void random_orbit_camera(const std::array<double, 3>& bounds_min, const std::array<double, 3>& bounds_max,
                         double fov_deg, std::mt19937_64& rng, protocol::Extract& request);

}  // namespace mtlod::clients

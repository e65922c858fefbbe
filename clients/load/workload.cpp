// mtlod-load's request generation (see workload.hpp).
#include "clients/load/workload.hpp"

#include <cmath>
#include <numbers>
#include <sstream>

#include "clients/common/extract_flags.hpp"
#include "fmt/format.h"
#include "protocol/camera.hpp"

namespace mtlod::clients {
Result<std::vector<ScriptedCamera>> parse_camera_script(const std::string& text) {
  std::vector<ScriptedCamera> cameras;
  std::stringstream in(text);
  std::string line;
  std::vector<double> v;
  for (std::size_t number = 1; std::getline(in, line); ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos || line[line.find_first_not_of(" \t")] == '#')
      continue;
    if (!clients::parse_number_list(line, v) || (v.size() != 6 && v.size() != 8)) {
      return make_error(
          ErrorCode::kInvalidArgument,
          fmt::format("camera script line {}: expected ex,ey,ez,tx,ty,tz[,fx,fy], got '{}'", number, line));
    }
    ScriptedCamera c;
    c.eye = {v[0], v[1], v[2]};
    c.target = {v[3], v[4], v[5]};
    if (v.size() == 8) {
      if (v[6] < 0 || v[6] > 1 || v[7] < 0 || v[7] > 1) {
        return make_error(ErrorCode::kInvalidArgument,
                          fmt::format("camera script line {}: focus must lie in 0..1", number));
      }
      c.has_focus = true;
      c.focus = {v[6], v[7]};
    }
    cameras.push_back(c);
  }
  if (cameras.empty()) return make_error(ErrorCode::kInvalidArgument, "camera script holds no camera");
  return cameras;
}

Result<Mix> parse_mix(const std::string& text) {
  Mix mix{0, 0};
  std::stringstream in(text);
  std::string part;
  while (std::getline(in, part, ',')) {
    const auto eq = part.find('=');
    double weight = -1;
    try {
      if (eq != std::string::npos) weight = std::stod(part.substr(eq + 1));
    } catch (const std::exception&) {
    }
    const std::string name = part.substr(0, eq);
    if (weight < 0 || !std::isfinite(weight) || (name != "extract" && name != "gaze")) {
      return make_error(ErrorCode::kInvalidArgument,
                        fmt::format("--mix '{}': expected extract=W,gaze=W", text));
    }
    (name == "extract" ? mix.extract : mix.gaze) = weight;
  }
  if (mix.extract + mix.gaze <= 0)
    return make_error(ErrorCode::kInvalidArgument, fmt::format("--mix '{}': all weights are 0", text));
  return mix;
}

void random_orbit_camera(const std::array<double, 3>& bounds_min, const std::array<double, 3>& bounds_max,
                         double fov_deg, std::mt19937_64& rng, protocol::Extract& request) {
  protocol::LookAt camera = protocol::frame_bounds(bounds_min, bounds_max, fov_deg);
  double distance = 0;
  for (int i = 0; i < 3; ++i)
    distance += (camera.eye[i] - camera.target[i]) * (camera.eye[i] - camera.target[i]);
  distance = std::sqrt(distance) * std::uniform_real_distribution<double>(0.8, 1.6)(rng);
  const double azimuth = std::uniform_real_distribution<double>(0, 2 * std::numbers::pi)(rng);
  const double elevation =
      std::uniform_real_distribution<double>(-std::numbers::pi / 3, std::numbers::pi / 3)(rng);
  camera.eye = {camera.target[0] + distance * std::cos(elevation) * std::sin(azimuth),
                camera.target[1] + distance * std::sin(elevation),
                camera.target[2] + distance * std::cos(elevation) * std::cos(azimuth)};
  camera.near = camera.far = 0;  // derived from the new distance
  const double aspect =
      static_cast<double>(request.viewport[0]) / std::max<std::uint32_t>(1, request.viewport[1]);
  protocol::look_at_camera(camera, aspect, request.view, request.projection);
}

RequestSequence::RequestSequence(const ModelView& model, const RequestSettings& settings, std::uint64_t seed,
                                 std::size_t first_camera)
    : model_(model),
      settings_(settings),
      rng_(seed),
      pick_(0, settings.mix.extract + settings.mix.gaze),
      script_index_(first_camera) {}

protocol::Request RequestSequence::next() {
  // A gaze needs an extract before it on the connection: its view and focus.
  if (has_view_ && pick_(rng_) >= settings_.mix.extract)
    return protocol::Gaze{unit_(rng_), unit_(rng_), std::nullopt, std::nullopt};
  protocol::Extract e = model_.base;
  const std::vector<ScriptedCamera>& script = settings_.script;
  if (settings_.random_cameras) {
    random_orbit_camera(model_.bounds_min, model_.bounds_max, settings_.fov_deg, rng_, e);
  } else if (!script.empty()) {
    const ScriptedCamera& s = script[script_index_++ % script.size()];
    protocol::LookAt look{s.eye, s.target, {0, 1, 0}, settings_.fov_deg};
    protocol::look_at_camera(look, static_cast<double>(e.viewport[0]) / e.viewport[1], e.view, e.projection);
    if (s.has_focus) protocol::gaze_region(e.criteria).points.front() = {s.focus[0], s.focus[1]};
  }
  if (settings_.random_focus && script.empty()) {
    protocol::Point& focus = protocol::gaze_region(e.criteria).points.front();
    focus.x = unit_(rng_);
    focus.y = unit_(rng_);
  }
  has_view_ = true;
  return e;
}

}  // namespace mtlod::clients

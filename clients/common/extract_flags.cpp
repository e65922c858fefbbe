// Extraction flags (see extract_flags.hpp). The request is validated by round-tripping through
// parse_request, so a bad flag gets exactly the message a bad request would.
#include "clients/common/extract_flags.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <sstream>

#include "CLI/CLI.hpp"
#include "fmt/format.h"
#include "fmt/ranges.h"
#include "protocol/camera.hpp"
#include "protocol/parse.hpp"

namespace mtlod::clients {

using protocol::enum_from_name;
using protocol::Extract;
using protocol::frame_bounds;
using protocol::kDistanceMetricNames;
using protocol::kDistanceUnitNames;
using protocol::kDracoMethodNames;
using protocol::kFalloffNames;
using protocol::Limits;
using protocol::look_at_camera;
using protocol::LookAt;
using protocol::parse_request;

namespace {

// "a,b,c" → exactly `count` numbers.
bool parse_numbers(const std::string& text, std::size_t count, std::vector<double>& out) {
  return parse_number_list(text, out) && out.size() == count;
}

Result<std::array<std::uint32_t, 2>> parse_size(const std::string& text, const char* flag) {
  const auto x = text.find('x');
  try {
    const unsigned long w = std::stoul(text.substr(0, x));
    const unsigned long h = x == std::string::npos ? w : std::stoul(text.substr(x + 1));
    return std::array<std::uint32_t, 2>{static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h)};
  } catch (const std::exception&) {
    return make_error(ErrorCode::kInvalidArgument, fmt::format("{} '{}': expected W or WxH", flag, text));
  }
}

Result<std::array<double, 3>> parse_vec3(const std::string& text, const char* flag) {
  std::vector<double> v;
  if (!parse_numbers(text, 3, v))
    return make_error(ErrorCode::kInvalidArgument, fmt::format("{} '{}': expected X,Y,Z", flag, text));
  return std::array<double, 3>{v[0], v[1], v[2]};
}

}  // namespace

bool parse_number_list(const std::string& text, std::vector<double>& out) {
  out.clear();
  std::stringstream in(text);
  std::string part;
  while (std::getline(in, part, ',')) {
    try {
      std::size_t used = 0;  // std::stod skips leading spaces; trailing ones are skipped here
      out.push_back(std::stod(part, &used));
      while (used < part.size() && std::isspace(static_cast<unsigned char>(part[used]))) ++used;
      if (used != part.size() || !std::isfinite(out.back())) return false;
    } catch (const std::exception&) {
      return false;
    }
  }
  return true;
}

std::string criterion_flag(core::view::Criterion criterion) {
  std::string flag = fmt::format("--{}", protocol::wire(criterion).name);
  std::replace(flag.begin(), flag.end(), '_', '-');
  return flag;
}

void add_extract_flags(CLI::App& app, ExtractFlags& f) {
  app.add_option("--eye", f.eye, "camera position X,Y,Z (default: frame the model from its front)");
  app.add_option("--target", f.target, "point looked at X,Y,Z (default: the model's centre)");
  app.add_option("--up", f.up, "up direction X,Y,Z")->capture_default_str();
  app.add_option("--fov", f.fov_deg, "vertical field of view in degrees")->capture_default_str();
  app.add_option("--grid", f.grid, "distance-transform grid W or WxH")->capture_default_str();
  app.add_option("--viewport", f.viewport, "screen size WxH in pixels")->capture_default_str();
  app.add_option("--error", f.error, "error bound e in model units");
  app.add_option("--error-px", f.error_px, "error bound e in screen pixels (converted per vertex by depth)");
  // One flag per criterion, from the protocol's table.
  for (const core::view::Criterion c : core::view::kAllCriteria) {
    const protocol::CriterionWire& w = protocol::wire(c);
    const std::string flag = criterion_flag(c);
    if (core::view::traits(c).seeds == core::view::Seeds::kPoints) {
      app.add_option(flag, f.criteria[c],
                     fmt::format("X,Y,D,F: allowed error e·F (F {} to {}) within D pixels of {}; one "
                                 "point at normalised X,Y (0..1) per flag, repeatable",
                                 w.factor_min, w.factor_max, w.measured_to))
          ->take_all();
    } else {
      app.add_option(flag, f.criteria[c],
                     fmt::format("D,F: allowed error e·F (F {} to {}) within D pixels of {}", w.factor_min,
                                 w.factor_max, w.measured_to))
          ->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
    }
  }
  app.add_option("--budget", f.budget, "at most this many triangles (worst first)");
  // The choices come from the protocol's tables, so a new law or metric shows up here by itself.
  app.add_option("--falloff", f.falloff,
                 fmt::format("falloff law: {} (default: step)", fmt::join(kFalloffNames, ", ")));
  app.add_option("--distance", f.distance,
                 fmt::format("distance transform: {}", fmt::join(kDistanceMetricNames, ", ")))
      ->capture_default_str();
  app.add_option("--units", f.units, "distances D in pixels or raw chamfer units")->capture_default_str();
  app.add_flag("--internal-silhouettes", f.internal_silhouettes,
               "depth jumps seed the silhouette distance too");
  app.add_option("--frustum-factor", f.frustum_factor, "error multiplier outside the view")
      ->capture_default_str();
  app.add_option("--backface-factor", f.backface_factor, "error multiplier for back faces")
      ->capture_default_str();
  app.add_option("--hidden-factor", f.hidden_factor,
                 "error multiplier behind the visible surface (default: 1, or 16 with the default criteria)");
  app.add_option("--codec", f.codec,
                 fmt::format("payload codec: {} (meshopt: no labels, at most 16 position bits); default: the "
                             "connection's (draco), or the output file's for mtlod-extract",
                             fmt::join(protocol::kCodecNames, ", ")));
  app.add_option(
      "--draco", f.draco_method,
      "Draco method: edgebreaker or sequential (default: edgebreaker for extract, sequential for gaze)");
  app.add_option("--draco-speed", f.draco_speed, "Draco speed 0 (smallest) .. 10 (fastest)")
      ->capture_default_str();
  app.add_option(
      "--draco-entropy", f.draco_entropy,
      "entropy-code Draco's attribute values: true or false (default: true for extract, false for gaze)");
  app.add_option("--position-bits", f.position_bits, "position quantization bits (meshopt: at most 16)")
      ->check(CLI::Range(1, 20))
      ->capture_default_str();
  app.add_option("--normal-bits", f.normal_bits, "normal quantization bits (octahedral)")
      ->check(CLI::Range(2, 16))
      ->capture_default_str();
  app.add_flag("--no-normals", f.no_normals, "leave the vertex normals out (sent by default)");
  app.add_flag("--colors", f.colors, "require vertex colours (sent by default when the model has them)");
  app.add_flag("--no-colors", f.no_colors, "leave the vertex colours out");
  app.add_flag("--labels", f.labels, "send per-vertex distance labels");
  app.add_flag("--delta", f.delta,
               "replies carry what changed since the previous mesh (by triangle id; sequential Draco)");
}

void apply_default_criteria(ExtractFlags& flags) {
  if (!flags.error && !flags.error_px) flags.error_px = 1;
  if (!flags.falloff.empty()) return;
  for (const core::view::Criterion c : core::view::kAllCriteria) {
    if (core::view::traits(c).combine == core::view::Combine::kStricter && !flags.criteria[c].empty()) return;
  }
  flags.falloff = "foveal";
  flags.criteria[core::view::kGazeCriterion].push_back("0.5,0.5,0,1");
  if (!flags.hidden_factor) flags.hidden_factor = kDefaultHiddenFactor;
}

Result<protocol::Extract> make_extract(const ExtractFlags& f, const std::string& model,
                                       const std::array<double, 3>& bounds_min,
                                       const std::array<double, 3>& bounds_max) {
  Extract e;
  e.model = model;
  MTLOD_TRY(e.viewport, parse_size(f.viewport, "--viewport"));
  MTLOD_TRY(e.grid, parse_size(f.grid, "--grid"));
  LookAt camera = frame_bounds(bounds_min, bounds_max, f.fov_deg);
  if (!f.eye.empty()) {
    MTLOD_TRY(camera.eye, parse_vec3(f.eye, "--eye"));
  }
  if (!f.target.empty()) {
    MTLOD_TRY(camera.target, parse_vec3(f.target, "--target"));
  }
  MTLOD_TRY(camera.up, parse_vec3(f.up, "--up"));
  camera.fov_deg = f.fov_deg;
  look_at_camera(camera, static_cast<double>(e.viewport[0]) / std::max<std::uint32_t>(1, e.viewport[1]),
                 e.view, e.projection);
  if (f.error.has_value() == f.error_px.has_value()) {
    return make_error(ErrorCode::kInvalidArgument,
                      "give exactly one of --error (model units) and --error-px (pixels)");
  }
  e.error = f.error ? *f.error : *f.error_px;
  e.error_unit = f.error ? core::view::ErrorUnits::kModel : core::view::ErrorUnits::kScreenPixels;
  std::vector<double> v;
  for (const core::view::Criterion c : core::view::kAllCriteria) {
    // Points share the first one's D and F (one transform per criterion), as on the wire.
    const bool points = core::view::traits(c).seeds == core::view::Seeds::kPoints;
    for (const std::string& text : f.criteria[c]) {
      if (!parse_numbers(text, points ? 4 : 2, v)) {
        return make_error(ErrorCode::kInvalidArgument, fmt::format("{} '{}': expected {}", criterion_flag(c),
                                                                   text, points ? "X,Y,D,F" : "D,F"));
      }
      std::optional<protocol::Region>& region = e.criteria.regions[c];
      if (!region) region = protocol::Region{v[points ? 2 : 0], v[points ? 3 : 1], {}};
      if (points) region->points.push_back({v[0], v[1]});
    }
  }
  e.budget = f.budget;
  e.normals = !f.no_normals;
  if (f.colors && f.no_colors)
    return make_error(ErrorCode::kInvalidArgument, "--colors and --no-colors contradict each other");
  if (f.colors || f.no_colors) e.colors = f.colors;
  e.quantization.normal_bits = f.normal_bits;
  e.labels = f.labels;
  e.draco.speed = f.draco_speed;
  e.quantization.position_bits = f.position_bits;
  e.draco.entropy_coding = f.draco_entropy;
  e.delta = f.delta;
  e.criteria.internal_silhouettes = f.internal_silhouettes;
  e.criteria.frustum_factor = f.frustum_factor;
  e.criteria.backface_factor = f.backface_factor;
  e.criteria.hidden_factor = f.hidden_factor.value_or(1.0);
  auto named = [](auto& out, const auto& names, const std::string& value, const char* flag) -> Status {
    using Enum = std::decay_t<decltype(out)>;
    const auto found = enum_from_name<Enum>(names, value);
    if (!found) {
      std::string options;
      for (const char* n : names) options += fmt::format("{}{}", options.empty() ? "" : ", ", n);
      return make_error(ErrorCode::kInvalidArgument,
                        fmt::format("{} '{}': expected one of {}", flag, value, options));
    }
    out = *found;
    return Ok{};
  };
  MTLOD_RETURN_IF_ERROR(
      named(e.criteria.falloff, kFalloffNames, f.falloff.empty() ? "step" : f.falloff, "--falloff"));
  MTLOD_RETURN_IF_ERROR(named(e.criteria.distance, kDistanceMetricNames, f.distance, "--distance"));
  MTLOD_RETURN_IF_ERROR(named(e.criteria.units, kDistanceUnitNames, f.units, "--units"));
  if (!f.codec.empty()) {
    core::codec::Codec codec{};
    MTLOD_RETURN_IF_ERROR(named(codec, protocol::kCodecNames, f.codec, "--codec"));
    e.codec = codec;
  }
  if (!f.draco_method.empty()) {
    core::codec::DracoMethod method{};
    MTLOD_RETURN_IF_ERROR(named(method, kDracoMethodNames, f.draco_method, "--draco"));
    e.draco.method = method;
  }
  // The same checks the server applies (ranges, singular matrices), with the same messages.
  auto parsed = parse_request(to_json(e, 0), Limits{});
  if (!parsed) return make_error(ErrorCode::kInvalidArgument, parsed.error().message);
  return std::get<Extract>(std::move(parsed->request));
}

}  // namespace mtlod::clients

// The command-line flags of an extraction, shared by mtlod-extract (local) and mtlod-client
// (remote) so that both mean the same thing: camera, grid, error bound, criteria, budget, Draco.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/result.hpp"
#include "protocol/messages.hpp"

namespace CLI {
class App;
}

namespace mtlod::clients {

struct ExtractFlags {
  std::string eye, target, up = "0,1,0";  // "X,Y,Z"; without --eye the model is framed from the front
  double fov_deg = 45;
  std::string grid = "256";  // "W" or "WxH"
  std::string viewport = "800x600";
  std::optional<double> error;     // model units
  std::optional<double> error_px;  // screen pixels
  // Per criterion, its flag's values (--silhouette, --focus, ...: protocol::kCriterionWire's
  // names): "X,Y,D,F" for each point of a point-seeded criterion (repeatable), else one "D,F".
  core::view::PerCriterion<std::vector<std::string>> criteria;
  std::optional<std::uint32_t> budget;
  std::string falloff;  // empty: step
  std::string distance = "chamfer-5-7-11", units = "pixels";
  bool internal_silhouettes = false;
  double frustum_factor = 8, backface_factor = 1;
  std::optional<double> hidden_factor;  // 1 (off) unless given, or set by apply_default_criteria
  std::string codec;                    // the payload's codec (protocol::kCodecNames); empty: the server's
  std::string draco_method;             // empty: the server's default for the request type
  int draco_speed = 10, position_bits = 14, normal_bits = 10;
  std::optional<bool> draco_entropy;       // unset: the server's default for the request type
  bool no_normals = false;                 // normals are sent unless this is set
  bool colors = false, no_colors = false;  // neither: the model's colours when it has them
  bool labels = false;
  bool delta = false;  // replies carry changes since the previous mesh (sequential Draco)
};

// Parses comma-separated numbers ("0.5, 0.25,20"; spaces around each allowed) into `out`. False
// when a part is not a whole finite number. Shared by every flag and file format of the clients.
bool parse_number_list(const std::string& text, std::vector<double>& out);

// A criterion's flag: "--" and its wire name with '-' for '_' (--silhouette, --focus, ...).
std::string criterion_flag(core::view::Criterion criterion);

// Registers the flags on `app`, writing into `flags`.
void add_extract_flags(CLI::App& app, ExtractFlags& flags);

// The default criteria of the viewing clients (mtlod-gaze, mtlod-load, the browser viewer), the
// winner of the image-space study (tests/evaluation/FIDELITY.md, `default`): a bound in screen
// pixels (1 unless given) that holds at the focus and grows with eccentricity like the eye's minimum
// angle of resolution, ×(1 + e/2.3°) (`--falloff foveal --focus X,Y,0,1`), and surfaces hidden from
// the camera coarsened ×16 (`--hidden-factor 16`, unless that flag was given). Applied only when
// neither --falloff nor a criterion that refines (core::view::Combine::kStricter: --silhouette,
// --focus) was given; the focus starts at the view's centre.
void apply_default_criteria(ExtractFlags& flags);
inline constexpr double kDefaultHiddenFactor = 16;

// Builds the request for `model` whose bounding box is given (for the default camera). The result
// is checked by the same parser the server uses; errors name the flag.
Result<protocol::Extract> make_extract(const ExtractFlags& flags, const std::string& model,
                                       const std::array<double, 3>& bounds_min,
                                       const std::array<double, 3>& bounds_max);

}  // namespace mtlod::clients

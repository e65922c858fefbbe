// mtlod-gaze's flags (see gaze_options.hpp).
#include "clients/gaze/gaze_options.hpp"

#include <cstdio>

#include "CLI/CLI.hpp"
#include "clients/common/scene_file.hpp"
#include "fmt/format.h"
#include "fmt/ranges.h"

namespace mtlod::clients {
namespace {

// The synthesiser's flags beyond rate, length and seed.
void add_synthesis_flags(CLI::App& app, SynthesisOptions& s) {
  app.add_option("--screen-deg", s.screen_deg,
                 "synthesised trace: the viewport's width in degrees of visual angle (its height follows "
                 "--viewport's shape)")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 180.0));
  app.add_option("--pursuit-share", s.pursuit_share,
                 "synthesised trace: share of fixations followed by smooth pursuit")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--blink-share", s.blink_share, "synthesised trace: share of fixations followed by a blink")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--pursuit-gain", s.pursuit_gain,
                 "synthesised trace: eye speed / target speed in pursuit; below 1 the eye falls behind "
                 "and catches up by saccades (1: none)")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 1.0));
}

}  // namespace

void add_gaze_flags(CLI::App& app, GazeOptions& o, clients::ExtractFlags& flags) {
  // Registered in the order --help lists them.
  add_endpoint_flags(app, o.endpoint);
  CLI::Option* model = app.add_option("--model", o.model, "model name")->capture_default_str();
  app.add_option("--scene", o.scene_file,
                 "scene file instead of --model: JSON {\"instances\": [{\"model\", \"matrix\"}, ...]} "
                 "(PROTOCOL.md, Scenes); every stream views the whole scene, framed unless --eye is given")
      ->excludes(model);
  app.add_option("--trace", o.trace_paths,
                 "CSV trace: time_ms,x,y per line (x, y normalised, 0,0 top left; 'time_ms,,' or "
                 "'time_ms,nan,nan': the tracker lost the eye), or a folder of *.csv traces; repeat the "
                 "flag or give a comma list for several, stream k plays trace k mod n; without it each "
                 "stream synthesises one")
      ->delimiter(',')
      ->allow_extra_args(false);
  app.add_option("--hz", o.synthesis.rate_hz, "synthesised trace: samples per second")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 10000.0));
  app.add_option("-d,--duration", o.synthesis.duration_ms, "synthesised trace: length in ms")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 86400e3));
  app.add_option("--seed", o.synthesis.seed, "synthesised trace: random seed (stream k uses seed + k)")
      ->capture_default_str();
  add_synthesis_flags(app, o.synthesis);
  app.add_option("--streams", o.streams, "concurrent gaze streams, one connection each")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1024u));
  app.add_option("--drain-timeout", o.drain_timeout_s, "seconds to wait for outstanding replies at the end")
      ->capture_default_str();
  app.add_option(
         "--attempts", o.retry.attempts,
         "connection attempts, with exponential backoff, when a connection drops (1: give up at once)")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1000u));
  app.add_option("--json", o.json_file, "write the report as JSON to this file");
  app.add_flag("-q,--quiet", o.quiet, "no progress line");
  app.add_option("--write-trace", o.write_trace,
                 "write the (first stream's) trace as CSV to this file and exit");
  clients::add_extract_flags(app, flags);
}

void complete_gaze_flags(clients::ExtractFlags& flags) {
  clients::apply_default_criteria(flags);
  // A gaze moves the focus: without one the trace would change nothing.
  std::vector<std::string>& gaze = flags.criteria[core::view::kGazeCriterion];
  if (gaze.empty()) gaze.push_back("0.5,0.5,20,0.1");
}

Status complete_synthesis(GazeOptions& options, const clients::ExtractFlags& flags) {
  // A malformed --viewport is reported when the extract is made; the default shape serves until then.
  unsigned width = 0, height = 0;
  if (std::sscanf(flags.viewport.c_str(), "%ux%u", &width, &height) == 2 && width > 0 && height > 0)
    options.synthesis.aspect = static_cast<double>(width) / height;
  return check_synthesis_options(options.synthesis);
}

Status read_gaze_scene(GazeOptions& options) {
  if (options.scene_file.empty()) return Ok{};
  MTLOD_TRY(options.scene, clients::read_scene_file(options.scene_file));
  return Ok{};
}

std::string describe_view(const GazeOptions& o) {
  if (o.scene_file.empty()) return o.model;
  return fmt::format("scene {} ({} instances)", o.scene_file, o.scene.size());
}

std::string describe_traces(const GazeOptions& o) {
  if (o.trace_paths.empty())
    return fmt::format("synthetic {} Hz, {} ms", o.synthesis.rate_hz, o.synthesis.duration_ms);
  return fmt::format("{}", fmt::join(o.trace_paths, ", "));
}

}  // namespace mtlod::clients

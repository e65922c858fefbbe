// mtlod-load's flags (see load_options.hpp).
#include "clients/load/load_options.hpp"

#include <fstream>
#include <sstream>

#include "CLI/CLI.hpp"
#include "clients/common/scene_file.hpp"
#include "fmt/format.h"

namespace mtlod::clients {
namespace {

// The flags of the run's shape: models, connections, how long, how fast.
void add_run_flags(CLI::App& app, LoadOptions& o) {
  app.add_option("--model", o.models,
                 "model name; repeat to spread connections over several models (default: bunny, unless "
                 "--scene is given)")
      ->take_all();
  app.add_option("--scene", o.scene_files,
                 "scene file, JSON {\"instances\": [{\"model\", \"matrix\"}, ...]} (PROTOCOL.md, Scenes), "
                 "viewed whole as a model is: cameras orbit its box; repeatable, beside --model (connections "
                 "take the models, then the scenes, in turn)")
      ->take_all();
  app.add_option("-c,--connections", o.connections, "connections")
      ->capture_default_str()
      ->check(CLI::Range(1u, 4096u));
  app.add_option("-d,--duration", o.duration_s, "seconds of sending (replies are awaited after)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
  app.add_option("-n,--requests", o.max_requests, "stop after this many requests (0: duration only)")
      ->capture_default_str();
  app.add_option("--rate", o.rate, "open loop: requests per second over all connections (0: closed loop)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e6));
  app.add_option("--arrivals", o.arrivals, "open loop schedule: uniform or poisson")->capture_default_str();
  app.add_option(
         "--window", o.window,
         "open loop: unanswered requests per connection before sending waits (0: the server's max_in_flight)")
      ->capture_default_str();
}

// The flags of what is sent: cameras, foci, the mix of request kinds.
void add_request_flags(CLI::App& app, LoadOptions& o) {
  app.add_option("--cameras", o.cameras,
                 "random (orbits around the model or scene), fixed (the camera flags) or a script file of "
                 "ex,ey,ez,tx,ty,tz[,fx,fy] lines, cycled")
      ->capture_default_str();
  app.add_option("--random-focus", o.random_focus, "each extract gets a random focus point (true/false)")
      ->capture_default_str();
  app.add_option("--mix", o.mix,
                 "request kinds by weight: extract=W,gaze=W (a gaze moves the focus of the "
                 "connection's last extract)")
      ->capture_default_str();
  app.add_option(
         "--gaze-hz", o.gaze_hz,
         "gaze streams: every connection sends one extract, then gaze updates at this rate (sets --mix "
         "gaze=1 and --rate to connections × Hz)")
      ->check(CLI::Range(0.0, 10000.0));
}

// The flags of the end of the run, reconnection and the report.
void add_session_flags(CLI::App& app, LoadOptions& o) {
  app.add_option("--drain-timeout", o.drain_timeout_s, "seconds to wait for outstanding replies at the end")
      ->capture_default_str();
  app.add_option("--seed", o.seed, "random seed for cameras, foci, mix and Poisson arrivals")
      ->capture_default_str();
  app.add_option(
         "--attempts", o.retry.attempts,
         "connection attempts when a connection drops or its server drains, with exponential backoff; the "
         "unanswered requests are then sent again (1: give up at once)")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1000u));
  app.add_option(
         "--reconnect-after", o.reconnect_after,
         "requests per connection: then it waits for its replies and reconnects, so a load balancer can "
         "move it (0: never)")
      ->capture_default_str();
  app.add_flag("--decode", o.decode,
               "decode every mesh payload (whole or delta, either codec) and check its triangles against the "
               "reply, as a viewer would; a payload that fails makes the run fail");
  app.add_option("--json", o.json_file, "write the report as JSON to this file");
  app.add_flag("-q,--quiet", o.quiet, "no progress line");
}

Result<std::vector<ScriptedCamera>> read_camera_script(const std::string& path) {
  std::ifstream in(path);
  if (!in) return make_error(ErrorCode::kIoError, fmt::format("{}: cannot read the camera script", path));
  std::stringstream text;
  text << in.rdbuf();
  auto parsed = parse_camera_script(text.str());
  if (!parsed) return make_error(parsed.error().code, fmt::format("{}: {}", path, parsed.error().message));
  return parsed;
}

}  // namespace

void add_load_flags(CLI::App& app, LoadOptions& options, clients::ExtractFlags& flags) {
  // Registered in the order --help lists them.
  add_endpoint_flags(app, options.endpoint);
  add_run_flags(app, options);
  add_request_flags(app, options);
  add_session_flags(app, options);
  clients::add_extract_flags(app, flags);
}

Result<RequestSettings> complete_load_options(LoadOptions& o, clients::ExtractFlags& flags) {
  clients::apply_default_criteria(flags);
  if (o.models.empty() && o.scene_files.empty()) o.models.push_back("bunny");
  o.scenes.clear();
  for (const std::string& file : o.scene_files) {
    MTLOD_TRY(std::vector<protocol::Instance> scene, clients::read_scene_file(file));
    o.scenes.push_back(std::move(scene));
  }
  if (o.gaze_hz > 0) {
    o.mix = "gaze=1";
    o.rate = o.gaze_hz * o.connections;
  }
  RequestSettings settings;
  MTLOD_TRY(settings.mix, parse_mix(o.mix));
  if (o.arrivals != "uniform" && o.arrivals != "poisson")
    return make_error(ErrorCode::kInvalidArgument, "--arrivals must be uniform or poisson");
  if (o.cameras != "random" && o.cameras != "fixed") {
    MTLOD_TRY(settings.script, read_camera_script(o.cameras));
  }
  settings.random_cameras = o.cameras == "random";
  settings.random_focus = o.random_focus;
  settings.fov_deg = flags.fov_deg;
  return settings;
}

}  // namespace mtlod::clients

// mtlod-load's command line: the flags, and what they mean once parsed (the defaults that depend on
// other flags, the request mix and the camera script).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "clients/common/extract_flags.hpp"
#include "clients/common/retry.hpp"
#include "clients/load/workload.hpp"
#include "core/result.hpp"
#include "protocol/messages.hpp"

namespace CLI {
class App;
}

namespace mtlod::clients {

struct LoadOptions {
  Endpoint endpoint;
  std::vector<std::string> models;  // empty after parsing: bunny, unless scenes are given
  // --scene files ({"instances": [{"model", "matrix"}, ...]}), viewed whole like models; their
  // instances, in the same order, once read (complete_load_options).
  std::vector<std::string> scene_files;
  std::vector<std::vector<protocol::Instance>> scenes;
  unsigned connections = 1;
  double duration_s = 10;
  std::uint64_t max_requests = 0;  // 0: bounded by duration only
  double rate = 0;                 // open loop: requests per second over all connections; 0: closed loop
  std::string arrivals = "uniform";
  unsigned window = 0;  // open loop: unanswered requests per connection; 0: the server's max_in_flight
  std::string cameras = "random";  // random, fixed or a script file
  bool random_focus = true;
  std::string mix = "extract=1";
  double gaze_hz = 0;
  double drain_timeout_s = 10;
  std::uint64_t seed = 1;
  RetryPolicy retry;
  std::uint64_t reconnect_after = 0;  // requests per connection before it is replaced; 0: never
  std::string json_file;
  bool quiet = false;
  bool decode = false;  // decode every payload as a viewer would, and count those that fail

  bool open_loop() const { return rate > 0; }
};

// Registers mtlod-load's flags on `app`, writing into `options` and `flags`.
void add_load_flags(CLI::App& app, LoadOptions& options, clients::ExtractFlags& flags);

// After parsing: fills the defaults that depend on other flags (mtlod-load's criteria, --gaze-hz's
// mix and rate, the model when no scene is given) and reads what the flags name (the camera script,
// the scene files). Errors name the flag, or the file and its line or field.
Result<RequestSettings> complete_load_options(LoadOptions& options, clients::ExtractFlags& flags);

}  // namespace mtlod::clients

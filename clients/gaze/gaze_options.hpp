// mtlod-gaze's command line: the flags, and the criteria it defaults to.
#pragma once

#include <string>
#include <vector>

#include "clients/common/extract_flags.hpp"
#include "clients/common/retry.hpp"
#include "clients/gaze/trace.hpp"
#include "protocol/messages.hpp"

namespace CLI {
class App;
}

namespace mtlod::clients {

struct GazeOptions {
  Endpoint endpoint;
  std::string model = "bunny";
  // --scene: a scene file ({"instances": [{"model", "matrix"}, ...]}) whose view every stream opens
  // instead of the model's; `scene` holds its instances once read (read_gaze_scene).
  std::string scene_file;
  std::vector<protocol::Instance> scene;
  // CSV files (time_ms,x,y) or folders of them; stream k plays trace k mod n. None: each stream
  // synthesises one.
  std::vector<std::string> trace_paths;
  SynthesisOptions synthesis;   // stream k uses seed + k
  unsigned streams = 1;         // concurrent gaze streams, one connection each
  double drain_timeout_s = 10;  // after the trace's end, for the outstanding replies
  RetryPolicy retry;
  std::string json_file;
  bool quiet = false;
  std::string write_trace;  // write the first stream's trace as CSV to this file and exit
};

// After parsing: with --scene, reads the file into options.scene. Errors name the file and the field.
Status read_gaze_scene(GazeOptions& options);

// What the streams look at, for the report: "bunny", or "scene FILE (N instances)".
std::string describe_view(const GazeOptions& options);

// A description of the traces for the report: the paths given, or the synthesis' rate and length.
std::string describe_traces(const GazeOptions& options);

// Registers mtlod-gaze's flags on `app`, writing into `options` and `flags`.
void add_gaze_flags(CLI::App& app, GazeOptions& options, clients::ExtractFlags& flags);

// After parsing: mtlod-gaze's criteria where the flags leave them open (clients::apply_default_criteria;
// given other criteria but no focus, a step law ×0.1 within 20 px of the gaze).
void complete_gaze_flags(clients::ExtractFlags& flags);

// After parsing: the synthesised viewport's shape from --viewport, and the synthesis options
// checked. Errors name the flags at fault.
Status complete_synthesis(GazeOptions& options, const clients::ExtractFlags& flags);

}  // namespace mtlod::clients

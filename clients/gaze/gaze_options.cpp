// mtlod-gaze's flags (see gaze_options.hpp).
#include "clients/gaze/gaze_options.hpp"

#include "CLI/CLI.hpp"

namespace mtlod::clients {

void add_gaze_flags(CLI::App& app, GazeOptions& o, clients::ExtractFlags& flags) {
  // Registered in the order --help lists them.
  add_endpoint_flags(app, o.endpoint);
  app.add_option("--model", o.model, "model name")->capture_default_str();
  app.add_option("--trace", o.trace_file,
                 "CSV trace: time_ms,x,y per line (x, y normalised, 0,0 top left); "
                 "without it a trace is synthesised");
  app.add_option("--hz", o.synthesis.rate_hz, "synthesised trace: samples per second")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 10000.0));
  app.add_option("-d,--duration", o.synthesis.duration_ms, "synthesised trace: length in ms")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 86400e3));
  app.add_option("--seed", o.synthesis.seed, "synthesised trace: random seed (stream k uses seed + k)")
      ->capture_default_str();
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

}  // namespace mtlod::clients

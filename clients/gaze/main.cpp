// mtlod-gaze: replays eye-tracker gaze against mtlod-server and measures gaze-to-mesh
// latency: from a sample's timestamp (its due time in the replay, so a late send counts) to the
// arrival of the mesh reply that reflects it. Gaze updates the server coalesced away are counted;
// each sample's wait for a mesh showing it or a newer sample is reported too. With --delta each
// stream applies its replies on a thread of its own, so decoding one reply never delays the arrival
// time taken for the next; gaze-to-applied (the mesh decoded into the client's copy) is reported
// too. A dropped connection is reopened with backoff; the view's extract and the newest unanswered
// sample are sent again (older samples are stale: the newest one supersedes them, as the server's
// coalescing would). Samples where the tracker lost the eye (blinks) are not sent: the server keeps
// the last gaze; the report counts them. With --scene every stream views a scene file's instances
// instead of one model (PROTOCOL.md, "Scenes"): its gazes move the scene's focus, and with --delta
// each instance's mesh is kept and checked on its own.
#include <cstdio>
#include <string>

#include "CLI/CLI.hpp"
#include "clients/gaze/gaze_options.hpp"
#include "clients/gaze/gaze_replay.hpp"
#include "clients/gaze/gaze_report.hpp"
#include "clients/gaze/trace_file.hpp"
#include "fmt/format.h"

namespace {

int fail(const std::string& message) {
  fmt::print(stderr, "mtlod-gaze: {}\n", message);
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace mtlod;
  CLI::App app{
      "mtlod-gaze: replay gaze traces (CSV time_ms,x,y) or synthetic ones against mtlod-server and "
      "measure gaze-to-mesh latency."};
  clients::GazeOptions options;
  clients::ExtractFlags flags;
  clients::add_gaze_flags(app, options, flags);
  CLI11_PARSE(app, argc, argv);
  clients::complete_gaze_flags(flags);

  if (auto checked = clients::complete_synthesis(options, flags); !checked)
    return fail(checked.error().message);
  if (auto scene = clients::read_gaze_scene(options); !scene) return fail(scene.error().message);

  auto file_traces = clients::read_trace_files(options.trace_paths);
  if (!file_traces) return fail(file_traces.error().message);
  if (!options.write_trace.empty()) {
    const auto trace =
        file_traces->empty() ? clients::synthesize_gaze_trace(options.synthesis) : file_traces->front();
    if (auto written = clients::write_trace_file(options.write_trace, trace); !written)
      return fail(written.error().message);
    fmt::print("wrote {} samples to {}\n", trace.size(), options.write_trace);
    return 0;
  }

  clients::GazeTotals totals;
  auto end = clients::run_gaze_replay(options, flags, *file_traces, totals);
  if (!end) return fail(end.error().message);
  if (auto reported = clients::report_gaze(options, flags, totals, *end); !reported)
    return fail(reported.error().message);
  return totals.meshes > 0 ? 0 : 1;
}

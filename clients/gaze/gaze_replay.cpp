// A replay of mtlod-gaze (see gaze_replay.hpp).
#include "clients/gaze/gaze_replay.hpp"

#include <unistd.h>

#include <cstdio>
#include <memory>
#include <thread>

#include "fmt/format.h"

namespace mtlod::clients {
namespace {

using Streams = std::vector<std::unique_ptr<GazeStream>>;

// Every stream opens its view with one extract first; that set-up is not measured.
Status open_streams(GazeReplay& replay, const clients::ExtractFlags& flags,
                    const std::vector<std::vector<GazeSample>>& file_traces, Streams& streams) {
  const GazeOptions& options = replay.options;
  for (unsigned k = 0; k < options.streams; ++k) {
    std::vector<GazeSample> trace;
    if (file_traces.empty()) {
      SynthesisOptions synthesis = options.synthesis;
      synthesis.seed = options.synthesis.seed + k;
      trace = synthesize_gaze_trace(synthesis);
    } else {
      trace = file_traces[k % file_traces.size()];
    }
    streams.push_back(std::make_unique<GazeStream>(replay, k, std::move(trace)));
    MTLOD_RETURN_IF_ERROR(streams.back()->open_view(flags));
  }
  return Ok{};
}

std::size_t outstanding(Streams& streams) {
  std::size_t n = 0;
  for (auto& s : streams) n += s->outstanding();
  return n;
}

// Shows progress on a terminal until every sender has finished and the replies are in, or the
// drain timeout after the longest trace's end passes.
void wait_for_replies(GazeReplay& replay, Streams& streams) {
  double trace_ms = 0;
  for (auto& s : streams) trace_ms = std::max(trace_ms, s->trace().back().time_ms);
  const auto drain_deadline =
      replay.start +
      std::chrono::milliseconds(static_cast<std::int64_t>(trace_ms + replay.options.drain_timeout_s * 1000));
  const bool progress = !replay.options.quiet && ::isatty(STDERR_FILENO);
  GazeTotals& totals = replay.totals;
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (progress) {
      std::lock_guard lock(totals.mutex);
      fmt::print(stderr, "\r{:6.1f} s  samples {:>7}  meshes {:>7}  superseded {:>7}  p99 {:>7.2f} ms   ",
                 nanoseconds_between(replay.start, Clock::now()) / 1e9, totals.sent, totals.meshes,
                 totals.superseded, totals.mesh_latency_us.value_at_percentile(99) / 1e3);
    }
    if (replay.senders_done == streams.size() && outstanding(streams) == 0) break;
    if (Clock::now() >= drain_deadline) break;
  }
  if (progress) fmt::print(stderr, "\n");
}

}  // namespace

Result<GazeReplayEnd> run_gaze_replay(const GazeOptions& options, const clients::ExtractFlags& flags,
                                      const std::vector<std::vector<GazeSample>>& file_traces,
                                      GazeTotals& totals) {
  GazeReplay replay(options, totals);
  Streams streams;
  MTLOD_RETURN_IF_ERROR(open_streams(replay, flags, file_traces, streams));

  replay.start = Clock::now();
  std::vector<std::thread> threads;
  for (auto& s : streams) {
    GazeStream& stream = *s;
    threads.emplace_back([&stream] { stream.receive_replies(); });
    if (flags.delta) threads.emplace_back([&stream] { stream.apply_deltas(); });
    threads.emplace_back([&stream] { stream.send_samples(); });
  }
  wait_for_replies(replay, streams);
  GazeReplayEnd end;
  end.lost = outstanding(streams);
  replay.finished = true;
  for (auto& s : streams) s->session().interrupt();
  for (auto& t : threads) t.join();

  end.elapsed_s = nanoseconds_between(replay.start, Clock::now()) / 1e9;
  for (auto& s : streams) {
    end.reconnects += s->session().reconnects();
    end.resent += s->session().resent();
  }
  return end;
}

}  // namespace mtlod::clients

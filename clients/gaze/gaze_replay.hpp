// A replay of mtlod-gaze: open every stream's view (set-up, not measured), replay the traces on
// their threads, show progress on a terminal, and wait for the outstanding replies.
#pragma once

#include <cstdint>
#include <vector>

#include "clients/common/extract_flags.hpp"
#include "clients/gaze/gaze_options.hpp"
#include "clients/gaze/gaze_stream.hpp"
#include "clients/gaze/trace.hpp"
#include "core/result.hpp"

namespace mtlod::clients {

// What a replay measured besides the totals.
struct GazeReplayEnd {
  double elapsed_s = 0;
  std::uint64_t lost = 0;  // samples sent and not answered by the drain deadline
  std::uint64_t reconnects = 0, resent = 0;
};

// Replays `file_traces` (stream k plays trace k mod n), or without any a trace synthesised per
// stream, recording into `totals`. Errors: set-up failed (a connection, the model, the first extract).
Result<GazeReplayEnd> run_gaze_replay(const GazeOptions& options, const clients::ExtractFlags& flags,
                                      const std::vector<std::vector<GazeSample>>& file_traces,
                                      GazeTotals& totals);

}  // namespace mtlod::clients

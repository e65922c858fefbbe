// A run of mtlod-load: connect every connection and look the models up (set-up, not measured), run
// the senders and receivers, show progress on a terminal, and wait for the outstanding replies.
#pragma once

#include <cstdint>

#include "clients/common/extract_flags.hpp"
#include "clients/load/load_options.hpp"
#include "clients/load/load_stream.hpp"
#include "core/result.hpp"

namespace mtlod::clients {

// What a run measured besides the totals.
struct LoadRunEnd {
  double elapsed_s = 0;      // of sending, or until the last reply when that came later
  std::uint64_t lost = 0;    // requests sent and never answered
  std::uint64_t unsent = 0;  // due requests the window held back past the end of the test
  std::uint64_t reconnects = 0, retried = 0, gave_up = 0;
};

// Runs the load test the options describe, recording into `totals`. Errors: set-up failed (a
// connection, a model that is not served, a scene naming one, an extract the flags cannot make).
Result<LoadRunEnd> run_load(const LoadOptions& options, const RequestSettings& requests,
                            const clients::ExtractFlags& flags, LoadTotals& totals);

}  // namespace mtlod::clients

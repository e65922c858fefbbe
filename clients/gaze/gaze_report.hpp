// mtlod-gaze's report: a text summary on stdout and, with --json, the same numbers as JSON.
#pragma once

#include "clients/common/extract_flags.hpp"
#include "clients/gaze/gaze_options.hpp"
#include "clients/gaze/gaze_replay.hpp"
#include "clients/gaze/gaze_stream.hpp"
#include "core/result.hpp"

namespace mtlod::clients {

// Prints the report, and writes it to options.json_file when one is given. Errors: the file could
// not be written.
Status report_gaze(const GazeOptions& options, const clients::ExtractFlags& flags, const GazeTotals& totals,
                   const GazeReplayEnd& end);

}  // namespace mtlod::clients

// Gaze trace files for mtlod-gaze: --trace reads one, --write-trace writes one (CSV time_ms,x,y).
#pragma once

#include <string>
#include <vector>

#include "clients/gaze/trace.hpp"
#include "core/result.hpp"

namespace mtlod::clients {

// The trace in the file at `path`; empty when `path` is. Errors name the file.
Result<std::vector<GazeSample>> read_trace_file(const std::string& path);

// Writes `trace` with a header line, times to the microsecond. Errors name the file.
Status write_trace_file(const std::string& path, const std::vector<GazeSample>& trace);

}  // namespace mtlod::clients

// Gaze trace files for mtlod-gaze: --trace reads them, --write-trace writes one (CSV time_ms,x,y).
#pragma once

#include <string>
#include <vector>

#include "clients/gaze/trace.hpp"
#include "core/result.hpp"

namespace mtlod::clients {

// The trace in the file at `path`. Errors name the file (and the line).
Result<std::vector<GazeSample>> read_trace_file(const std::string& path);

// The traces at `paths`, in their order: a file is one trace, a folder every *.csv file in it, in
// sorted name order. Errors name the file or folder: one missing, a folder with no .csv file, a
// trace that does not parse.
Result<std::vector<std::vector<GazeSample>>> read_trace_files(const std::vector<std::string>& paths);

// Writes `trace` with a header line (format_gaze_sample per sample). Errors name the file.
Status write_trace_file(const std::string& path, const std::vector<GazeSample>& trace);

}  // namespace mtlod::clients

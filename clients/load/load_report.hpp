// mtlod-load's report: a text summary on stdout and, with --json, the same numbers as JSON.
#pragma once

#include "clients/common/extract_flags.hpp"
#include "clients/load/load_options.hpp"
#include "clients/load/load_run.hpp"
#include "clients/load/load_stream.hpp"
#include "core/result.hpp"

namespace mtlod::clients {

// Prints the report, and writes it to options.json_file when one is given. Errors: the file could
// not be written.
Status report_load(const LoadOptions& options, const clients::ExtractFlags& flags, const LoadTotals& totals,
                   const LoadRunEnd& end);

}  // namespace mtlod::clients

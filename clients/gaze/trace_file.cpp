// Gaze trace files (see trace_file.hpp).
#include "clients/gaze/trace_file.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "fmt/format.h"

namespace mtlod::clients {
namespace {

namespace fs = std::filesystem;

// The *.csv files in `folder`, sorted by name. Errors: it cannot be listed, or holds none.
Result<std::vector<std::string>> csv_files_in(const std::string& folder) {
  std::error_code error;
  std::vector<std::string> files;
  for (fs::directory_iterator it(folder, error), end; !error && it != end; it.increment(error)) {
    if (it->path().extension() == ".csv" && it->is_regular_file(error)) files.push_back(it->path().string());
  }
  if (error)
    return make_error(ErrorCode::kIoError, fmt::format("{}: cannot list: {}", folder, error.message()));
  if (files.empty())
    return make_error(ErrorCode::kNotFound, fmt::format("{}: no .csv trace in the folder", folder));
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace

Result<std::vector<GazeSample>> read_trace_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) return make_error(ErrorCode::kIoError, fmt::format("{}: cannot read", path));
  std::stringstream text;
  text << in.rdbuf();
  auto parsed = parse_gaze_trace(text.str());
  if (!parsed) return make_error(parsed.error().code, fmt::format("{}: {}", path, parsed.error().message));
  return parsed;
}

Result<std::vector<std::vector<GazeSample>>> read_trace_files(const std::vector<std::string>& paths) {
  std::vector<std::vector<GazeSample>> traces;
  for (const std::string& path : paths) {
    std::vector<std::string> files{path};
    std::error_code ignored;
    if (fs::is_directory(path, ignored)) {
      MTLOD_TRY(files, csv_files_in(path));
    }
    for (const std::string& file : files) {
      MTLOD_TRY(std::vector<GazeSample> trace, read_trace_file(file));
      traces.push_back(std::move(trace));
    }
  }
  return traces;
}

Status write_trace_file(const std::string& path, const std::vector<GazeSample>& trace) {
  std::ofstream out(path);
  out << "time_ms,x,y\n";
  for (const auto& s : trace) out << format_gaze_sample(s) << '\n';
  if (!out) return make_error(ErrorCode::kIoError, fmt::format("{}: write failed", path));
  return Ok{};
}

}  // namespace mtlod::clients

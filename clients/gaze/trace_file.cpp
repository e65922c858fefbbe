// Gaze trace files (see trace_file.hpp).
#include "clients/gaze/trace_file.hpp"

#include <fstream>
#include <sstream>

#include "fmt/format.h"

namespace mtlod::clients {

Result<std::vector<GazeSample>> read_trace_file(const std::string& path) {
  if (path.empty()) return std::vector<GazeSample>{};
  std::ifstream in(path);
  if (!in) return make_error(ErrorCode::kIoError, fmt::format("{}: cannot read", path));
  std::stringstream text;
  text << in.rdbuf();
  auto parsed = parse_gaze_trace(text.str());
  if (!parsed) return make_error(parsed.error().code, fmt::format("{}: {}", path, parsed.error().message));
  return parsed;
}

Status write_trace_file(const std::string& path, const std::vector<GazeSample>& trace) {
  std::ofstream out(path);
  out << "time_ms,x,y\n";
  for (const auto& s : trace) out << fmt::format("{:.3f},{:.5f},{:.5f}\n", s.time_ms, s.x, s.y);
  if (!out) return make_error(ErrorCode::kIoError, fmt::format("{}: write failed", path));
  return Ok{};
}

}  // namespace mtlod::clients

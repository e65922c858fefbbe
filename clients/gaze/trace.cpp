// Gaze traces (see trace.hpp).
#include "clients/gaze/trace.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>

#include "clients/common/extract_flags.hpp"
#include "fmt/format.h"

namespace mtlod::clients {

Result<std::vector<GazeSample>> parse_gaze_trace(const std::string& text) {
  std::vector<GazeSample> samples;
  std::stringstream in(text);
  std::string line;
  for (std::size_t number = 1; std::getline(in, line); ++number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const auto first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    std::vector<double> v;
    if (!clients::parse_number_list(line, v) || v.size() != 3) {
      if (samples.empty() && number == 1) continue;  // a header line such as "time_ms,x,y"
      return make_error(ErrorCode::kInvalidArgument,
                        fmt::format("line {}: expected time_ms,x,y, got '{}'", number, line));
    }
    if (v[1] < 0 || v[1] > 1 || v[2] < 0 || v[2] > 1) {
      return make_error(ErrorCode::kInvalidArgument,
                        fmt::format("line {}: x and y must lie in 0..1, got {}, {}", number, v[1], v[2]));
    }
    if (v[0] < 0 || (!samples.empty() && v[0] < samples.back().time_ms)) {
      return make_error(ErrorCode::kInvalidArgument,
                        fmt::format("line {}: time {} ms goes backwards", number, v[0]));
    }
    samples.push_back(GazeSample{v[0], v[1], v[2]});
  }
  if (samples.empty()) return make_error(ErrorCode::kInvalidArgument, "the trace holds no sample");
  return samples;
}

std::vector<GazeSample> synthesize_gaze_trace(const SynthesisOptions& o) {
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> point(0.1, 0.9);
  std::uniform_real_distribution<double> fixation(o.fixation_min_ms, o.fixation_max_ms);
  std::normal_distribution<double> noise(0.0, o.jitter);
  // Segments: a fixation at `from`, then a saccade from `from` to `to`.
  double from_x = point(rng), from_y = point(rng), to_x = point(rng), to_y = point(rng);
  double fixation_end = fixation(rng);
  auto saccade_length = [&] {
    return std::max(o.saccade_min_ms, o.saccade_ms_per_unit * std::hypot(to_x - from_x, to_y - from_y));
  };
  double saccade_end = fixation_end + saccade_length();
  std::vector<GazeSample> samples;
  const double step_ms = 1000.0 / o.rate_hz;
  for (std::uint64_t i = 0;; ++i) {
    const double t = static_cast<double>(i) * step_ms;
    if (t >= o.duration_ms) break;
    while (t >= saccade_end) {  // next fixation at the saccade's target
      from_x = to_x, from_y = to_y;
      to_x = point(rng), to_y = point(rng);
      fixation_end = saccade_end + fixation(rng);
      saccade_end = fixation_end + saccade_length();
    }
    double x = from_x, y = from_y;
    if (t < fixation_end) {
      x += noise(rng), y += noise(rng);
    } else {
      const double s = (t - fixation_end) / (saccade_end - fixation_end);
      const double w = s * s * (3 - 2 * s);
      x = from_x + (to_x - from_x) * w;
      y = from_y + (to_y - from_y) * w;
    }
    samples.push_back(GazeSample{t, std::clamp(x, 0.0, 1.0), std::clamp(y, 0.0, 1.0)});
  }
  return samples;
}

}  // namespace mtlod::clients

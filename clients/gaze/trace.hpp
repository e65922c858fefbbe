// Gaze traces for mtlod-gaze: samples of where a viewer looks (time in ms, x and y in normalised
// viewport coordinates, 0,0 top left), read from CSV or synthesised as fixations joined by saccades.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/result.hpp"

namespace mtlod::clients {

struct GazeSample {
  double time_ms = 0;
  double x = 0.5;
  double y = 0.5;
};

// Reads "time_ms,x,y" lines; a first line that is not numeric is a header, blank lines and '#'
// comments are skipped. Times must not decrease and x, y must lie in 0..1; errors name the line.
Result<std::vector<GazeSample>> parse_gaze_trace(const std::string& text);

struct SynthesisOptions {
  double rate_hz = 120;  // samples per second (eye trackers: 60..1000)
  double duration_ms = 10'000;
  double fixation_min_ms = 150;  // fixations last 150..400 ms (typical reading and scene viewing)
  double fixation_max_ms = 400;
  double saccade_ms_per_unit = 100;  // a saccade across the whole viewport takes about 100 ms
  double saccade_min_ms = 20;
  double jitter = 0.002;  // fixational noise, normalised units (standard deviation)
  std::uint64_t seed = 1;
};

// Fixations at random points within [0.1, 0.9]² joined by saccades (smoothstep motion), sampled
// at rate_hz from time 0 up to duration_ms (excluded). Every sample lies within 0..1.
std::vector<GazeSample> synthesize_gaze_trace(const SynthesisOptions& options);

}  // namespace mtlod::clients

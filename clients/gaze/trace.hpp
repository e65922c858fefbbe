// Gaze traces for mtlod-gaze: samples of where a viewer looks (time in ms, x and y in normalised
// viewport coordinates, 0,0 top left), read from CSV or synthesised as fixations, saccades, smooth
// pursuit and blinks.
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
  bool tracked = true;  // false: the tracker lost the eye (a blink); x and y mean nothing
};

// Reads "time_ms,x,y" lines; a first line that is not a sample is a header, blank lines and '#'
// comments are skipped. "time_ms,," and "time_ms,nan,nan" are samples where the tracker lost the eye.
// Times must not decrease, x and y must lie in 0..1 and at least one sample must have a gaze; errors
// name the line.
Result<std::vector<GazeSample>> parse_gaze_trace(const std::string& text);

// The CSV line of `sample`, without the newline: times to the microsecond, a lost sample as "time_ms,,".
std::string format_gaze_sample(const GazeSample& sample);

struct SynthesisOptions {
  double rate_hz = 120;  // samples per second (eye trackers: 60..1000)
  double duration_ms = 10'000;
  // The viewport as the viewer sees it: its width in degrees of visual angle, and width / height.
  double screen_deg = 40;
  double aspect = 4.0 / 3.0;
  // What follows a fixation: smooth pursuit, a blink, or else a saccade to the next fixation.
  double pursuit_share = 0.2;
  double blink_share = 0.1;
  double fixation_min_ms = 150;  // fixations last 150..400 ms (typical reading and scene viewing)
  double fixation_max_ms = 400;
  // Saccade amplitudes; durations follow the main sequence, ms_per_deg × amplitude + base_ms.
  double saccade_min_deg = 1;
  double saccade_max_deg = 15;
  double saccade_ms_per_deg = 2.2;
  double saccade_base_ms = 21;
  // Smooth pursuit of a target moving at a constant velocity; the eye follows at `pursuit_gain` of
  // its speed and makes a catch-up saccade whenever it falls `catch_up_deg` behind (gain 1: never).
  double pursuit_min_deg_s = 5;
  double pursuit_max_deg_s = 30;
  double pursuit_min_ms = 300;
  double pursuit_max_ms = 1500;
  double pursuit_gain = 0.95;
  double catch_up_deg = 1;
  double blink_min_ms = 100;  // the tracker reports no gaze for 100..400 ms
  double blink_max_ms = 400;
  // Noise on every sample (tracker and tremor, standard deviation per axis), and the slow drift of
  // a fixation (a random walk: its standard deviation after one second); saccades undo the drift.
  double jitter_deg = 0.03;
  double drift_deg = 0.2;
  std::uint64_t seed = 1;
};

// Errors: shares outside 0..1 or summing above 1, a rate, duration, screen or range that is empty
// or not positive. The message names the option.
Status check_synthesis_options(const SynthesisOptions& options);

// A trace that starts with a fixation within [0.1, 0.9]², sampled at rate_hz from time 0 up to
// duration_ms (excluded); deterministic for a seed. Every tracked sample lies within 0..1.
std::vector<GazeSample> synthesize_gaze_trace(const SynthesisOptions& options);

}  // namespace mtlod::clients

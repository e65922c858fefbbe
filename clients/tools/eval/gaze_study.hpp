// mtlod-eval gaze: a gaze study in numbers. A fixation/saccade trace (a file, or mtlod-gaze's
// synthesiser) is replayed against one view of a model: every frame shows the budgeted cut the
// default criteria (clients::apply_default_criteria) gave for the gaze sample that had reached the
// viewer `latency` ms earlier, and is scored by the foveated image error around where the eye is
// at that frame, against one uniform cut of about the same bytes. After each saccade (I-VT
// velocity threshold), the time until the error near the new fixation is back within a tolerance
// of its settled value.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace mtlod::eval_tool {

struct GazeStudyOptions {
  std::vector<std::string> meshes;  // NAME=PATH
  std::string trace;                // CSV time_ms,x,y (mtlod-gaze's format); empty: synthesised
  double duration_ms = 3000;        // of the synthesised trace
  double hz = 120;                  // its sample rate, and the display's frame rate
  std::uint64_t seed = 1;
  std::vector<double> latencies_ms{0, 8, 16, 50};  // gaze sample to mesh on screen
  std::size_t budget = 16000;
  std::uint32_t image_px = 512, grid_px = 256;
  double near_deg = 4.6;          // "near the fixation": within 2·e2 of the gaze
  double settle_tolerance = 0.1;  // back within 10 % of the fixation's settled error
  double saccade_deg_per_s = 60;  // I-VT threshold (Salvucci and Goldberg 2000)
  std::string out_dir = "tests/evaluation";
  std::string report = "GAZE.md", csv = "gaze.csv";
  std::string cache_dir = "build/eval-cache";
  std::vector<std::string> notes;
};

int run_gaze_study(const GazeStudyOptions& options, const std::string& command);

}  // namespace mtlod::eval_tool

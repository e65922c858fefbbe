// mtlod-eval score: two renderings that arrive as PNG files (screenshots of the browser viewer,
// tests/evaluation/viewer_study.mjs) scored as FIDELITY.md scores the internal renderer's images:
// the foveated error 1 − foveated SSIM and the other scores of core/eval/image_metrics, through
// core::compare_rgb_renderings. Prints one JSON object on standard output.
#pragma once

#include <string>
#include <vector>

namespace mtlod::eval_tool {

struct ScoreOptions {
  std::string reference, candidate;  // PNG files of one size: the full model's rendering and the cut's
  std::vector<double> focus;         // X,Y normalised (0..1, from the top left); empty: the centroid of
                                     // the reference's coverage (FIDELITY.md's gaze on the object)
  double fov_deg = 40.0;             // vertical field of view the images were rendered with
  double viewing_distance_px = 0;    // eye to image in pixels; 0: the camera's centre of projection
  double e2_deg = 2.3;               // eccentricity at which acuity halves
  std::string background;            // RRGGBB hex; empty: the reference's top-left pixel
};

// Exit status: 0 scored, 1 an unreadable file, 2 bad options or images of different sizes.
int run_score(const ScoreOptions& options);

}  // namespace mtlod::eval_tool

// mtlod-eval fidelity: what a viewer sees, per triangle and per byte. Every method's cut of a model is
// rendered from orbit cameras, shaded with the model's normals, and compared with the full model's
// rendering by image metrics (core/eval/image_metrics), at equal triangle counts and at equal Draco
// payload sizes. The methods are budgeted refinements of one Multi-Tessellation under different
// criteria, plus meshoptimizer's simplifier; the report says how the target method fares against
// uniform and meshoptimizer on the foveated error (1 − foveated SSIM).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace mtlod::eval_tool {

struct FidelityOptions {
  std::vector<std::string> meshes;  // NAME=PATH
  std::vector<std::size_t> budgets{1000, 4000, 16000, 64000};
  int cameras = 8;
  std::uint32_t image_px = 512;  // rendered images (square), pixels
  std::uint32_t grid_px = 256;   // the view grid of the distance transforms (the server's default)
  // NAME=SPEC, in order; empty: the study's standard set (uniform, silhouette-DT, focus-DT, the
  // viewer's former criteria, the default, meshopt). SPEC is `uniform`, `meshopt`, or criteria (see
  // parse_criteria in fidelity.cpp and FIDELITY.md).
  std::vector<std::string> methods;
  std::string target = "default";  // the method the targets are about
  bool equal_triangles = true;     // also compare at equal triangle counts (equal bytes always)
  bool curves = true;              // an error-against-bytes plot per mesh (figures/fidelity-NAME-curves.svg)
  std::string out_dir = "tests/evaluation";
  std::string report = "FIDELITY.md";  // file names inside out_dir
  std::string csv = "fidelity.csv";
  std::string cache_dir = "build/eval-cache";
  // The equal-bytes cuts of uniform, the target and meshopt are also scored from the camera turned by
  // each of these angles (degrees about the model's vertical axis): a stale cut while the view orbits.
  std::vector<double> turns{5, 15, 45};
  std::vector<std::string> figure_meshes;  // side-by-side renders and difference images
  std::vector<std::string> notes;          // extra lines for the report's setup section
};

// Runs the study and writes out_dir/report, out_dir/csv and out_dir/figures/fidelity-*. `command`
// is quoted in the report. Returns the process exit code.
int run_fidelity(const FidelityOptions& options, const std::string& command);

}  // namespace mtlod::eval_tool

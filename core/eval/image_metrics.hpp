// Image-space quality of a simplification: the full-resolution model and a cut are
// rendered from one camera (core/eval/render, shaded with the model's normals) and the two shaded
// images are compared as single-channel luminance images:
//
// - SSIM, the structural similarity index of Wang, Bovik, Sheikh and Simoncelli, "Image quality
//   assessment: from error visibility to structural similarity", IEEE Trans. Image Processing 13(4),
//   2004, pp. 600–612: local means, variances and covariance under an 11×11 Gaussian window of
//   σ = 1.5 (normalised), K1 = 0.01, K2 = 0.03, L the dynamic range, and the mean over the windows
//   (their MSSIM). As in the authors' reference code only windows that lie wholly inside the
//   image are used, so the map is (W − 10)×(H − 10); map entry (i, j) is the window centred on pixel
//   (i + 5, j + 5).
// - The mean absolute error of the pixels (MAE), over the whole image or over a mask.
// - Foveated variants: each pixel (or window, by its centre pixel) weighted by the relative acuity at
//   its eccentricity from the focus point. Acuity follows the linear law of the minimum angle of
//   resolution, MAR(e) = MAR0·(1 + e/e2) (Levi, Klein and Aitsebaomo, "Vernier acuity, crowding and
//   cortical magnification", Vision Research 25(7), 1985, pp. 963–977), with e2 = 2.3° from Geisler
//   and Perry, "A real-time foveated multiresolution system for low-bandwidth video communication",
//   Proc. SPIE 3299, 1998, pp. 294–305: their contrast threshold CT(f, e) = CT0·exp(α·f·(e + e2)/e2)
//   puts the highest visible frequency at fc(e) ∝ e2/(e2 + e). The weight is that relative acuity,
//   w(e) = MAR0/MAR(e) = fc(e)/fc(0) = e2/(e2 + e): 1 at the focus, ½ at e2, ~0.1 at 20°. The same
//   law and e2 drive the server's kFoveal falloff (core/view/allowed_error.hpp).
//
// Eccentricity needs a viewing geometry. Here the viewer's eye sits on the axis through the image
// centre at focal_px pixels from the image plane: the angle between the rays through the focus and
// through a pixel centre is the eccentricity, exactly (no small-angle approximation). The natural
// choice is the camera's own centre of projection, focal_px = (H/2)/tan(fovy/2) (focal_px_from_fov):
// the screen seen under the field of view it was rendered with. A real display viewed from d pixels
// away gives focal_px = d.
//
// Images are W×H floats, row-major, top row first (like the view grid), values in [0, L]. Pure
// functions; the SSIM keeps a small ring of filtered rows, never a whole filtered image.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "core/view/grid.hpp"

namespace mtlod::core::eval {

// Luma of 8-bit RGB pixels (3 bytes each) in [0, 1]: Y' = (0.299·R' + 0.587·G' + 0.114·B')/255 on the
// stored (gamma-encoded) values, the ITU-R BT.601 weights that JPEG/JFIF and MATLAB's rgb2gray use.
// SSIM is defined on such display values (Wang et al. test on 8-bit greyscale images), so L = 1.
// luminance holds rgb.size()/3 entries.
void luminance_from_rgb(std::span<const std::uint8_t> rgb, std::span<float> luminance);

struct SsimOptions {
  double dynamic_range = 1.0;       // L: the range of the pixel values (1 for luminance_from_rgb's)
  double k1 = 0.01;                 // C1 = (K1·L)², the paper's stabilising constants
  double k2 = 0.03;                 // C2 = (K2·L)²
  std::uint32_t window_radius = 5;  // the window is (2r + 1)² pixels: 11×11 in the paper
  double sigma_px = 1.5;            // of the circular-symmetric Gaussian weighting
};

// Size of the SSIM map of a size-pixel image: (W − 2r) × (H − 2r). The image must be at least one
// window large (W, H ≥ 2r + 1).
view::GridSize ssim_map_size(view::GridSize size, const SsimOptions& options = {});

// SSIM of images a and b (size.cell_count() entries each): writes the map, when not empty
// (ssim_map_size(size).cell_count() entries), and returns its mean (MSSIM). Identical images give
// exactly 1: the per-window terms are formed so that equal inputs make numerator and denominator
// bit-identical. Filtering is separable and in double precision, O(W·H·r).
double ssim(std::span<const float> a, std::span<const float> b, view::GridSize size,
            std::span<float> map = {}, const SsimOptions& options = {});

// Which pixels count and how much. Both parts are optional; a pixel's weight is
// (mask empty or mask ≠ 0) · (weights empty ? 1 : weights). Either span has one entry per pixel.
struct PixelWeights {
  std::span<const std::uint8_t> mask;  // e.g. pixels covered by either rendering
  std::span<const float> weights;      // e.g. foveation_weights; non-negative
};

// Weighted mean of an SSIM map of a size-pixel image, each window weighted by the weight of its
// centre pixel. With no weight at all (an empty mask) the images agree wherever they are compared,
// and the result is 1.
double weighted_ssim(std::span<const float> map, view::GridSize size, const PixelWeights& weighting,
                     const SsimOptions& options = {});

// Weighted mean of |a − b| over the pixels (a and b of one size): Σ w·|a − b| / Σ w. Unweighted, every
// pixel counts, so identical background dilutes the mean by the share of the image the model
// covers; a coverage mask measures the model's pixels only. No weight at all gives 0.
double mean_absolute_error(std::span<const float> a, std::span<const float> b,
                           const PixelWeights& weighting = {});

// The viewing geometry and acuity law of the foveated metrics.
struct Foveation {
  float focus_x_px = 0.0f;  // the focus in continuous pixel coordinates: pixel (i, j) covers
  float focus_y_px = 0.0f;  // [i, i+1) × [j, j+1), so the centre of pixel (i, j) is (i + ½, j + ½)
  double focal_px = 1.0;    // distance from the eye to the image plane, pixels (focal_px_from_fov)
  double e2_deg = 2.3;      // eccentricity at which acuity halves (Geisler and Perry 1998)
};

// The camera's centre of projection for an image height_px tall seen under a vertical field of view
// of fovy_deg degrees: (height_px/2) / tan(fovy/2).
double focal_px_from_fov(std::uint32_t height_px, double fovy_deg);

// Eccentricity in degrees of the point (x_px, y_px) of a size-pixel image: the angle at the eye
// between the rays through it and through the focus, the eye on the axis through the image centre
// (W/2, H/2). 0 exactly at the focus itself.
double pixel_eccentricity_deg(view::GridSize size, const Foveation& foveation, double x_px, double y_px);

// Relative acuity at eccentricity e degrees: e2/(e2 + e); 1 at e = 0.
inline double acuity_weight(double e_deg, double e2_deg) {
  return e2_deg / (e2_deg + e_deg);
}

// Acuity weight of every pixel centre: weights holds size.cell_count() entries.
void foveation_weights(view::GridSize size, const Foveation& foveation, std::span<float> weights);

// Every image-space score of a pair of renderings, computed from one SSIM map.
struct ImageComparison {
  double ssim = 1.0;           // mean over every window (the paper's MSSIM)
  double ssim_covered = 1.0;   // over windows centred on a covered pixel
  double foveated_ssim = 1.0;  // over windows centred on a covered pixel, weighted by acuity
  double mae = 0.0;            // over every pixel
  double mae_covered = 0.0;    // over covered pixels
  double foveated_mae = 0.0;   // over covered pixels, weighted by acuity
  std::size_t covered_pixels = 0;
};

// Compares luminance images a and b of one size. covered marks the pixels either rendering covers
// (empty: every pixel); weights are the acuity weights of foveation_weights (empty: all 1, and the
// foveated values equal the covered ones). map is scratch of ssim_map_size(size).cell_count() floats,
// and holds the SSIM map afterwards.
ImageComparison compare_images(std::span<const float> a, std::span<const float> b, view::GridSize size,
                               std::span<const std::uint8_t> covered, std::span<const float> weights,
                               std::span<float> map, const SsimOptions& options = {});

// Renderings that arrive as pictures (screenshots of the viewer): a pixel is covered when it differs
// from the background colour in a, in b, or both. covered holds a_rgb.size()/3 entries (1 covered,
// 0 not); returns how many are covered. Antialiased edge pixels, blends of model and background,
// count as covered.
std::size_t coverage_from_background(std::span<const std::uint8_t> a_rgb, std::span<const std::uint8_t> b_rgb,
                                     const std::array<std::uint8_t, 3>& background,
                                     std::span<std::uint8_t> covered);

// Two 8-bit RGB renderings of one size-pixel view compared as the studies compare their own
// renderings: luma (luminance_from_rgb), covered = coverage_from_background, acuity weights of
// `foveation` (foveation_weights), then compare_images. Allocates its scratch: for tools, not loops.
ImageComparison compare_rgb_renderings(std::span<const std::uint8_t> a_rgb,
                                       std::span<const std::uint8_t> b_rgb, view::GridSize size,
                                       const std::array<std::uint8_t, 3>& background,
                                       const Foveation& foveation, const SsimOptions& options = {});

}  // namespace mtlod::core::eval

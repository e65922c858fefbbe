// SSIM, mean absolute error and their foveated variants (see image_metrics.hpp).
#include "core/eval/image_metrics.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>
#include <vector>

namespace mtlod::core::eval {
namespace {

double radians_to_degrees(double r) {
  return r * (180.0 / std::numbers::pi);
}

// Weight of pixel c under a PixelWeights (1 when both parts are empty).
double pixel_weight(const PixelWeights& w, std::size_t c) {
  if (!w.mask.empty() && w.mask[c] == 0) return 0.0;
  return w.weights.empty() ? 1.0 : double(w.weights[c]);
}

}  // namespace

void luminance_from_rgb(std::span<const std::uint8_t> rgb, std::span<float> luminance) {
  assert(rgb.size() == 3 * luminance.size());
  for (std::size_t c = 0; c < luminance.size(); ++c)
    luminance[c] = float((0.299 * rgb[3 * c] + 0.587 * rgb[3 * c + 1] + 0.114 * rgb[3 * c + 2]) / 255.0);
}

view::GridSize ssim_map_size(view::GridSize size, const SsimOptions& options) {
  const std::uint32_t side = 2 * options.window_radius + 1;
  assert(size.width >= side && size.height >= side);
  (void)side;
  return {size.width - 2 * options.window_radius, size.height - 2 * options.window_radius};
}

double ssim(std::span<const float> a, std::span<const float> b, view::GridSize size, std::span<float> map,
            const SsimOptions& options) {
  assert(a.size() == size.cell_count() && b.size() == a.size());
  assert(options.dynamic_range > 0 && options.k1 > 0 && options.k2 > 0 && options.sigma_px > 0);
  const view::GridSize out = ssim_map_size(size, options);
  assert(map.empty() || map.size() == out.cell_count());
  const std::size_t r = options.window_radius, n = 2 * r + 1, w = size.width, mw = out.width;
  const double c1 = (options.k1 * options.dynamic_range) * (options.k1 * options.dynamic_range);
  const double c2 = (options.k2 * options.dynamic_range) * (options.k2 * options.dynamic_range);

  // The 2D Gaussian window normalised to sum 1 is the outer product of the normalised 1D one, so
  // the window sums are a horizontal pass followed by a vertical one.
  std::vector<double> g(n);
  double g_sum = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const double x = double(k) - double(r);
    g_sum += g[k] = std::exp(-x * x / (2 * options.sigma_px * options.sigma_px));
  }
  for (double& v : g) v /= g_sum;

  // Per row: a, b, a·b and (a − b)² in double, then their horizontal window sums, kept in a ring of
  // n rows for the vertical pass. The window sums of x², y² are not needed: with D = E[(a − b)²],
  // σa² + σb² = 2σab + D − (μa − μb)², which makes the denominators of equal windows equal to their
  // numerators bit for bit (SSIM exactly 1) and spares two of the usual five filtered images.
  enum { kA, kB, kAB, kDD, kTerms };
  std::vector<double> row(kTerms * w);
  std::vector<double> ring(n * kTerms * mw);
  double sum = 0;
  for (std::size_t y = 0; y < size.height; ++y) {
    for (std::size_t x = 0; x < w; ++x) {
      const double av = a[y * w + x], bv = b[y * w + x], d = av - bv;
      row[kA * w + x] = av, row[kB * w + x] = bv, row[kAB * w + x] = av * bv, row[kDD * w + x] = d * d;
    }
    double* slot = &ring[(y % n) * kTerms * mw];
    for (int t = 0; t < kTerms; ++t) {
      const double* in = &row[t * w];
      double* h = slot + t * mw;
      for (std::size_t x = 0; x < mw; ++x) {
        double s = 0;
        for (std::size_t k = 0; k < n; ++k) s += g[k] * in[x + k];
        h[x] = s;
      }
    }
    if (y + 1 < n) continue;
    // Window rows y − n + 1 … y are all in the ring: output row j = y − 2r.
    const std::size_t j = y + 1 - n;
    for (std::size_t x = 0; x < mw; ++x) {
      double m[kTerms] = {0, 0, 0, 0};
      for (std::size_t k = 0; k < n; ++k) {
        const double* h = &ring[((j + k) % n) * kTerms * mw];
        for (int t = 0; t < kTerms; ++t) m[t] += g[k] * h[t * mw + x];
      }
      // The paper's index with C3 = C2/2: luminance term × contrast-structure term.
      const double mean_diff = m[kA] - m[kB];
      const double covariance = m[kAB] - m[kA] * m[kB];
      const double luminance_num = 2 * m[kA] * m[kB] + c1;
      const double luminance_den = luminance_num + mean_diff * mean_diff;
      const double contrast_structure_num = 2 * covariance + c2;
      const double contrast_structure_den = contrast_structure_num + (m[kDD] - mean_diff * mean_diff);
      const double s = (luminance_num * contrast_structure_num) / (luminance_den * contrast_structure_den);
      if (!map.empty()) map[j * mw + x] = float(s);
      sum += s;
    }
  }
  return sum / double(out.cell_count());
}

double weighted_ssim(std::span<const float> map, view::GridSize size, const PixelWeights& weighting,
                     const SsimOptions& options) {
  const view::GridSize out = ssim_map_size(size, options);
  assert(map.size() == out.cell_count());
  assert(weighting.mask.empty() || weighting.mask.size() == size.cell_count());
  assert(weighting.weights.empty() || weighting.weights.size() == size.cell_count());
  const std::size_t r = options.window_radius;
  double sum = 0, total = 0;
  for (std::size_t j = 0; j < out.height; ++j) {
    for (std::size_t i = 0; i < out.width; ++i) {
      const double wt = pixel_weight(weighting, (j + r) * size.width + (i + r));
      sum += wt * map[j * out.width + i], total += wt;
    }
  }
  return total > 0 ? sum / total : 1.0;
}

double mean_absolute_error(std::span<const float> a, std::span<const float> b,
                           const PixelWeights& weighting) {
  assert(a.size() == b.size());
  assert(weighting.mask.empty() || weighting.mask.size() == a.size());
  assert(weighting.weights.empty() || weighting.weights.size() == a.size());
  double sum = 0, total = 0;
  for (std::size_t c = 0; c < a.size(); ++c) {
    const double wt = pixel_weight(weighting, c);
    sum += wt * std::abs(double(a[c]) - double(b[c])), total += wt;
  }
  return total > 0 ? sum / total : 0.0;
}

double focal_px_from_fov(std::uint32_t height_px, double fovy_deg) {
  assert(fovy_deg > 0 && fovy_deg < 180);
  return 0.5 * double(height_px) / std::tan(0.5 * fovy_deg * (std::numbers::pi / 180.0));
}

double pixel_eccentricity_deg(view::GridSize size, const Foveation& f, double x_px, double y_px) {
  assert(f.focal_px > 0);
  // Rays from the eye through the focus (u) and the point (v); atan2 of |u × v| and u·v is accurate
  // at small angles too, where acos of the normalised dot product loses half its digits.
  const double cx = 0.5 * size.width, cy = 0.5 * size.height;
  const double u[3] = {f.focus_x_px - cx, f.focus_y_px - cy, f.focal_px};
  const double v[3] = {x_px - cx, y_px - cy, f.focal_px};
  const double cross[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
  const double dot = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
  return radians_to_degrees(std::atan2(std::hypot(cross[0], cross[1], cross[2]), dot));
}

void foveation_weights(view::GridSize size, const Foveation& foveation, std::span<float> weights) {
  assert(weights.size() == size.cell_count());
  for (std::uint32_t j = 0; j < size.height; ++j)
    for (std::uint32_t i = 0; i < size.width; ++i)
      weights[size.cell(i, j)] =
          float(acuity_weight(pixel_eccentricity_deg(size, foveation, i + 0.5, j + 0.5), foveation.e2_deg));
}

ImageComparison compare_images(std::span<const float> a, std::span<const float> b, view::GridSize size,
                               std::span<const std::uint8_t> covered, std::span<const float> weights,
                               std::span<float> map, const SsimOptions& options) {
  ImageComparison out;
  out.ssim = ssim(a, b, size, map, options);
  out.ssim_covered = weighted_ssim(map, size, {covered, {}}, options);
  out.foveated_ssim = weighted_ssim(map, size, {covered, weights}, options);
  out.mae = mean_absolute_error(a, b);
  out.mae_covered = mean_absolute_error(a, b, {covered, {}});
  out.foveated_mae = mean_absolute_error(a, b, {covered, weights});
  out.covered_pixels = covered.empty()
                           ? size.cell_count()
                           : size.cell_count() - std::size_t(std::count(covered.begin(), covered.end(), 0));
  return out;
}

std::size_t coverage_from_background(std::span<const std::uint8_t> a_rgb, std::span<const std::uint8_t> b_rgb,
                                     const std::array<std::uint8_t, 3>& background,
                                     std::span<std::uint8_t> covered) {
  assert(a_rgb.size() == b_rgb.size() && a_rgb.size() == 3 * covered.size());
  const auto differs = [&background](std::span<const std::uint8_t> rgb, std::size_t c) {
    return rgb[3 * c] != background[0] || rgb[3 * c + 1] != background[1] || rgb[3 * c + 2] != background[2];
  };
  std::size_t count = 0;
  for (std::size_t c = 0; c < covered.size(); ++c) {
    covered[c] = differs(a_rgb, c) || differs(b_rgb, c);
    count += covered[c];
  }
  return count;
}

ImageComparison compare_rgb_renderings(std::span<const std::uint8_t> a_rgb,
                                       std::span<const std::uint8_t> b_rgb, view::GridSize size,
                                       const std::array<std::uint8_t, 3>& background,
                                       const Foveation& foveation, const SsimOptions& options) {
  assert(a_rgb.size() == 3 * size.cell_count() && b_rgb.size() == a_rgb.size());
  const std::size_t n = size.cell_count();
  std::vector<float> a(n), b(n), weights(n), map(ssim_map_size(size, options).cell_count());
  std::vector<std::uint8_t> covered(n);
  luminance_from_rgb(a_rgb, a);
  luminance_from_rgb(b_rgb, b);
  coverage_from_background(a_rgb, b_rgb, background, covered);
  foveation_weights(size, foveation, weights);
  return compare_images(a, b, size, covered, weights, map, options);
}

}  // namespace mtlod::core::eval

#include "clients/tools/eval/score.hpp"

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <vector>

#include "clients/tools/eval/support.hpp"
#include "core/eval/image_metrics.hpp"
#include "core/io/image_io.hpp"
#include "fmt/format.h"

namespace mtlod::eval_tool {

using namespace mtlod::core;

namespace {

bool parse_hex_colour(const std::string& text, std::array<std::uint8_t, 3>& out) {
  unsigned r = 0, g = 0, b = 0;
  char rest = 0;
  if (text.size() != 6 || std::sscanf(text.c_str(), "%2x%2x%2x%c", &r, &g, &b, &rest) != 3) return false;
  out = {std::uint8_t(r), std::uint8_t(g), std::uint8_t(b)};
  return true;
}

}  // namespace

int run_score(const ScoreOptions& o) {
  auto a = io::read_png_rgb(o.reference);
  if (!a) return fmt::print(stderr, "mtlod-eval: {}\n", a.error().message), 1;
  auto b = io::read_png_rgb(o.candidate);
  if (!b) return fmt::print(stderr, "mtlod-eval: {}\n", b.error().message), 1;
  const view::GridSize size = a->size;
  const std::uint32_t min_side = 2 * eval::SsimOptions{}.window_radius + 1;
  if (b->size.width != size.width || b->size.height != size.height)
    return fmt::print(stderr, "mtlod-eval: {} is {}x{}, {} is {}x{}\n", o.reference, size.width, size.height,
                      o.candidate, b->size.width, b->size.height),
           2;
  if (size.width < min_side || size.height < min_side)
    return fmt::print(stderr, "mtlod-eval: images must be at least {}x{}\n", min_side, min_side), 2;
  if (!o.focus.empty() && !(o.focus[0] >= 0 && o.focus[0] <= 1 && o.focus[1] >= 0 && o.focus[1] <= 1))
    return fmt::print(stderr, "mtlod-eval: --focus {},{} is outside [0, 1]²\n", o.focus[0], o.focus[1]), 2;
  if (!(o.fov_deg > 0 && o.fov_deg < 180) || !(o.viewing_distance_px >= 0) || !(o.e2_deg > 0))
    return fmt::print(stderr,
                      "mtlod-eval: --fov must be in (0, 180), --viewing-distance-px and --e2 positive\n"),
           2;
  std::array<std::uint8_t, 3> background{a->rgb[0], a->rgb[1], a->rgb[2]};
  if (!o.background.empty() && !parse_hex_colour(o.background, background))
    return fmt::print(stderr, "mtlod-eval: --background '{}' is not RRGGBB\n", o.background), 2;

  // The reference alone gives the model's coverage and so the default focus.
  std::vector<std::uint8_t> reference_mask(size.cell_count());
  const std::size_t reference_px = eval::coverage_from_background(a->rgb, a->rgb, background, reference_mask);
  const std::array<float, 2> centroid = focus_point(reference_mask, size);
  const std::array<float, 2> focus =
      o.focus.empty() ? centroid : std::array<float, 2>{float(o.focus[0]), float(o.focus[1])};
  eval::Foveation foveation;
  foveation.focus_x_px = focus[0] * float(size.width);
  foveation.focus_y_px = focus[1] * float(size.height);
  foveation.focal_px =
      o.viewing_distance_px > 0 ? o.viewing_distance_px : eval::focal_px_from_fov(size.height, o.fov_deg);
  foveation.e2_deg = o.e2_deg;
  const eval::ImageComparison c = eval::compare_rgb_renderings(a->rgb, b->rgb, size, background, foveation);

  fmt::print(
      "{{\"foveated_error\":{:.9g},\"foveated_ssim\":{:.9g},\"ssim\":{:.9g},\"ssim_covered\":{:.9g},"
      "\"mae\":{:.9g},\"mae_covered\":{:.9g},\"foveated_mae\":{:.9g},\"covered_pixels\":{},"
      "\"reference_pixels\":{},\"width\":{},\"height\":{},\"focus\":[{:.6f},{:.6f}],"
      "\"reference_centroid\":[{:.6f},{:.6f}],\"background\":\"{:02x}{:02x}{:02x}\"}}\n",
      1.0 - c.foveated_ssim, c.foveated_ssim, c.ssim, c.ssim_covered, c.mae, c.mae_covered, c.foveated_mae,
      c.covered_pixels, reference_px, size.width, size.height, focus[0], focus[1], centroid[0], centroid[1],
      background[0], background[1], background[2]);
  return 0;
}

}  // namespace mtlod::eval_tool

// Colour maps for debug images (core/ARCHITECTURE.md §1.2–1.4; the papers' figures 2–3 show the
// distance image over the projected model).
#include "core/eval/debug_image.hpp"

#include <algorithm>
#include <cassert>

namespace mtlod::core::eval {

namespace {

// Piecewise-linear ramp through blue, cyan, green, yellow and red for t in [0, 1].
void ramp_colour(float t, std::uint8_t* rgb) {
  static constexpr float kStops[5][3] = {{0, 0, 255}, {0, 255, 255}, {0, 255, 0}, {255, 255, 0}, {255, 0, 0}};
  t = std::clamp(t, 0.0f, 1.0f) * 4.0f;
  const int k = std::min(static_cast<int>(t), 3);
  const float f = t - static_cast<float>(k);
  for (int c = 0; c < 3; ++c) {
    rgb[c] = static_cast<std::uint8_t>(kStops[k][c] + (kStops[k + 1][c] - kStops[k][c]) * f + 0.5f);
  }
}

template <class T>
void colorize(std::span<const T> raw, [[maybe_unused]] view::GridSize grid, std::uint32_t unreached,
              std::uint32_t max_raw, std::uint32_t band_raw, std::span<std::uint8_t> rgb) {
  assert(raw.size() == grid.cell_count() && rgb.size() == 3 * grid.cell_count());
  if (max_raw == 0) {
    for (const T v : raw)
      if (v < unreached) max_raw = std::max<std::uint32_t>(max_raw, v);
  }
  const float scale = max_raw > 0 ? 1.0f / static_cast<float>(max_raw) : 0.0f;
  for (std::size_t c = 0; c < raw.size(); ++c) {
    std::uint8_t* out = rgb.data() + 3 * c;
    const std::uint32_t v = raw[c];
    if (v >= unreached) {
      std::fill(out, out + 3, std::uint8_t{96});
    } else if (v == 0) {
      std::fill(out, out + 3, std::uint8_t{0});
    } else {
      ramp_colour(static_cast<float>(v) * scale, out);
      // Halving the colour on band boundaries draws iso-distance lines like a contour map.
      if (band_raw > 0 && v % band_raw < std::max(1u, band_raw / 5)) {
        for (int k = 0; k < 3; ++k) out[k] = static_cast<std::uint8_t>(out[k] / 2);
      }
    }
  }
}

}  // namespace

void colorize_occupancy(std::span<const std::uint8_t> occupancy, [[maybe_unused]] view::GridSize grid,
                        std::span<std::uint8_t> rgb) {
  assert(occupancy.size() == grid.cell_count() && rgb.size() == 3 * grid.cell_count());
  for (std::size_t c = 0; c < occupancy.size(); ++c) {
    std::fill(rgb.begin() + 3 * c, rgb.begin() + 3 * c + 3,
              occupancy[c] != 0 ? std::uint8_t{255} : std::uint8_t{0});
  }
}

void colorize_distance(std::span<const std::uint32_t> raw, view::GridSize grid, std::uint32_t unreached,
                       std::uint32_t max_raw, std::uint32_t band_raw, std::span<std::uint8_t> rgb) {
  colorize(raw, grid, unreached, max_raw, band_raw, rgb);
}
void colorize_distance(std::span<const std::uint16_t> raw, view::GridSize grid, std::uint32_t unreached,
                       std::uint32_t max_raw, std::uint32_t band_raw, std::span<std::uint8_t> rgb) {
  colorize(raw, grid, unreached, max_raw, band_raw, rgb);
}

}  // namespace mtlod::core::eval

// Colour maps for debug images of the grid stages (core/ARCHITECTURE.md §1.2–1.4), as in the papers:
// occupancy, distance transform and labels as RGB byte images. Pure functions; core/io/image_io
// writes them to PNG.
#pragma once

#include <cstdint>
#include <span>

#include "core/view/grid.hpp"

namespace mtlod::core::eval {

// rgb holds 3·grid.cell_count() bytes. Object cells white, background black.
void colorize_occupancy(std::span<const std::uint8_t> occupancy, view::GridSize grid,
                        std::span<std::uint8_t> rgb);

// Distance values (raw units, any transform) on a blue → green → yellow → red ramp over
// [0, max_raw] (max_raw = 0: the largest finite value in the grid), with a dark iso-line every
// band_raw units when band_raw > 0 (e.g. 25 = every 5 px of a 5-7-11 transform). Seeds (0) are black
// and values ≥ unreached are grey.
void colorize_distance(std::span<const std::uint32_t> raw, view::GridSize grid, std::uint32_t unreached,
                       std::uint32_t max_raw, std::uint32_t band_raw, std::span<std::uint8_t> rgb);
void colorize_distance(std::span<const std::uint16_t> raw, view::GridSize grid, std::uint32_t unreached,
                       std::uint32_t max_raw, std::uint32_t band_raw, std::span<std::uint8_t> rgb);

}  // namespace mtlod::core::eval

// PNG writing for debug images of the grid stages (occupancy, distance transform, labels), via libpng.
// The colour maps themselves are pure and live in core/debug_image.hpp.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>

#include "core/grid.hpp"
#include "core/result.hpp"

namespace mtlod::core::io {

// 8-bit grey image, one byte per cell, row-major, top row first.
Status write_png_gray(const std::filesystem::path& path, std::span<const std::uint8_t> cells, GridSize grid);
// 8-bit RGB image, three bytes per cell.
Status write_png_rgb(const std::filesystem::path& path, std::span<const std::uint8_t> rgb, GridSize grid);

// Convenience dumps: the occupancy (object white) and a chamfer distance grid on the colour ramp of
// colorize_distance, with an iso-line every band_px pixels (units_per_pixel raw units per pixel).
Status write_occupancy_png(const std::filesystem::path& path, std::span<const std::uint8_t> occupancy,
                           GridSize grid);
Status write_distance_png(const std::filesystem::path& path, std::span<const std::uint16_t> raw,
                          GridSize grid, std::uint32_t units_per_pixel, std::uint32_t band_px = 5);

}  // namespace mtlod::core::io

// PNG files via libpng: writing the debug images of the grid stages (occupancy, distance transform,
// labels), and reading renderings back for scoring (mtlod-eval score: screenshots of the viewer).
// The colour maps themselves are pure and live in core/debug_image.hpp.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <vector>

#include "core/result.hpp"
#include "core/view/grid.hpp"

namespace mtlod::core::io {

// 8-bit grey image, one byte per cell, row-major, top row first.
Status write_png_gray(const std::filesystem::path& path, std::span<const std::uint8_t> cells,
                      view::GridSize grid);
// 8-bit RGB image, three bytes per cell.
Status write_png_rgb(const std::filesystem::path& path, std::span<const std::uint8_t> rgb,
                     view::GridSize grid);

// An 8-bit RGB image, three bytes per pixel, row-major, top row first.
struct RgbImage {
  std::vector<std::uint8_t> rgb;
  view::GridSize size;
};

// Reads any PNG as 8-bit sRGB-encoded RGB (libpng converts grey, palette and 16-bit images; alpha is
// composited over black). Fails on unreadable files and on images larger than kMaxGridSide a side.
Result<RgbImage> read_png_rgb(const std::filesystem::path& path);

// Convenience dumps: the occupancy (object white) and a chamfer distance grid on the colour ramp of
// colorize_distance, with an iso-line every band_px pixels (units_per_pixel raw units per pixel).
Status write_occupancy_png(const std::filesystem::path& path, std::span<const std::uint8_t> occupancy,
                           view::GridSize grid);
Status write_distance_png(const std::filesystem::path& path, std::span<const std::uint16_t> raw,
                          view::GridSize grid, std::uint32_t units_per_pixel, std::uint32_t band_px = 5);

}  // namespace mtlod::core::io

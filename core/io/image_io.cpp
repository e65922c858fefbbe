// PNG writing and reading with libpng's simplified API (png_image), for the debug images of
// core/ARCHITECTURE.md §1.2–1.4 and the renderings that mtlod-eval scores.
#include "core/io/image_io.hpp"

#include <png.h>

#include <cstring>
#include <string>
#include <vector>

#include "core/eval/debug_image.hpp"
#include "core/view/distance_transform.hpp"

namespace mtlod::core::io {

namespace {

Status write_png(const std::filesystem::path& path, const std::uint8_t* pixels, std::size_t size,
                 view::GridSize grid, std::uint32_t format, std::size_t channels) {
  if (!grid.valid()) {
    return make_error(ErrorCode::kInvalidArgument, "image grid " + std::to_string(grid.width) + "x" +
                                                       std::to_string(grid.height) +
                                                       " is empty or too large");
  }
  if (size != channels * grid.cell_count()) {
    return make_error(ErrorCode::kInvalidArgument,
                      "image buffer of " + std::to_string(size) + " bytes does not match the grid");
  }
  png_image image;
  std::memset(&image, 0, sizeof(image));
  image.version = PNG_IMAGE_VERSION;
  image.width = grid.width;
  image.height = grid.height;
  image.format = format;
  if (png_image_write_to_file(&image, path.c_str(), 0, pixels, 0, nullptr) == 0) {
    std::string message = "cannot write PNG " + path.string() + ": " + image.message;
    png_image_free(&image);
    return make_error(ErrorCode::kIoError, std::move(message));
  }
  return Ok{};
}

}  // namespace

Status write_png_gray(const std::filesystem::path& path, std::span<const std::uint8_t> cells,
                      view::GridSize grid) {
  return write_png(path, cells.data(), cells.size(), grid, PNG_FORMAT_GRAY, 1);
}

Status write_png_rgb(const std::filesystem::path& path, std::span<const std::uint8_t> rgb,
                     view::GridSize grid) {
  return write_png(path, rgb.data(), rgb.size(), grid, PNG_FORMAT_RGB, 3);
}

Result<RgbImage> read_png_rgb(const std::filesystem::path& path) {
  png_image image;
  std::memset(&image, 0, sizeof(image));
  image.version = PNG_IMAGE_VERSION;
  if (png_image_begin_read_from_file(&image, path.c_str()) == 0)
    return make_error(ErrorCode::kIoError, "cannot read PNG " + path.string() + ": " + image.message);
  RgbImage out;
  out.size = {image.width, image.height};
  // Checked before allocating: a header may claim any size.
  if (!out.size.valid()) {
    png_image_free(&image);
    return make_error(ErrorCode::kInvalidArgument, "PNG " + path.string() + " is " +
                                                       std::to_string(image.width) + "x" +
                                                       std::to_string(image.height) + ", outside 1.." +
                                                       std::to_string(view::kMaxGridSide) + " a side");
  }
  image.format = PNG_FORMAT_RGB;
  out.rgb.resize(3 * out.size.cell_count());
  if (png_image_finish_read(&image, nullptr, out.rgb.data(), 0, nullptr) == 0) {
    std::string message = "cannot decode PNG " + path.string() + ": " + image.message;
    png_image_free(&image);
    return make_error(ErrorCode::kIoError, std::move(message));
  }
  return out;
}

Status write_occupancy_png(const std::filesystem::path& path, std::span<const std::uint8_t> occupancy,
                           view::GridSize grid) {
  if (occupancy.size() != grid.cell_count()) return make_error(ErrorCode::kInvalidArgument, "occupancy size");
  std::vector<std::uint8_t> grey(occupancy.size());
  for (std::size_t c = 0; c < grey.size(); ++c) grey[c] = occupancy[c] != 0 ? 255 : 0;
  return write_png_gray(path, grey, grid);
}

Status write_distance_png(const std::filesystem::path& path, std::span<const std::uint16_t> raw,
                          view::GridSize grid, std::uint32_t units_per_pixel, std::uint32_t band_px) {
  if (raw.size() != grid.cell_count()) return make_error(ErrorCode::kInvalidArgument, "distance grid size");
  std::vector<std::uint8_t> rgb(3 * raw.size());
  eval::colorize_distance(raw, grid, view::kChamferUnreached, 0, band_px * units_per_pixel, rgb);
  return write_png_rgb(path, rgb, grid);
}

}  // namespace mtlod::core::io

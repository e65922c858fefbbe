// Image-space silhouette error (papers/000 §4, figures 3–5: "the smoothness of the silhouette"):
// rasterise the silhouette masks of a mesh and of its simplification from one camera, count the
// pixels where they differ (XOR), and measure how far each contour lies from the other (mean and max
// in pixels, through an exact Euclidean distance transform of the other contour). Also the triangles
// within an image distance of a focus point, which restricts the object-space error to the focus
// region (papers/002). Masks are W×H byte images, row-major, top row first, like the view grid.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "core/view/grid.hpp"

namespace mtlod::core::view {
class ViewMapping;  // core/view/view_grid.hpp
}  // namespace mtlod::core::view

namespace mtlod::core::eval {

// Silhouette mask of a mesh through mapping (its grid is the image): mask[c] = 1 when the centre of
// pixel c lies inside or on the edge of a projected triangle, else 0. Triangles with a corner at or
// behind the eye plane (clip.w ≤ 0) are skipped (the evaluation's cameras see the whole model).
// mask holds mapping.grid().cell_count() bytes. Returns the number of covered pixels.
std::size_t rasterize_silhouette(const view::ViewMapping& mapping, std::span<const float> positions,
                                 std::span<const std::uint32_t> triangles, std::span<std::uint8_t> mask);

// Pixels where a and b differ (both the same size); diff, when not empty, receives 1 there.
std::size_t xor_count(std::span<const std::uint8_t> a, std::span<const std::uint8_t> b,
                      std::span<std::uint8_t> diff = {});

// Contour of a mask: object pixels with a 4-neighbour that is background or off the image.
// contour holds grid.cell_count() bytes (1 on the contour). Returns the number of contour pixels.
std::size_t extract_contour(std::span<const std::uint8_t> mask, view::GridSize grid,
                            std::span<std::uint8_t> contour);

// Distances from the contour pixels of one mask to the nearest contour pixel of the other, in pixels.
struct ContourDistance {
  double mean_px = 0.0;
  double max_px = 0.0;
  std::size_t pixels = 0;  // contour pixels measured
};

struct SilhouetteError {
  std::size_t xor_pixels = 0;
  std::size_t pixels_a = 0;  // covered pixels of each mask
  std::size_t pixels_b = 0;
  ContourDistance a_to_b;
  ContourDistance b_to_a;
  // Symmetric contour distances: the larger maximum, and the mean over the contour pixels of both.
  double max_px() const { return a_to_b.max_px > b_to_a.max_px ? a_to_b.max_px : b_to_a.max_px; }
  double mean_px() const {
    const std::size_t n = a_to_b.pixels + b_to_a.pixels;
    return n == 0 ? 0.0
                  : (a_to_b.mean_px * double(a_to_b.pixels) + b_to_a.mean_px * double(b_to_a.pixels)) /
                        double(n);
  }
};

// Compares two masks of the same grid. A contour measured against an empty contour has +inf distances;
// two empty masks give all zeros.
SilhouetteError compare_silhouettes(std::span<const std::uint8_t> mask_a,
                                    std::span<const std::uint8_t> mask_b, view::GridSize grid);

// Focus region: in_region[t] = 1 when the projection of triangle t comes within radius_px pixels of
// the point (x_px, y_px) of mapping's grid (continuous coordinates, pixel (i, j) covers
// [i, i+1) × [j, j+1)), by the exact 2D point–triangle distance; triangles with a corner behind the
// eye plane are left out. Visibility is ignored, as in the papers' labels. in_region has one entry per
// triangle. Returns the number of triangles in the region.
std::size_t triangles_near_point(const view::ViewMapping& mapping, std::span<const float> positions,
                                 std::span<const std::uint32_t> triangles, float x_px, float y_px,
                                 float radius_px, std::span<std::uint8_t> in_region);

}  // namespace mtlod::core::eval

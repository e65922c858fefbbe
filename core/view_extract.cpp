// One view-dependent extraction, stage by stage (see view_extract.hpp).
#include "core/view_extract.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

#include "core/labels.hpp"
#include "core/occupancy.hpp"

namespace mtlod::core {
namespace {

// Exact squared distances → distances in fifths of a pixel: the 5-per-pixel scale of the papers'
// labels, so the allowed-error laws read them as 5-7-11 units. Fits 16 bits on grids up to 4096².
void to_fifths_of_pixel(std::span<const std::uint32_t> squared, std::span<std::uint16_t> out) {
  for (std::size_t c = 0; c < out.size(); ++c) {
    out[c] = squared[c] == kEuclideanUnreached
                 ? kChamferUnreached
                 : static_cast<std::uint16_t>(std::lround(5.0 * std::sqrt(static_cast<double>(squared[c]))));
  }
}

}  // namespace

ViewExtractor::ViewExtractor(const Mt& mt, const OccupancyLevels& levels) : mt_(mt), levels_(levels) {
  // Bounding sphere (box centre and half diagonal): enough to pick the occupancy cut's error.
  float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (std::size_t v = 0; v < mt.vertex_count(); ++v) {
    for (int c = 0; c < 3; ++c) {
      lo[c] = std::min(lo[c], mt.positions[3 * v + c]);
      hi[c] = std::max(hi[c], mt.positions[3 * v + c]);
    }
  }
  float r2 = 0;
  for (int c = 0; c < 3; ++c) {
    centre_[c] = 0.5f * (lo[c] + hi[c]);
    r2 += 0.25f * (hi[c] - lo[c]) * (hi[c] - lo[c]);
  }
  radius_ = std::sqrt(r2);
}

void ViewExtractor::map(const ViewRequest& request) {
  assert(request.grid.valid());
  request_ = &request;
  mapping_ = ViewMapping(request.camera, request.grid);
}

double ViewExtractor::covered_cells() const {
  // The bounding sphere's projected radius in cells at its centre's depth; a centre at or behind
  // the eye means the model surrounds the camera: the whole grid.
  float clip_w = 0;
  mapping_.map_point(centre_[0], centre_[1], centre_[2], &clip_w);
  const double grid_cells = static_cast<double>(request_->grid.cell_count());
  if (!(clip_w > radius_)) return grid_cells;
  const double cell = mapping_.model_units_per_pixel(clip_w, static_cast<float>(request_->grid.height));
  const double radius_cells = radius_ / cell;
  return std::min(grid_cells, 3.14159265358979 * radius_cells * radius_cells);
}

std::size_t ViewExtractor::occupancy() {
  occupancy_triangles_ = levels_.for_covered_cells(covered_cells()).triangles;
  const std::size_t cells = request_->grid.cell_count();
  occupancy_.resize(cells);
  if (request_->internal_silhouettes) depth_.resize(cells);
  rasterize_occupancy(mapping_, mt_.positions, occupancy_triangles_, occupancy_,
                      request_->internal_silhouettes ? std::span<float>(depth_) : std::span<float>());
  return occupancy_triangles_.size() / 3;
}

void ViewExtractor::transform(std::span<const std::uint8_t> image, std::span<std::uint16_t> out) {
  const DistanceMetric metric = request_->allowed.metric;
  if (metric != DistanceMetric::kEuclidean) return transformer_.chamfer(metric, image, request_->grid, out);
  euclidean_.resize(out.size());
  transformer_.euclidean_squared(image, request_->grid, euclidean_);
  to_fifths_of_pixel(euclidean_, out);
}

void ViewExtractor::transform_from_cells(std::span<const std::uint32_t> cells, std::span<std::uint16_t> out) {
  const DistanceMetric metric = request_->allowed.metric;
  if (metric != DistanceMetric::kEuclidean) return transformer_.chamfer_from_cells(metric, cells, request_->grid, out);
  euclidean_.resize(out.size());
  transformer_.euclidean_squared_from_cells(cells, request_->grid, euclidean_);
  to_fifths_of_pixel(euclidean_, out);
}

void ViewExtractor::distance_transforms() {
  const ViewRequest& r = *request_;
  const std::size_t cells = r.grid.cell_count();
  if (r.allowed.use_silhouette || (r.labels && r.focus.empty())) {
    silhouette_dt_.resize(cells);
    if (r.internal_silhouettes) {
      seeds_image_ = occupancy_;
      mark_depth_discontinuities(depth_, r.grid, r.depth_jump, seeds_image_);
      transform(seeds_image_, silhouette_dt_);
    } else {
      transform(occupancy_, silhouette_dt_);
    }
  } else {
    silhouette_dt_.clear();
  }
  auto seeded = [&](const std::vector<std::array<float, 2>>& points, std::vector<std::uint16_t>& out) {
    out.clear();
    if (points.empty()) return;
    cells_.clear();
    for (const auto& p : points) cells_.push_back(focus_cell(r.grid, p[0], p[1]));
    out.resize(cells);
    transform_from_cells(cells_, out);
  };
  seeded(r.allowed.use_focus ? r.focus : std::vector<std::array<float, 2>>{}, focus_dt_);
  seeded(r.allowed.use_neglect ? r.neglect : std::vector<std::array<float, 2>>{}, neglect_dt_);
}

void ViewExtractor::allowed_error() {
  const ViewRequest& r = *request_;
  AllowedErrorOptions options = r.allowed;
  if (options.metric == DistanceMetric::kEuclidean) options.metric = DistanceMetric::kChamfer5711;  // see transform()
  options.use_silhouette = options.use_silhouette && !silhouette_dt_.empty();
  options.use_focus = options.use_focus && !focus_dt_.empty();
  options.use_neglect = options.use_neglect && !neglect_dt_.empty();
  vertex_allowed_error_.resize(mt_.vertex_count());
  field_.bind(mapping_, options, {silhouette_dt_, focus_dt_, neglect_dt_, mt_.positions, mt_.normals});
  field_.compute_all(vertex_allowed_error_);
}

void ViewExtractor::refine(Refiner& session, CutMesh& out) {
  const AllowedError allowed = AllowedError::from_vertices(vertex_allowed_error_);
  if (request_->budget) {
    session.refine_budget(allowed, *request_->budget, out);
  } else if (request_->dynamic) {
    session.update(allowed, out);
  } else {
    session.refine(allowed, out);
  }
  if (request_->labels) {
    // Labels of the cut's vertices only: the silhouette distance when it was computed, else the focus's.
    const std::span<const std::uint16_t> dt = !silhouette_dt_.empty() ? std::span<const std::uint16_t>(silhouette_dt_)
                                                                       : std::span<const std::uint16_t>(focus_dt_);
    vertex_labels_.resize(mt_.vertex_count());
    for (std::uint32_t v : out.triangles) vertex_labels_[v] = dt.empty() ? 0 : vertex_label(mapping_, mt_.positions, v, dt);
  }
}

std::size_t ViewExtractor::memory_bytes() const {
  auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
  return transformer_.memory_bytes() + bytes(occupancy_) + bytes(seeds_image_) + bytes(depth_) + bytes(silhouette_dt_) +
         bytes(focus_dt_) + bytes(neglect_dt_) + bytes(euclidean_) + bytes(cells_) + bytes(vertex_allowed_error_) +
         bytes(vertex_labels_) + field_.memory_bytes();
}

}  // namespace mtlod::core

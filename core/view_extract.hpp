// One view-dependent extraction, stage by stage (DESIGN.md §1 and §4: grid mapping → occupancy →
// distance transforms → labels/allowed error → refinement). A ViewExtractor belongs to one worker
// and one model and keeps every buffer between requests; the session's Refiner carries the cut for
// dynamic refinement. Stages are separate calls so a caller can time each one (core has no clock).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "core/allowed_error.hpp"
#include "core/distance_transform.hpp"
#include "core/mt.hpp"
#include "core/occupancy_levels.hpp"
#include "core/refine.hpp"
#include "core/view_grid.hpp"

namespace mtlod::core {

struct ViewRequest {
  Camera camera;
  GridSize grid{256, 256};
  // Allowed-error settings: bound, units, laws per criterion, coarsening factors. Its `metric` says
  // which distance transform runs; kEuclidean is computed exactly and handed on in fifths of a pixel.
  AllowedErrorOptions allowed;
  std::vector<std::array<float, 2>> focus;    // normalised viewport coordinates, (0,0) top left
  std::vector<std::array<float, 2>> neglect;  // the same, for regions of neglect
  bool internal_silhouettes = false;          // depth jumps seed the silhouette transform too
  float depth_jump = 0.1f;                    // relative depth difference that counts as a jump
  std::optional<std::size_t> budget;          // triangle budget: worst-first refinement
  bool dynamic = true;                        // move the session's cut (false: refine from the root)
  bool labels = false;                        // fill vertex labels (silhouette, else focus) for encoding
};

class ViewExtractor {
 public:
  // levels: the model's precomputed occupancy cuts, shared by every extractor of the model.
  ViewExtractor(const Mt& mt, const OccupancyLevels& levels);

  const Mt& mt() const { return mt_; }

  // Stage 1: binds the request and builds the mapping.
  void map(const ViewRequest& request);
  // Stage 2: rasterises the occupancy from a precomputed coarse cut sized to the grid cells the
  // model covers (see OccupancyLevels). Returns that cut's triangle count.
  std::size_t occupancy();
  // Stage 3: the silhouette, focus and neglect transforms the request uses.
  void distance_transforms();
  // Stage 4: per-vertex allowed error (and labels when asked).
  void allowed_error();
  // Stage 5: refines `session` (dynamic unless a budget is set or `dynamic` is off) and writes the
  // cut to `out`.
  void refine(Refiner& session, CutMesh& out);

  // After the stages: the per-vertex labels (model vertex count entries; only the cut's vertices are
  // meaningful), the grids, and the occupancy cut, for encoders, tools and debug images.
  std::span<const std::uint32_t> vertex_labels() const { return vertex_labels_; }
  std::span<const std::uint8_t> occupancy_grid() const { return occupancy_; }
  std::span<const std::uint16_t> silhouette_dt() const { return silhouette_dt_; }
  std::span<const std::uint16_t> focus_dt() const { return focus_dt_; }
  std::span<const float> vertex_allowed_error() const { return vertex_allowed_error_; }
  const ViewMapping& mapping() const { return mapping_; }
  std::span<const std::uint32_t> occupancy_triangles() const { return occupancy_triangles_; }

  // Grid cells covered by the model's bounding sphere (at most the whole grid).
  double covered_cells() const;

  // Bytes of scratch memory held (grids, transforms, per-vertex arrays): a worker's cost per model.
  std::size_t memory_bytes() const;

 private:
  void transform(std::span<const std::uint8_t> image, std::span<std::uint16_t> out);
  void transform_from_cells(std::span<const std::uint32_t> cells, std::span<std::uint16_t> out);

  const Mt& mt_;
  std::array<float, 3> centre_{};
  float radius_ = 0.0f;
  const ViewRequest* request_ = nullptr;
  ViewMapping mapping_;
  const OccupancyLevels& levels_;
  std::span<const std::uint32_t> occupancy_triangles_;
  DistanceTransformer transformer_;
  AllowedErrorField field_;
  std::vector<std::uint8_t> occupancy_, seeds_image_;
  std::vector<float> depth_;
  std::vector<std::uint16_t> silhouette_dt_, focus_dt_, neglect_dt_;
  std::vector<std::uint32_t> euclidean_, cells_;
  std::vector<float> vertex_allowed_error_;
  std::vector<std::uint32_t> vertex_labels_;
};

}  // namespace mtlod::core

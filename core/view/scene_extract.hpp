// One extraction of a scene: many instances of models, each placed by its own model matrix, seen
// by one camera through one grid (core/ARCHITECTURE.md §4, "Scenes"). The stages are those of
// ViewExtractor, but the picture is the whole scene's:
//   1. every instance gets its own mapping (P·V·M with its matrix);
//   2. each instance's occupancy cut is rasterised with depths into one grid, the nearest surface
//      winning a cell, which also records the instance it shows;
//   3. the distance transforms run once on that grid: the silhouette is the outline of the
//      picture, where an instance meets the background or passes in front of another;
//   4. each instance's allowed error is read off the shared transforms and the shared visible
//      depth, so an instance behind another is coarsened as hidden surface;
//   5. each instance is refined on demand; with a triangle budget, all of them at one threshold of
//      the worst-first order (error / allowed error, cut::AllowedError::threshold), the finest
//      threshold whose cuts fit together, found by a search over thresholds.
// Instances of one model share its MT and one refiner; the per-request cost follows the cuts.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include <glm/mat4x4.hpp>

#include "core/cut/refine.hpp"
#include "core/model/mt.hpp"
#include "core/result.hpp"
#include "core/util/zeroed_array.hpp"
#include "core/view/allowed_error.hpp"
#include "core/view/distance_transform.hpp"
#include "core/view/occupancy.hpp"
#include "core/view/occupancy_levels.hpp"
#include "core/view/view_extract.hpp"
#include "core/view/view_grid.hpp"

namespace mtlod::core::view {

// One placed copy of a model. The MT and its occupancy levels are shared by every instance of the
// model and must outlive the extraction.
struct SceneInstance {
  const model::Mt* mt = nullptr;
  const OccupancyLevels* levels = nullptr;
  glm::mat4 model{1.0f};  // model → world; invertible and finite (the caller checks)
};

// The scene's request: ViewRequest's camera (its `model` matrix unused: each instance has its own),
// grid, criteria, points, internal silhouettes and budget, applied to the whole picture. An error
// bound in model units is in world units here; each instance's is divided by how far its matrix
// stretches a length at most (its largest singular value), so that the bound holds in the world.
// labels, dynamic and allowed_error_on_demand are not used: a scene is refined on demand from the
// roots each time.
struct SceneRequest {
  ViewRequest view;
  std::span<const SceneInstance> instances;
};

// What an extraction found, beyond the cuts.
struct SceneStats {
  std::size_t triangles = 0;          // over every instance's cut
  std::size_t rasterized = 0;         // occupancy triangles of the instances in view
  std::size_t instances_in_view = 0;  // whose bounding box may meet the view
  std::size_t passes = 0;             // refinements of the whole scene the budget's search made
  cut::Rank threshold;                // of the cuts returned ({0, 1}: the error bound alone)
  bool within_budget = true;          // false when even the roots exceed the budget
};

// What a client session keeps of its scene's view, so that a request with the same view (camera,
// grid, instances, criteria; only the gaze criterion's points moved: a gaze) skips the occupancy and
// every other transform, as ViewCache does for one model. Owned by the session, filled by
// SceneExtractor; the cuts are the same as from every stage (tests/core/scene_extract_test.cpp).
class SceneCache {
 public:
  // Whether the last request took the gaze's path.
  bool reused() const { return reused_; }
  // Bytes held: the view's transforms, visible depths and instance grid, about 12 a cell.
  std::size_t memory_bytes() const;
  void reset() { valid_ = false; }

 private:
  friend class SceneExtractor;
  bool valid_ = false;
  bool reused_ = false;
  ViewRequest view_;                                     // the request's view, but its gaze points and budget
  bool has_gaze_ = false;                                // the view had gaze points
  std::vector<SceneInstance> instances_;                 // the MTs (versions) and matrices
  PerCriterion<std::vector<std::uint16_t>> transforms_;  // of the view, but the gaze criterion's
  std::vector<float> visible_depth_;
  std::vector<std::uint32_t> owner_;
  std::size_t rasterized_ = 0;
  // The budget's last threshold and the budget: where the next gaze's search starts.
  std::optional<float> threshold_;
  std::optional<std::size_t> threshold_budget_;
};

class SceneExtractor {
 public:
  // Extracts every instance's cut into cuts[i] (resized to the instance count). Fails as
  // cut::Refiner does (a damaged block of a mapped file), and then no cut is a result. With a
  // session, a gaze (the session's view, the gaze points moved) reuses the view's occupancy and
  // transforms but the gaze criterion's; the refinement runs from the roots either way.
  Result<SceneStats> extract(const SceneRequest& request, std::vector<cut::CutMesh>& cuts,
                             StageObserver* observer = nullptr, SceneCache* session = nullptr);

  // After extract: the shared grids, for tools and tests.
  std::span<const std::uint8_t> occupancy_grid() const { return occupancy_; }
  // Per cell: the instance whose surface is nearest, or kNoInstance for background.
  std::span<const std::uint32_t> instance_grid() const { return owner_; }
  std::span<const std::uint16_t> distance_transform(Criterion c) const { return dt_[c]; }
  std::span<const float> visible_depth() const { return visible_depth_; }
  static constexpr std::uint32_t kNoInstance = 0xFFFFFFFFu;

  // Bytes of scratch memory held: the grids, and per model its refiner and allowed-error field.
  std::size_t memory_bytes() const;
  // Drops what is kept for a model (before the MT goes away: a new one may come at its address).
  void forget(const model::Mt& mt) { models_.erase(&mt); }

 private:
  struct PerModel {
    explicit PerModel(const model::Mt& mt) : refiner(mt) {}
    cut::Refiner refiner;
    util::ZeroedArray<float> field;
  };
  void map(const SceneRequest& request);
  void occupancy(const SceneRequest& request, SceneStats& stats);
  // The transforms the request needs; with `only`, that criterion's alone.
  void distance_transforms(const SceneRequest& request, std::optional<Criterion> only = std::nullopt);
  static bool same_view(const SceneCache& session, const SceneRequest& request);
  void remember(const SceneRequest& request, const SceneStats& stats, SceneCache& session) const;
  void recall(const SceneCache& session, SceneStats& stats);
  void bind_fields(const SceneRequest& request);
  // Refines every instance at `threshold` into trial_, stopping once the total passes `stop_above`.
  // Returns the total, or the refiner's error.
  Result<std::size_t> refine_all(const SceneRequest& request, cut::Rank threshold, std::size_t stop_above);
  // hint: a threshold to try first when the bound's cut does not fit (the session's last).
  Result<SceneStats> refine(const SceneRequest& request, std::vector<cut::CutMesh>& cuts, SceneStats stats,
                            std::optional<float> hint);
  PerModel& per_model(const model::Mt& mt);

  std::vector<ViewMapping> mappings_;
  std::vector<AllowedErrorField> fields_;  // one per instance, bound to its mapping
  // Per instance: the grid cells its placed box may cover (empty: out of view).
  static CellRect box_cells(const ViewMapping& mapping, const model::Bounds& box);
  std::vector<CellRect> rects_;
  std::vector<std::uint8_t> hidden_whole_;  // per instance: in view, owning no cell: its roots
  std::map<const model::Mt*, std::unique_ptr<PerModel>> models_;
  std::vector<cut::CutMesh> trial_;
  DistanceTransformer transformer_;
  std::vector<std::uint8_t> occupancy_, instance_occupancy_, seeds_image_;
  std::vector<float> depth_, instance_depth_, visible_depth_;
  std::vector<std::uint32_t> owner_, cells_;
  std::vector<ProjectedCorner> projected_;
  PerCriterion<std::vector<std::uint16_t>> dt_;
};

}  // namespace mtlod::core::view

// One extraction, stage by stage (core/ARCHITECTURE.md §1, §4: grid mapping → occupancy →
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

#include "core/cut/refine.hpp"
#include "core/model/mt.hpp"
#include "core/util/zeroed_array.hpp"
#include "core/view/allowed_error.hpp"
#include "core/view/distance_transform.hpp"
#include "core/view/occupancy.hpp"
#include "core/view/occupancy_levels.hpp"
#include "core/view/view_grid.hpp"

namespace mtlod::core::view {

struct ViewRequest {
  Camera camera;
  GridSize grid{256, 256};
  // Allowed-error settings: bound, units, laws per criterion, coarsening factors. Its `metric` says
  // which distance transform runs; kEuclidean is computed exactly and handed on in fifths of a pixel.
  AllowedErrorOptions allowed;
  // The seeds of each point-seeded criterion (Seeds::kPoints): normalised viewport coordinates,
  // (0,0) top left.
  PerCriterion<std::vector<std::array<float, 2>>> points;
  bool internal_silhouettes = false;  // depth jumps seed the silhouette transform too
  float depth_jump = 0.1f;            // relative depth difference that counts as a jump
  std::optional<std::size_t> budget;  // triangle budget: worst-first refinement (the same cut
                                      // whether from the root or moved, on a session's gaze)
  bool dynamic = true;                // move the session's cut (false: refine from the root)
  // A new view, static or in a session, with or without a budget, refines from the root asking for
  // the allowed error of only the vertices the refinement reads (an on-demand cut::Refinement)
  // instead of every vertex's in stage 4; the same cut. false: stage 4 computes every vertex's (for
  // callers that read the whole field).
  bool allowed_error_on_demand = true;
  bool labels = false;  // fill vertex labels (silhouette, else focus) for encoding; whole transforms
};

// What one client session keeps between its requests, so that a request with the same view as the
// session's previous one — same camera, grid and criteria, only the gaze criterion's points moved
// (kGazeCriterion): a gaze — skips the occupancy and every other transform, recomputes the allowed
// error only for the known vertices in cells where the gaze law's multiplier changed, and hands exactly those
// vertices to the refinement. Owned by the session, filled by ViewExtractor; the result is the
// same as computing every stage again (tests/core/view_extract_test.cpp holds it to that).
//
// Known vertices: on demand (the default), those whose allowed error the view's refinements asked
// for, each with its grid cell and depth — the vertices of the cuts since the view began, and
// never many more than the current cut reads (the others are forgotten); every vertex when the
// whole field was computed. So a gaze costs what the cut and the moved foci cost, whatever the
// model's size.
class ViewCache {
 public:
  // Whether the last request took the incremental path, and how many vertices it recomputed.
  bool reused() const { return reused_; }
  std::size_t changed_vertices() const { return changed_.size(); }
  // Vertices whose allowed error the session knows for its view (see above).
  std::size_t known_vertices() const { return known_vertices_.size(); }
  // How often the session forgot the known vertices its cut no longer read.
  std::size_t forgets() const { return forgets_; }
  // Bytes held: 16 per known vertex, per cell about 14, and the field's pages that were written.
  std::size_t memory_bytes() const;
  // Forget everything (another model, say).
  void reset() { valid_ = false; }

 private:
  friend class ViewExtractor;
  bool valid_ = false;
  bool reused_ = false;
  Camera camera_;
  GridSize grid_;
  AllowedErrorOptions allowed_;
  PerCriterion<std::vector<std::array<float, 2>>> points_;  // but the gaze criterion's
  bool has_gaze_ = false;
  bool internal_silhouettes_ = false;
  float depth_jump_ = 0.0f;
  util::ZeroedArray<float> allowed_error_;               // per vertex: right for the known ones
  bool allowed_error_complete_ = false;                  // every vertex's was computed (else on demand)
  PerCriterion<std::vector<std::uint16_t>> transforms_;  // of the view, but the gaze criterion's
  std::vector<float> visible_depth_;                     // of the view, with hidden-surface coarsening
  std::vector<float> gaze_factor_;                       // per cell, for the last request's gaze points
  std::vector<std::uint32_t> gaze_cells_;  // the last request's gaze points (kNoCell off the grid)
  // The known vertices, their cells (kNoCell off the grid) and clip-space w. With a complete field
  // they are listed on the view's first reuse; on demand, known_bits_ marks them.
  std::vector<std::uint32_t> known_vertices_;
  std::vector<std::uint32_t> known_cells_;
  std::vector<float> known_clip_w_;
  // The known vertices of each cell, chained: a gaze visits those of the cells whose gaze
  // multiplier changed, not every known vertex. Per cell the last known vertex added to it (an
  // index into known_*, kNoKnown: none), per known vertex the one added to its cell before it.
  static constexpr std::uint32_t kNoKnown = 0xFFFFFFFFu;
  std::vector<std::uint32_t> cell_last_known_;
  std::vector<std::uint32_t> known_in_cell_before_;
  bool known_all_ = false;                       // known_vertices_ lists every vertex (complete field)
  util::ZeroedArray<std::uint64_t> known_bits_;  // on demand: one bit per model vertex
  std::vector<std::uint8_t> cell_changed_;       // per cell, during a gaze: its gaze multiplier changed
  std::vector<std::uint32_t> changed_cells_;
  std::vector<std::uint32_t> changed_;  // vertices recomputed by the last request
  std::size_t forgets_ = 0;
};

// Whether a request computes a criterion's transform: the criterion is in use (with seeds), or the
// labels need the silhouette's.
bool criterion_transform_needed(const ViewRequest& request, Criterion c);
// A criterion's transform as its traits seed it (criteria.hpp): from the zero cells of `background`
// (the occupancy, or a copy with depth jumps marked), the request's points of the criterion, or the
// grid's border; in the request's metric (DistanceTransformer::labels). cells: scratch.
void criterion_transform(DistanceTransformer& transformer, Criterion c, const ViewRequest& request,
                         std::span<const std::uint8_t> background, std::vector<std::uint32_t>& cells,
                         std::span<std::uint16_t> out);

// Grid cells a bounding sphere (centre in model space, radius in the mapping's world units) covers:
// its projected disc at the centre's depth, at most the whole grid; the whole grid when the centre
// is at or behind the eye, inside the sphere. What picks a model's occupancy level.
double covered_cells(const ViewMapping& mapping, const std::array<float, 3>& centre, float radius);

// The five stages of a request, in the order they run.
enum class Stage : std::uint8_t { kMap, kOccupancy, kTransforms, kAllowedError, kRefine };
inline constexpr std::size_t kStageCount = 5;

// Told each stage as it finishes: how a caller times the stages (core has no clock).
class StageObserver {
 public:
  virtual void finished(Stage stage) = 0;

 protected:
  ~StageObserver() = default;
};

class ViewExtractor {
 public:
  // levels: the model's precomputed occupancy cuts, shared by every extractor of the model.
  ViewExtractor(const model::Mt& mt, const OccupancyLevels& levels);

  const model::Mt& mt() const { return mt_; }

  // One request, every stage in order: what the server, mtlod-extract and the studies run. With a
  // session, the stages read and update it (a gaze takes the incremental path). Returns
  // refine_view's cut, or its error (a damaged block of a mapped file).
  Result<cut::CutSpan> extract(const ViewRequest& request, cut::Refiner& refiner, cut::CutMesh& scratch,
                               ViewCache* session = nullptr, StageObserver* observer = nullptr);
  // Stages 1 to 4 of a static request with every vertex's allowed error computed, whatever the
  // request's allowed_error_on_demand: the field a study ranks cuts by. Valid until the next call.
  std::span<const float> allowed_error_field(const ViewRequest& request);

  // The stages one by one (tests and benchmarks time or check each).
  // Stage 1: binds the request and builds the mapping. With a session, the stages below read and
  // update it, and take the incremental path when the view is the session's previous one.
  void map(const ViewRequest& request, ViewCache* session = nullptr);
  // Stage 2: rasterises the occupancy from a precomputed coarse cut sized to the grid cells the
  // model covers (see OccupancyLevels), with its depths when internal silhouettes or hidden-surface
  // coarsening need them. Returns that cut's triangle count (0: reused the session's).
  std::size_t occupancy();
  // Stage 3: the transforms of the criteria the request uses, each seeded as its traits say.
  void distance_transforms();
  // Stage 4: per-vertex allowed error: every vertex, or on the incremental path only the session's
  // known vertices in cells whose gaze multiplier changed; on a new view with
  // allowed_error_on_demand, none yet: stage 5 asks for those it reads (and, in a session, so do the
  // view's gazes).
  void allowed_error();
  // Stage 5: refines `session` (dynamic unless `dynamic` is off; with a budget, dynamic on the
  // session's gazes) and writes the cut to `out`.
  Status refine(cut::Refiner& session, cut::CutMesh& out);
  // The same without copying a gaze's cut out of the session's refiner: a view of its kept mesh
  // (valid until the refiner's next call), or of `scratch` when the cut was written there.
  // Fails as cut::Refiner::refine_view does.
  Result<cut::CutSpan> refine_view(cut::Refiner& session, cut::CutMesh& scratch);

  // After the stages: the per-vertex labels (model vertex count entries; only the cut's vertices are
  // meaningful), the grids, and the occupancy cut, for encoders, tools and debug images.
  std::span<const std::uint32_t> vertex_labels() const { return vertex_labels_; }
  // Vertices whose allowed error this extractor computed one by one for sessions (asked for on
  // demand, or changed by a gaze), since it was made.
  std::size_t vertices_computed() const { return vertices_computed_; }
  std::span<const std::uint8_t> occupancy_grid() const { return occupancy_; }
  // A criterion's transform (empty when the request did not use it). The gaze criterion's is
  // computed only within its law's reach of the gaze points (kChamferUnreached elsewhere, where the
  // law's multiplier is 1) unless the request asks for labels.
  std::span<const std::uint16_t> distance_transform(Criterion c) const { return transforms_[c]; }
  // Every vertex's allowed error, or only the cut's when it was computed on demand.
  std::span<const float> vertex_allowed_error() const { return allowed_; }
  const ViewMapping& mapping() const { return mapping_; }
  // The coarse cut the last occupancy() rasterised (null when it reused the session's view).
  const OccupancyLevel* occupancy_level() const { return occupancy_level_; }

  // Grid cells covered by the model's bounding sphere (at most the whole grid).
  double covered_cells() const;

  // Bytes of scratch memory held (grids, transforms, per-vertex arrays): a worker's cost per model.
  std::size_t memory_bytes() const;

 private:
  // Stages 1 to 4, telling the observer (if any) as each ends.
  void prepare(const ViewRequest& request, ViewCache* session, StageObserver* observer);
  // Stage 4 of a gaze: recomputes the session's known vertices in cells whose gaze multiplier
  // changed, listing them in its changed_ (metric: the labels', as bound to the field).
  void update_known_for_gaze(ViewCache& session, DistanceMetric metric);
  // The part of the grid the gaze criterion's transform is computed in, its seeds in cells_ (none:
  // the whole grid, by criterion_transform).
  std::optional<CellRect> gaze_rect();
  // Whether the request has the session's view (everything but the gaze points).
  static bool same_view(const ViewCache& session, const ViewRequest& request);
  void remember_view(ViewCache& session) const;
  void remember_gaze_cells(ViewCache& session) const;
  // The gaze multiplier of every cell and the gaze points, for the request's.
  void remember_gaze(ViewCache& session) const;
  // A complete field's known vertices: every vertex, with its cell and clip-space w.
  void list_all_vertices(ViewCache& session);
  // The session's known vertices become none (a new view).
  static void forget_known(ViewCache& session);
  // Chains the known vertices from position `first` on into their cells' lists (from 0: every
  // cell's list starts empty).
  static void link_known(ViewCache& session, std::size_t first);
  // The session's on-demand allowed error: field_'s values for vertices the session does not know
  // yet, which become known (KnownSource forwards the refiner's requests here).
  void fill_known(std::span<const std::uint32_t> vertices, std::span<float> field);
  class KnownSource;
  // Forgets the known vertices the session's cut does not read once they far outnumber those it does.
  void forget_unread(cut::Refiner& refiner);

  const model::Mt& mt_;
  std::array<float, 3> centre_{};
  float radius_ = 0.0f;
  const ViewRequest* request_ = nullptr;
  ViewRequest field_request_;  // allowed_error_field's copy of its request
  ViewCache* session_ = nullptr;
  bool incremental_ = false;
  bool on_demand_ = false;  // stage 5 computes the allowed error it reads
  // The transforms, visible depths and field in use: this extractor's buffers or the session's.
  PerCriterion<std::span<const std::uint16_t>> transforms_;
  std::span<const float> visible_depth_;
  std::span<float> allowed_;
  ViewMapping mapping_;
  const OccupancyLevels& levels_;
  const OccupancyLevel* occupancy_level_ = nullptr;
  DistanceTransformer transformer_;
  AllowedErrorField field_;
  std::vector<std::uint8_t> occupancy_, seeds_image_;
  std::vector<float> depth_, visible_depth_bound_;
  PerCriterion<std::vector<std::uint16_t>> dt_;
  std::vector<std::uint32_t> cells_;
  util::ZeroedArray<float> vertex_allowed_error_;
  util::ZeroedArray<std::uint32_t> vertex_labels_;  // written for the cut's vertices only
  std::vector<ProjectedCorner> projected_;          // occupancy scratch
  std::vector<std::uint32_t> unknown_;              // fill_known scratch
  std::size_t vertices_computed_ = 0;
};

}  // namespace mtlod::core::view

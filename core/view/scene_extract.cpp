// One extraction of a scene, stage by stage (see scene_extract.hpp).
#include "core/view/scene_extract.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>

#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

#include "core/model/bounds.hpp"
#include "core/view/occupancy.hpp"

namespace mtlod::core::view {
namespace {

constexpr float kFar = std::numeric_limits<float>::infinity();

// The budget's search stops once the scene's cut fills this much of the budget, or after this many
// refinements of the whole scene, or when the thresholds it brackets are this close.
constexpr double kFilled = 0.98;
constexpr std::size_t kMaxPasses = 16;
constexpr double kClosest = 1.0001;
// Thresholds above this coarsen every positive allowed error to nothing: past it only the roots and
// the triangles allowed no error at all are left (a budget below that gets the roots alone).
constexpr double kLargestThreshold = 1e12;

}  // namespace

// The cells the model's bounding box, placed by the instance's mapping, may cover: empty when all
// eight corners lie beyond one side of the frustum (clip-space x, y against w, or w ≤ 0 behind);
// the whole grid when some corner is behind the eye (the box's projection is then unbounded),
// else the corners' cells with a cell of margin (conservative rasterisation marks a cell a
// triangle touches).
CellRect SceneExtractor::box_cells(const ViewMapping& mapping, const model::Bounds& box) {
  const GridSize grid = mapping.grid();
  int left = 0, right = 0, below = 0, above = 0, behind = 0;
  float gx0 = kFar, gy0 = kFar, gx1 = -kFar, gy1 = -kFar;
  for (int k = 0; k < 8; ++k) {
    const float x = (k & 1) ? box.hi[0] : box.lo[0];
    const float y = (k & 2) ? box.hi[1] : box.lo[1];
    const float z = (k & 4) ? box.hi[2] : box.lo[2];
    float cx, cy, cw;
    mapping.clip_xyw(x, y, z, cx, cy, cw);
    left += (cx < -cw), right += (cx > cw), below += (cy < -cw), above += (cy > cw);
    behind += !(cw > kMinClipW);
    if (cw > kMinClipW) {
      const GridPoint g = mapping.to_grid(cx, cy, cw);
      gx0 = std::min(gx0, g.x), gx1 = std::max(gx1, g.x), gy0 = std::min(gy0, g.y), gy1 = std::max(gy1, g.y);
    }
  }
  if (left == 8 || right == 8 || below == 8 || above == 8 || behind == 8) return {};
  if (behind > 0 || !std::isfinite(gx0 + gx1 + gy0 + gy1)) return {0, 0, grid.width, grid.height};
  auto clamp = [](float v, std::uint32_t size) {
    return static_cast<std::uint32_t>(std::clamp(v, 0.0f, static_cast<float>(size)));
  };
  return {clamp(std::floor(gx0) - 1.0f, grid.width), clamp(std::floor(gy0) - 1.0f, grid.height),
          clamp(std::floor(gx1) + 2.0f, grid.width), clamp(std::floor(gy1) + 2.0f, grid.height)};
}

SceneExtractor::PerModel& SceneExtractor::per_model(const model::Mt& mt) {
  std::unique_ptr<PerModel>& entry = models_[&mt];
  if (!entry) entry = std::make_unique<PerModel>(mt);
  if (entry->field.size() != mt.vertex_count()) entry->field.reset(mt.vertex_count());
  return *entry;
}

void SceneExtractor::map(const SceneRequest& request) {
  const std::size_t n = request.instances.size();
  mappings_.clear();
  rects_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    Camera camera = request.view.camera;
    camera.model = request.instances[i].model;
    mappings_.emplace_back(camera, request.view.grid);
    rects_[i] = box_cells(mappings_.back(), request.instances[i].mt->bounds);
  }
}

void SceneExtractor::occupancy(const SceneRequest& request, SceneStats& stats) {
  const GridSize grid = request.view.grid;
  const std::size_t cells = grid.cell_count();
  occupancy_.assign(cells, 0);
  depth_.assign(cells, kFar);
  owner_.assign(cells, kNoInstance);
  instance_occupancy_.resize(cells);
  instance_depth_.resize(cells);
  for (std::size_t i = 0; i < request.instances.size(); ++i) {
    const CellRect& rect = rects_[i];
    if (rect.empty()) continue;
    const SceneInstance& instance = request.instances[i];
    const ViewMapping& mapping = mappings_[i];
    // The occupancy cut sized to the cells the instance's bounding sphere covers (the mapping's
    // pixels are in the instance's model units).
    const model::Bounds& box = instance.mt->bounds;
    const OccupancyLevel& level =
        instance.levels->for_covered_cells(covered_cells(mapping, box.centre(), box.radius()));
    // Depths from the cut's own triangles (a hole's cap is not a surface); the nearest wins a cell.
    stats.rasterized += rasterize_occupancy_compact(mapping, level.positions, level.cut_triangles(),
                                                    instance_occupancy_, instance_depth_, projected_);
    // Only the cells the instance's box may cover can hold its surface.
    for (std::uint32_t y = rect.y0; y < rect.y1; ++y) {
      for (std::uint32_t c = grid.cell(rect.x0, y), end = c + (rect.x1 - rect.x0); c < end; ++c) {
        if (!instance_occupancy_[c]) continue;
        occupancy_[c] = 1;
        if (owner_[c] == kNoInstance || instance_depth_[c] < depth_[c]) {
          depth_[c] = instance_depth_[c];
          owner_[c] = static_cast<std::uint32_t>(i);
        }
      }
    }
  }
  if (request.view.allowed.hidden_factor != 1.0f) {
    visible_depth_.resize(cells);
    visible_depth_bound(depth_, grid, visible_depth_);
  } else {
    visible_depth_.clear();
  }
}

void SceneExtractor::distance_transforms(const SceneRequest& request, std::optional<Criterion> only) {
  const ViewRequest& r = request.view;
  const GridSize grid = r.grid;
  if (only) {
    std::vector<std::uint16_t>& out = dt_[*only];
    out.clear();
    if (!criterion_transform_needed(r, *only)) return;
    out.resize(grid.cell_count());
    assert(traits(*only).seeds == Seeds::kPoints);  // needs no occupancy
    return criterion_transform(transformer_, *only, r, {}, cells_, out);
  }
  // The picture's outline: background, and where two instances' surfaces meet the nearer one's
  // edge seeds the farther cell (as a depth jump does with internal silhouettes).
  seeds_image_ = occupancy_;
  for (std::uint32_t y = 0; y < grid.height; ++y) {
    for (std::uint32_t x = 0; x < grid.width; ++x) {
      const std::uint32_t c = grid.cell(x, y);
      if (owner_[c] == kNoInstance) continue;
      auto meet = [&](std::uint32_t d) {
        if (owner_[d] == kNoInstance || owner_[d] == owner_[c]) return;
        seeds_image_[depth_[c] < depth_[d] ? d : c] = 0;
      };
      if (x + 1 < grid.width) meet(c + 1);
      if (y + 1 < grid.height) meet(c + grid.width);
    }
  }
  if (r.internal_silhouettes) mark_depth_discontinuities(depth_, grid, r.depth_jump, seeds_image_);
  for (const Criterion c : kAllCriteria) {
    std::vector<std::uint16_t>& out = dt_[c];
    out.clear();
    if (!criterion_transform_needed(r, c)) continue;
    out.resize(grid.cell_count());
    criterion_transform(transformer_, c, r, seeds_image_, cells_, out);
  }
}

void SceneExtractor::bind_fields(const SceneRequest& request) {
  AllowedErrorOptions options = request.view.allowed;
  if (options.metric == DistanceMetric::kEuclidean)
    options.metric =
        DistanceMetric::kChamfer5711;  // labels in fifths of a pixel (DistanceTransformer::labels)
  PerCriterion<std::span<const std::uint16_t>> transforms;
  for (const Criterion c : kAllCriteria) {
    transforms[c] = dt_[c];
    if (dt_[c].empty()) options.criteria[c].reset();
  }
  const float bound = options.error;
  fields_.resize(request.instances.size());
  // With hidden surfaces coarsened, an instance in view that no cell of the picture shows is hidden
  // whole by others: its coarsest cut. (Near an occluder's outline the per-vertex test keeps detail,
  // as a cell next to the background is never behind the surface.) Out of view is the frustum
  // factor's business.
  const bool hiding = request.view.allowed.hidden_factor != 1.0f;
  hidden_whole_.resize(request.instances.size());
  for (std::size_t i = 0; i < request.instances.size(); ++i) hidden_whole_[i] = hiding && !rects_[i].empty();
  for (const std::uint32_t owner : owner_) {
    if (owner != kNoInstance) hidden_whole_[owner] = 0;
  }
  for (std::size_t i = 0; i < request.instances.size(); ++i) {
    const SceneInstance& instance = request.instances[i];
    // A pixel bound is converted by each instance's mapping, which knows its matrix's stretch. A
    // bound in units holds in the world: a model-space error of e/s moves no point farther than e
    // once stretched at most s times.
    if (options.units == ErrorUnits::kModel) options.error = bound / largest_stretch(instance.model);
    fields_[i].bind(mappings_[i], options,
                    {transforms, instance.mt->positions, instance.mt->normals, visible_depth_});
  }
}

Result<std::size_t> SceneExtractor::refine_all(const SceneRequest& request, cut::Rank threshold,
                                               std::size_t stop_above) {
  trial_.resize(request.instances.size());
  std::size_t total = 0;
  for (std::size_t i = 0; i < request.instances.size(); ++i) {
    PerModel& model = per_model(*request.instances[i].mt);
    cut::Refinement what = cut::Refinement::from_root(fields_[i], model.field);
    what.allowed.threshold = hidden_whole_[i] ? cut::Rank{1, kFar} : threshold;
    MTLOD_RETURN_IF_ERROR(model.refiner.refine(what, trial_[i]));
    total += trial_[i].triangle_count();
    if (total > stop_above) break;
  }
  return total;
}

Result<SceneStats> SceneExtractor::refine(const SceneRequest& request, std::vector<cut::CutMesh>& cuts,
                                          SceneStats stats, std::optional<float> hint) {
  const std::optional<std::size_t> budget = request.view.budget;
  auto take = [&](cut::Rank threshold, std::size_t total) {
    cuts.swap(trial_);
    stats.threshold = threshold;
    stats.triangles = total;
  };
  // The error bound alone: the cut a budget's worst-first refinement would stop at anyway.
  MTLOD_TRY(std::size_t total, refine_all(request, cut::Rank{}, budget.value_or(SIZE_MAX)));
  stats.passes = 1;
  if (!budget || total <= *budget) {
    take(cut::Rank{}, total);
    return stats;
  }
  // The finest threshold whose cuts fit. The count falls as the threshold rises, roughly as its
  // inverse on smooth surfaces: the next guess scales by count / budget until one fits, then
  // interpolates between the two sides in logarithms, never closer than a tenth to either end.
  double over = 1.0, fits = 0.0;  // fits = 0: none found yet
  double over_count = static_cast<double>(total), fits_count = 0.0;
  bool found = false;
  const double target = static_cast<double>(*budget);
  while (stats.passes < kMaxPasses) {
    double next;
    if (!found) {
      // A gaze moves the threshold little: the session's last one first.
      next = hint && *hint > over ? *hint : over * std::max(1.25, 1.05 * over_count / target);
      hint.reset();
      if (next > kLargestThreshold) break;
    } else {
      if (fits / over < kClosest || fits_count >= kFilled * target) break;
      const double span = std::log(fits / over);
      double at = fits_count > 0 ? std::log(over_count / target) / std::log(over_count / fits_count) : 0.5;
      at = std::clamp(std::isfinite(at) ? at : 0.5, 0.1, 0.9);
      next = over * std::exp(at * span);
    }
    const cut::Rank threshold{0, static_cast<float>(next)};
    MTLOD_TRY(total, refine_all(request, threshold, *budget));
    ++stats.passes;
    if (total <= *budget) {
      if (!found || total > fits_count) take(threshold, total);
      found = true;
      fits = next;
      fits_count = static_cast<double>(total);
    } else {
      over = next;
      over_count = static_cast<double>(total);
    }
  }
  if (found) return stats;
  // Nothing but the roots is coarse enough (or the triangles allowed no error fill the budget).
  const cut::Rank roots{1, kFar};
  MTLOD_TRY(total, refine_all(request, roots, SIZE_MAX));
  ++stats.passes;
  take(roots, total);
  stats.within_budget = total <= *budget;
  return stats;
}

std::size_t SceneCache::memory_bytes() const {
  auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
  std::size_t total = bytes(instances_) + bytes(visible_depth_) + bytes(owner_);
  for (const auto& dt : transforms_.entries) total += bytes(dt);
  for (const Criterion c : kAllCriteria) total += bytes(view_.points[c]);
  return total;
}

bool SceneExtractor::same_view(const SceneCache& s, const SceneRequest& request) {
  const ViewRequest& a = s.view_;
  const ViewRequest& b = request.view;
  for (const Criterion c : kAllCriteria) {
    if (c != kGazeCriterion && a.points[c] != b.points[c]) return false;
  }
  if (!s.valid_ || a.camera.view != b.camera.view || a.camera.projection != b.camera.projection ||
      a.grid.width != b.grid.width || a.grid.height != b.grid.height || !(a.allowed == b.allowed) ||
      s.has_gaze_ == b.points[kGazeCriterion].empty() || a.internal_silhouettes != b.internal_silhouettes ||
      a.depth_jump != b.depth_jump || s.instances_.size() != request.instances.size())
    return false;
  for (std::size_t i = 0; i < s.instances_.size(); ++i) {
    const SceneInstance &x = s.instances_[i], &y = request.instances[i];
    if (x.mt != y.mt || x.levels != y.levels || x.model != y.model) return false;
  }
  return true;
}

void SceneExtractor::remember(const SceneRequest& request, const SceneStats& stats, SceneCache& s) const {
  s.valid_ = true;
  s.view_ = request.view;
  s.has_gaze_ = !request.view.points[kGazeCriterion].empty();
  s.view_.points[kGazeCriterion].clear();
  s.view_.budget.reset();
  s.instances_.assign(request.instances.begin(), request.instances.end());
  for (const Criterion c : kAllCriteria) {
    if (c == kGazeCriterion) {
      s.transforms_[c].clear();
    } else {
      s.transforms_[c] = dt_[c];
    }
  }
  s.visible_depth_ = visible_depth_;
  s.owner_ = owner_;
  s.rasterized_ = stats.rasterized;
}

void SceneExtractor::recall(const SceneCache& s, SceneStats& stats) {
  for (const Criterion c : kAllCriteria) {
    if (c != kGazeCriterion) dt_[c] = s.transforms_[c];
  }
  visible_depth_ = s.visible_depth_;
  owner_ = s.owner_;
  stats.rasterized = s.rasterized_;
}

Result<SceneStats> SceneExtractor::extract(const SceneRequest& request, std::vector<cut::CutMesh>& cuts,
                                           StageObserver* observer, SceneCache* session) {
  assert(request.view.grid.valid());
  const auto finished = [observer](Stage stage) {
    if (observer) observer->finished(stage);
  };
  SceneStats stats;
  map(request);
  for (const CellRect& rect : rects_) stats.instances_in_view += !rect.empty();
  finished(Stage::kMap);
  const bool gaze = session != nullptr && same_view(*session, request);
  if (session) session->reused_ = gaze;
  if (gaze) {
    // Only the gaze points moved: the view's picture and other transforms are the session's.
    recall(*session, stats);
    finished(Stage::kOccupancy);
    distance_transforms(request, kGazeCriterion);
  } else {
    occupancy(request, stats);
    finished(Stage::kOccupancy);
    distance_transforms(request);
    if (session) remember(request, stats, *session);
  }
  finished(Stage::kTransforms);
  bind_fields(request);
  finished(Stage::kAllowedError);
  std::optional<float> hint;
  if (session && session->threshold_budget_ == request.view.budget) hint = session->threshold_;
  Result<SceneStats> result = refine(request, cuts, stats, hint);
  if (session && result) {
    const cut::Rank threshold = result->threshold;
    session->threshold_budget_ = request.view.budget;
    session->threshold_ =
        threshold.tier == 0 && threshold.key > 1.0f ? std::optional(threshold.key) : std::nullopt;
  }
  finished(Stage::kRefine);
  return result;
}

std::size_t SceneExtractor::memory_bytes() const {
  auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
  std::size_t total = bytes(mappings_) + bytes(rects_) + bytes(hidden_whole_) + transformer_.memory_bytes() +
                      bytes(occupancy_) + bytes(instance_occupancy_) + bytes(seeds_image_) + bytes(depth_) +
                      bytes(instance_depth_) + bytes(visible_depth_) + bytes(owner_) + bytes(cells_) +
                      bytes(projected_);
  for (const auto& dt : dt_.entries) total += bytes(dt);
  for (const AllowedErrorField& field : fields_) total += sizeof(field) + field.memory_bytes();
  for (const cut::CutMesh& cut : trial_) total += bytes(cut.triangles) + bytes(cut.ids);
  for (const auto& [mt, model] : models_)
    total += model->refiner.memory_bytes() + model->field.resident_bytes();
  return total;
}

}  // namespace mtlod::core::view

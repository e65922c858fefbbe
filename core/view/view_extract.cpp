// One view-dependent extraction, stage by stage (see view_extract.hpp).
#include "core/view/view_extract.hpp"

#include <algorithm>
#include <cassert>

#include "core/model/bounds.hpp"
#include "core/view/labels.hpp"
#include "core/view/occupancy.hpp"

namespace mtlod::core::view {

// What the refiner asks for in a session: forwarded to ViewExtractor::fill_known.
class ViewExtractor::KnownSource final : public cut::VertexErrorSource {
 public:
  explicit KnownSource(ViewExtractor& extractor) : extractor_(extractor) {}
  float vertex_allowed_error(std::uint32_t vertex) const override {
    extractor_.fill_known(std::span(&vertex, 1), extractor_.allowed_);
    return extractor_.allowed_[vertex];
  }
  void fill(std::span<const std::uint32_t> vertices, std::span<float> field) const override {
    extractor_.fill_known(vertices, field);
  }

 private:
  ViewExtractor& extractor_;
};

ViewExtractor::ViewExtractor(const model::Mt& mt, const OccupancyLevels& levels) : mt_(mt), levels_(levels) {
  // Bounding sphere (box centre and half diagonal): enough to pick the occupancy cut's error.
  const model::Bounds& box = mt.bounds;
  centre_ = box.centre();
  radius_ = box.radius();
}

std::size_t ViewCache::memory_bytes() const {
  auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
  std::size_t criteria = 0;
  for (const Criterion c : kAllCriteria) criteria += bytes(transforms_[c]) + bytes(points_[c]);
  return allowed_error_.resident_bytes() + known_bits_.resident_bytes() + criteria + bytes(visible_depth_) +
         bytes(gaze_factor_) + bytes(known_vertices_) + bytes(known_cells_) + bytes(known_clip_w_) +
         bytes(cell_last_known_) + bytes(known_in_cell_before_) + bytes(cell_changed_) +
         bytes(changed_cells_) + bytes(changed_) + bytes(gaze_cells_);
}

bool ViewExtractor::same_view(const ViewCache& s, const ViewRequest& r) {
  for (const Criterion c : kAllCriteria) {
    if (c != kGazeCriterion && s.points_[c] != r.points[c]) return false;
  }
  return s.valid_ && s.camera_.model == r.camera.model && s.camera_.view == r.camera.view &&
         s.camera_.projection == r.camera.projection && s.grid_.width == r.grid.width &&
         s.grid_.height == r.grid.height && s.allowed_ == r.allowed &&
         s.has_gaze_ == !r.points[kGazeCriterion].empty() &&
         s.internal_silhouettes_ == r.internal_silhouettes && s.depth_jump_ == r.depth_jump;
}

void ViewExtractor::map(const ViewRequest& request, ViewCache* session) {
  assert(request.grid.valid());
  request_ = &request;
  session_ = session;
  mapping_ = ViewMapping(request.camera, request.grid);
  incremental_ = session != nullptr && same_view(*session, request) &&
                 session->allowed_error_.size() == mt_.vertex_count();
  if (session) session->reused_ = incremental_;
}

double covered_cells(const ViewMapping& mapping, const std::array<float, 3>& centre, float radius) {
  float clip_w = 0;
  mapping.map_point(centre[0], centre[1], centre[2], &clip_w);
  const GridSize grid = mapping.grid();
  const double grid_cells = static_cast<double>(grid.cell_count());
  if (!(clip_w > radius)) return grid_cells;
  const double cell = mapping.model_units_per_pixel(clip_w, static_cast<float>(grid.height));
  const double radius_cells = radius / cell;
  return std::min(grid_cells, 3.14159265358979 * radius_cells * radius_cells);
}

double ViewExtractor::covered_cells() const {
  return view::covered_cells(mapping_, centre_, radius_);
}

std::size_t ViewExtractor::occupancy() {
  const bool hidden = request_->allowed.hidden_factor != 1.0f;
  if (incremental_) {
    occupancy_level_ = nullptr;  // the silhouette transform and the visible depths are the session's
    visible_depth_ = session_->visible_depth_;
    return 0;
  }
  const OccupancyLevel& level = levels_.for_covered_cells(covered_cells());
  occupancy_level_ = &level;
  const std::size_t cells = request_->grid.cell_count();
  occupancy_.resize(cells);
  if (request_->internal_silhouettes || hidden) {
    // Depths come from the cut's own triangles: a hole's cap is not a surface.
    depth_.resize(cells);
    rasterize_occupancy_compact(mapping_, level.positions, level.cut_triangles(), occupancy_, depth_,
                                projected_);
  } else {
    rasterize_occupancy_compact(mapping_, level.positions, level.triangles, occupancy_, {}, projected_,
                                level.closed);
  }
  if (hidden) {
    visible_depth_bound_.resize(cells);
    visible_depth_bound(depth_, request_->grid, visible_depth_bound_);
    visible_depth_ = visible_depth_bound_;
  } else {
    visible_depth_ = {};
  }
  return level.triangle_count();
}

bool criterion_transform_needed(const ViewRequest& r, Criterion c) {
  switch (traits(c).seeds) {
    case Seeds::kBackground:
      // Labels read the silhouette distance when there is no gaze to measure from.
      return r.allowed.criteria[c] || (r.labels && r.points[kGazeCriterion].empty());
    case Seeds::kPoints:
      return r.allowed.criteria[c] && !r.points[c].empty();
    case Seeds::kBorder:
      return r.allowed.criteria[c].has_value();
  }
  return false;
}

namespace {
// The cells of a criterion's points (kNoCell for those off the grid).
void point_cells(GridSize grid, std::span<const std::array<float, 2>> points,
                 std::vector<std::uint32_t>& cells) {
  cells.clear();
  for (const auto& p : points) cells.push_back(focus_cell(grid, p[0], p[1]));
}
}  // namespace

void criterion_transform(DistanceTransformer& transformer, Criterion c, const ViewRequest& r,
                         std::span<const std::uint8_t> background, std::vector<std::uint32_t>& cells,
                         std::span<std::uint16_t> out) {
  const DistanceMetric metric = r.allowed.metric;
  switch (traits(c).seeds) {
    case Seeds::kBackground:
      return transformer.labels(metric, background, r.grid, out);
    case Seeds::kPoints:
      point_cells(r.grid, r.points[c], cells);
      return transformer.labels_from_cells(metric, cells, r.grid, out);
    case Seeds::kBorder:
      cells.clear();
      for (std::uint32_t x = 0; x < r.grid.width; ++x) {
        cells.push_back(r.grid.cell(x, 0));
        cells.push_back(r.grid.cell(x, r.grid.height - 1));
      }
      for (std::uint32_t y = 1; y + 1 < r.grid.height; ++y) {
        cells.push_back(r.grid.cell(0, y));
        cells.push_back(r.grid.cell(r.grid.width - 1, y));
      }
      return transformer.labels_from_cells(metric, cells, r.grid, out);
  }
}

void ViewExtractor::distance_transforms() {
  const ViewRequest& r = *request_;
  const std::size_t cells = r.grid.cell_count();
  // Internal silhouettes seed the silhouette transform at depth jumps too.
  std::span<const std::uint8_t> background = occupancy_;
  if (!incremental_ && r.internal_silhouettes && criterion_transform_needed(r, Criterion::kSilhouette)) {
    seeds_image_ = occupancy_;
    mark_depth_discontinuities(depth_, r.grid, r.depth_jump, seeds_image_);
    background = seeds_image_;
  }
  for (const Criterion c : kAllCriteria) {
    // A gaze keeps the view's transforms but the gaze criterion's.
    if (incremental_ && c != kGazeCriterion) {
      transforms_[c] = session_->transforms_[c];
      continue;
    }
    std::vector<std::uint16_t>& out = dt_[c];
    out.clear();
    if (criterion_transform_needed(r, c)) {
      out.resize(cells);
      const std::optional<CellRect> rect = c == kGazeCriterion ? gaze_rect() : std::nullopt;
      if (rect) {
        transformer_.labels_from_cells_within(r.allowed.metric, cells_, r.grid, *rect, out);
      } else {
        criterion_transform(transformer_, c, r, background, cells_, out);
      }
    }
    transforms_[c] = out;
  }
}

std::optional<CellRect> ViewExtractor::gaze_rect() {
  // Past its law's reach of every gaze point the gaze multiplier is 1, and a cell's label (in
  // pixels) is at least its Chebyshev distance in cells: the transform is needed only in the boxes
  // of that radius around the points (their bounding rectangle). Labels read it everywhere.
  const ViewRequest& r = *request_;
  if (r.labels) return std::nullopt;
  const std::optional<float> reach =
      law_reach_px(*r.allowed.criteria[kGazeCriterion], grid_tan_per_px(mapping_, r.allowed));
  const GridSize grid = r.grid;
  if (!reach || !(*reach < float(std::max(grid.width, grid.height)))) return std::nullopt;
  const std::uint32_t radius = std::uint32_t(*reach) + 2;  // cells outside lie over reach + 1 px away
  point_cells(grid, r.points[kGazeCriterion], cells_);
  CellRect rect{grid.width, grid.height, 0, 0};  // empty until a point is on the grid
  for (const std::uint32_t c : cells_) {
    if (c == kNoCell) continue;
    const std::uint32_t x = c % grid.width, y = c / grid.width;
    rect.x0 = std::min(rect.x0, x > radius ? x - radius : 0);
    rect.y0 = std::min(rect.y0, y > radius ? y - radius : 0);
    rect.x1 = std::max(rect.x1, std::min(grid.width, x + radius + 1));
    rect.y1 = std::max(rect.y1, std::min(grid.height, y + radius + 1));
  }
  if (rect.empty()) return CellRect{0, 0, 1, 1};  // no point on the grid: every cell unreached
  if (2 * std::size_t{rect.width()} * rect.height() > grid.cell_count()) return std::nullopt;
  return rect;
}

void ViewExtractor::allowed_error() {
  const ViewRequest& r = *request_;
  on_demand_ = false;
  AllowedErrorOptions options = r.allowed;
  if (options.metric == DistanceMetric::kEuclidean)
    options.metric = DistanceMetric::kChamfer5711;  // see transform()
  for (const Criterion c : kAllCriteria) {
    if (transforms_[c].empty()) options.criteria[c].reset();
  }
  field_.bind(mapping_, options, {transforms_, mt_.positions, mt_.normals, visible_depth_});
  if (!incremental_) {
    util::ZeroedArray<float>& field = session_ ? session_->allowed_error_ : vertex_allowed_error_;
    // Only the entries written are read: on demand, the pages of the cut's vertices.
    if (field.size() != mt_.vertex_count()) field.reset(mt_.vertex_count());
    allowed_ = field;
    // From the root anyway: a static request, or a session's new view. Without a session a
    // dynamic request moves the refiner's cut, which compares every vertex's value.
    on_demand_ = r.allowed_error_on_demand && (!r.dynamic || session_ != nullptr);
    if (!on_demand_) field_.compute_all(allowed_);
    if (session_) {
      remember_view(*session_);
      forget_known(*session_);
      session_->allowed_error_complete_ = !on_demand_;
    }
    return;
  }
  ViewCache& s = *session_;
  allowed_ = s.allowed_error_;
  on_demand_ = !s.allowed_error_complete_;
  if (s.allowed_error_complete_ && !s.known_all_) list_all_vertices(s);
  update_known_for_gaze(s, options.metric);
}

void ViewExtractor::update_known_for_gaze(ViewCache& s, DistanceMetric metric) {
  // Only the gaze moved: a vertex's allowed error changes only where its cell's gaze multiplier did.
  s.changed_.clear();
  s.changed_cells_.clear();
  auto visit = [&](std::uint32_t c) {
    const float factor = field_.gaze_factor(c);
    if (factor == s.gaze_factor_[c]) return;
    s.gaze_factor_[c] = factor;
    if (s.cell_changed_[c]) return;
    s.cell_changed_[c] = 1;
    s.changed_cells_.push_back(c);
  };
  // The gaze multiplier is 1 from the label gaze_reach() on, and a label below it lies within
  // reach / units cells (Chebyshev) of a gaze point: a pixel step costs at least `units` in every
  // transform (the Euclidean one rounds, hence one cell more). So only boxes around the old and the
  // new gaze points can hold a changed multiplier; everywhere else it was 1 and still is.
  const GridSize grid = request_->grid;
  const std::uint32_t radius = std::uint32_t(std::min<std::size_t>(
      field_.gaze_reach() / units_per_pixel(metric) + 1, std::max(grid.width, grid.height)));
  std::size_t foci = 0;  // on the grid, old and new
  for (const std::uint32_t f : s.gaze_cells_) foci += f != kNoCell;
  for (const auto& p : request_->points[kGazeCriterion]) foci += focus_cell(grid, p[0], p[1]) != kNoCell;
  const bool whole_grid =
      foci * (2 * std::size_t{radius} + 1) * (2 * std::size_t{radius} + 1) >= grid.cell_count();
  // A cell in two boxes is visited twice; the second visit finds its multiplier stored.
  auto visit_boxes = [&] {
    for (const std::uint32_t f : s.gaze_cells_) {
      if (f == kNoCell) continue;
      const std::uint32_t fx = f % grid.width, fy = f / grid.width;
      const std::uint32_t x0 = fx > radius ? fx - radius : 0, x1 = std::min(grid.width - 1, fx + radius);
      const std::uint32_t y0 = fy > radius ? fy - radius : 0, y1 = std::min(grid.height - 1, fy + radius);
      for (std::uint32_t y = y0; y <= y1; ++y)
        for (std::uint32_t x = x0; x <= x1; ++x) visit(grid.cell(x, y));
    }
  };
  if (whole_grid) {
    for (std::uint32_t c = 0; c < grid.cell_count(); ++c) visit(c);
  } else {
    visit_boxes();  // around the old gaze points
  }
  remember_gaze_cells(s);
  if (!whole_grid) visit_boxes();  // around the new ones
  if (s.changed_cells_.empty()) return;
  // The cell's labels give one multiplier for all its vertices, and each known vertex's depth was
  // kept with it: no vertex is projected again (the same values as field_.vertex_allowed_error(v),
  // which maps the vertex to this cell and depth).
  for (const std::uint32_t c : s.changed_cells_) {
    s.cell_changed_[c] = 0;
    const float multiplier = field_.cell_multiplier(c);
    for (std::uint32_t k = s.cell_last_known_[c]; k != ViewCache::kNoKnown; k = s.known_in_cell_before_[k]) {
      const std::uint32_t v = s.known_vertices_[k];
      allowed_[v] = field_.vertex_allowed_error_in_cell(multiplier, c, s.known_clip_w_[k], v);
      s.changed_.push_back(v);
    }
  }
  vertices_computed_ += s.changed_.size();
}

void ViewExtractor::remember_gaze_cells(ViewCache& s) const {
  point_cells(request_->grid, request_->points[kGazeCriterion], s.gaze_cells_);
}

void ViewExtractor::remember_gaze(ViewCache& s) const {
  const std::size_t cells = request_->grid.cell_count();
  s.gaze_factor_.resize(cells);
  for (std::uint32_t c = 0; c < cells; ++c) s.gaze_factor_[c] = field_.gaze_factor(c);
  s.cell_changed_.assign(cells, 0);
  remember_gaze_cells(s);
}

void ViewExtractor::remember_view(ViewCache& s) const {
  const ViewRequest& r = *request_;
  s.valid_ = true;
  s.camera_ = r.camera;
  s.grid_ = r.grid;
  s.allowed_ = r.allowed;
  for (const Criterion c : kAllCriteria) {
    const bool gaze = c == kGazeCriterion;  // moves with every gaze: recomputed each time
    if (gaze) {
      s.points_[c].clear();
      s.transforms_[c].clear();
    } else {
      s.points_[c] = r.points[c];
      s.transforms_[c].assign(transforms_[c].begin(), transforms_[c].end());
    }
  }
  s.has_gaze_ = !r.points[kGazeCriterion].empty();
  s.internal_silhouettes_ = r.internal_silhouettes;
  s.depth_jump_ = r.depth_jump;
  s.visible_depth_.assign(visible_depth_.begin(), visible_depth_.end());
  remember_gaze(s);
  s.changed_.clear();
}

void ViewExtractor::list_all_vertices(ViewCache& s) {
  // The cells compute_all saw (map_vertices is bit-identical to the per-vertex mapping).
  const std::size_t n = mt_.vertex_count();
  s.known_vertices_.resize(n);
  s.known_cells_.resize(n);
  s.known_clip_w_.resize(n);
  for (std::uint32_t v = 0; v < n; ++v) s.known_vertices_[v] = v;
  map_vertices(mapping_, mt_.positions, s.known_cells_, s.known_clip_w_);
  s.known_all_ = true;
  link_known(s, 0);
}

void ViewExtractor::link_known(ViewCache& s, std::size_t first) {
  if (first == 0) s.cell_last_known_.assign(s.grid_.cell_count(), ViewCache::kNoKnown);
  s.known_in_cell_before_.resize(s.known_vertices_.size());
  for (std::size_t k = first; k < s.known_vertices_.size(); ++k) {
    const std::uint32_t c = s.known_cells_[k];
    if (c == kNoCell) continue;  // no gaze multiplier off the grid
    s.known_in_cell_before_[k] = s.cell_last_known_[c];
    s.cell_last_known_[c] = std::uint32_t(k);
  }
}

void ViewExtractor::forget_known(ViewCache& s) {
  if (!s.known_all_)
    for (const std::uint32_t v : s.known_vertices_) util::clear_bit(s.known_bits_, v);
  s.known_all_ = false;
  s.known_vertices_.clear();
  s.known_cells_.clear();
  s.known_clip_w_.clear();
  link_known(s, 0);
}

void ViewExtractor::fill_known(std::span<const std::uint32_t> vertices, std::span<float> field) {
  ViewCache& s = *session_;
  const std::size_t words = (mt_.vertex_count() + 63) / 64;
  if (s.known_bits_.size() != words) s.known_bits_.reset(words);
  unknown_.clear();
  for (const std::uint32_t v : vertices) {
    if (util::test_bit(s.known_bits_, v))
      continue;  // up to date: computed for this view, changed by its gazes
    util::set_bit(s.known_bits_, v);
    unknown_.push_back(v);
  }
  if (unknown_.empty()) return;
  const std::size_t first = s.known_vertices_.size(), count = unknown_.size();
  s.known_vertices_.insert(s.known_vertices_.end(), unknown_.begin(), unknown_.end());
  s.known_cells_.resize(first + count);
  s.known_clip_w_.resize(first + count);
  field_.fill_mapped(unknown_, field, std::span(s.known_cells_).subspan(first),
                     std::span(s.known_clip_w_).subspan(first));
  link_known(s, first);
  vertices_computed_ += count;
}

void ViewExtractor::forget_unread(cut::Refiner& refiner) {
  // Known vertices are updated at every gaze, so those of cuts long gone cost time until forgotten.
  // They are forgotten in one pass once they are four times those the cut reads: the cut's own
  // stay known, and a vertex forgotten is asked for again should a later cut read it.
  ViewCache& s = *session_;
  const std::size_t read = refiner.cut_nodes().size() + mt_.root_triangle_count();  // about, from above
  if (s.known_vertices_.size() <= 4 * read) return;
  ++s.forgets_;
  for (const std::uint32_t v : s.known_vertices_) util::clear_bit(s.known_bits_, v);
  refiner.for_each_cut_vertex([&](std::uint32_t v) { util::set_bit(s.known_bits_, v); });
  std::size_t kept = 0;
  for (std::size_t k = 0; k < s.known_vertices_.size(); ++k) {
    const std::uint32_t v = s.known_vertices_[k];
    if (!util::test_bit(s.known_bits_, v)) continue;
    s.known_vertices_[kept] = v;
    s.known_cells_[kept] = s.known_cells_[k];
    s.known_clip_w_[kept] = s.known_clip_w_[k];
    ++kept;
  }
  s.known_vertices_.resize(kept);
  s.known_cells_.resize(kept);
  s.known_clip_w_.resize(kept);
  link_known(s, 0);
  // Every vertex the cut reads was asked for (fill_known), so the bits set above are exactly those
  // of the entries kept.
}

void ViewExtractor::prepare(const ViewRequest& request, ViewCache* session, StageObserver* observer) {
  const auto finished = [observer](Stage stage) {
    if (observer) observer->finished(stage);
  };
  map(request, session);
  finished(Stage::kMap);
  occupancy();
  finished(Stage::kOccupancy);
  distance_transforms();
  finished(Stage::kTransforms);
  allowed_error();
  finished(Stage::kAllowedError);
}

Result<cut::CutSpan> ViewExtractor::extract(const ViewRequest& request, cut::Refiner& refiner,
                                            cut::CutMesh& scratch, ViewCache* session,
                                            StageObserver* observer) {
  prepare(request, session, observer);
  Result<cut::CutSpan> cut = refine_view(refiner, scratch);
  if (observer) observer->finished(Stage::kRefine);
  return cut;
}

std::span<const float> ViewExtractor::allowed_error_field(const ViewRequest& request) {
  field_request_ = request;
  field_request_.dynamic = false;
  field_request_.allowed_error_on_demand = false;
  prepare(field_request_, nullptr, nullptr);
  return allowed_;
}

Status ViewExtractor::refine(cut::Refiner& session, cut::CutMesh& out) {
  MTLOD_TRY(const cut::CutSpan cut, refine_view(session, out));
  out.assign(cut);
  return Ok{};
}

Result<cut::CutSpan> ViewExtractor::refine_view(cut::Refiner& session, cut::CutMesh& scratch) {
  const cut::AllowedError allowed = cut::AllowedError::from_vertices(allowed_);
  // In a session, what the refinement asks for becomes known to the view's gazes.
  const KnownSource known(*this);
  const cut::VertexErrorSource& source =
      session_ ? static_cast<const cut::VertexErrorSource&>(known) : field_;
  const bool gaze = request_->dynamic && incremental_;
  const std::span<const std::uint32_t> changed =
      session_ ? session_->changed_ : std::span<const std::uint32_t>();
  // The one place a request's refinement is chosen. A gaze moves the session's cut (even after a
  // saccade: cheaper than from the root); a new view with a budget in a session keeps its cut for
  // the gazes that follow; a dynamic request without a session compares the whole field.
  cut::Refinement what;
  if (gaze) {
    what = on_demand_ ? cut::Refinement::move(source, allowed_, changed)
                      : cut::Refinement::move(allowed, changed);
  } else if (on_demand_) {
    what = cut::Refinement::from_root(source, allowed_);
  } else if (request_->dynamic && !request_->budget) {
    what = cut::Refinement::move(allowed);
  } else {
    what = cut::Refinement::from_root(allowed);
  }
  if (request_->budget) {
    what.within(*request_->budget);
    if (request_->dynamic && session_) what.keeping();
  }
  Result<cut::CutSpan> refined = session.refine_view(what, scratch);
  if (!refined) {
    // The session's known vertices belong to a cut the refiner no longer holds.
    if (session_) session_->reset();
    return refined;
  }
  const cut::CutSpan cut = *refined;
  if (session_ && on_demand_) forget_unread(session);
  if (request_->labels) {
    // Labels of the cut's vertices only: the silhouette distance when it was computed, else the gaze's.
    const std::span<const std::uint16_t> silhouette = transforms_[Criterion::kSilhouette];
    const std::span<const std::uint16_t> dt = !silhouette.empty() ? silhouette : transforms_[kGazeCriterion];
    if (vertex_labels_.size() != mt_.vertex_count()) vertex_labels_.reset(mt_.vertex_count());
    for (std::uint32_t v : cut.triangles)
      vertex_labels_[v] = dt.empty() ? 0 : vertex_label(mapping_, mt_.positions, v, dt);
  }
  return cut;
}

std::size_t ViewExtractor::memory_bytes() const {
  auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
  std::size_t dt_bytes = 0;
  for (const auto& dt : dt_.entries) dt_bytes += bytes(dt);
  return transformer_.memory_bytes() + bytes(occupancy_) + bytes(seeds_image_) + bytes(depth_) +
         bytes(visible_depth_bound_) + dt_bytes + bytes(cells_) + vertex_allowed_error_.resident_bytes() +
         vertex_labels_.resident_bytes() + bytes(projected_) + bytes(unknown_) + field_.memory_bytes();
}

}  // namespace mtlod::core::view

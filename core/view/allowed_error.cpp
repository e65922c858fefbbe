// Allowed error (core/ARCHITECTURE.md §1.5). See the header for why a per-vertex array whose
// triangle value is the minimum over the vertices reproduces the papers' triangle-label law.
#include "core/view/allowed_error.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>

namespace mtlod::core::view {

namespace {

constexpr float kInfinity = std::numeric_limits<float>::infinity();

}  // namespace

float eccentricity_deg(float distance_px, float tan_per_px) {
  return std::atan(distance_px * tan_per_px) * (180.0f / std::numbers::pi_v<float>);
}

float law_factor(const RegionLaw& law, float distance_px, float tan_per_px) {
  // Unlabeled (no cell, or no seed anywhere): outside every region.
  if (!(distance_px < kInfinity)) return 1.0f;
  const float f = law.factor;
  switch (law.law) {
    case FalloffLaw::kStep:
      return distance_px <= law.distance_px ? f : 1.0f;
    case FalloffLaw::kLinear:
    case FalloffLaw::kSmoothstep: {
      if (distance_px <= law.distance_px) return f;
      if (!(law.falloff_px > 0.0f) || distance_px >= law.distance_px + law.falloff_px) return 1.0f;
      float t = (distance_px - law.distance_px) / law.falloff_px;
      if (law.law == FalloffLaw::kSmoothstep) t = t * t * (3.0f - 2.0f * t);
      return f + (1.0f - f) * t;
    }
    case FalloffLaw::kFoveal: {
      // Acuity falls linearly with eccentricity (MAR grows as 1 + e/e2), and so may the error. f < 1
      // refines around the focus and never exceeds the base error; f ≥ 1 makes the base error (times f)
      // the bound at the focus, growing without a cap (tests/evaluation/FIDELITY.md's default, f = 1).
      const float grown = f * (1.0f + eccentricity_deg(distance_px, tan_per_px) / law.foveal_e2_deg);
      return f < 1.0f ? std::min(grown, 1.0f) : grown;
    }
  }
  return 1.0f;
}

std::optional<float> law_reach_px(const RegionLaw& law, float tan_per_px) {
  switch (law.law) {
    case FalloffLaw::kStep:
      return law.distance_px;
    case FalloffLaw::kLinear:
    case FalloffLaw::kSmoothstep:
      return law.distance_px + std::max(law.falloff_px, 0.0f);
    case FalloffLaw::kFoveal: {
      const float f = law.factor;
      if (!(f > 0.0f && f < 1.0f && law.foveal_e2_deg > 0.0f && tan_per_px > 0.0f)) return std::nullopt;
      // f·(1 + e/e2) reaches 1 at e = e2·(1/f − 1): a little further, so that rounding cannot leave
      // the multiplier just below 1 there.
      const double e = double(law.foveal_e2_deg) * (1.0 / f - 1.0) * 1.001 + 1e-3;
      if (!(e < 89.0)) return std::nullopt;
      return static_cast<float>(std::tan(e * (std::numbers::pi / 180.0)) / tan_per_px);
    }
  }
  return std::nullopt;
}

float grid_tan_per_px(const ViewMapping& mapping, const AllowedErrorOptions& options) {
  const float tan_half_fovy = options.fovy_deg > 0.0f
                                  ? std::tan(options.fovy_deg * (std::numbers::pi_v<float> / 360.0f))
                                  : 1.0f / mapping.projection_y_scale();
  return 2.0f * tan_half_fovy / static_cast<float>(mapping.grid().height);
}

void AllowedErrorField::bind(const ViewMapping& mapping, const AllowedErrorOptions& options,
                             const AllowedErrorInputs& inputs) {
  const std::size_t cells = mapping.grid().cell_count();
  for ([[maybe_unused]] const Criterion c : kAllCriteria)
    assert(!options.criteria[c] || inputs.transforms[c].size() == cells);
  assert(inputs.normals.empty() || inputs.normals.size() == inputs.positions.size());
  assert(inputs.visible_depth.empty() || inputs.visible_depth.size() == cells);
  (void)cells;
  mapping_ = &mapping;
  options_ = options;
  inputs_ = inputs;
  const float grid_height = static_cast<float>(mapping.grid().height);
  viewport_height_px_ = options.viewport_height_px > 0.0f ? options.viewport_height_px : grid_height;
  tan_per_px_ = grid_tan_per_px(mapping, options);
  // error · model_units_per_pixel(clip_w) = error · 2·clip_w/(H·P[1][1]), with the constant part folded.
  pixel_bound_per_clip_w_ = options.error * mapping.model_units_per_pixel(1.0f, viewport_height_px_);
  assert(options.metric != DistanceMetric::kEuclidean);
  for (const Criterion c : kAllCriteria) {
    if (const std::optional<RegionLaw>& law = options.criteria[c])
      tabulate(*law, options.metric, tan_per_px_, inputs.transforms[c], tables_[c]);
  }
}

void AllowedErrorField::tabulate(const RegionLaw& law, DistanceMetric metric, float tan_per_px,
                                 std::span<const std::uint16_t> dt, LawTable& table) {
  // The largest label, unreached cells counting as 0. Real labels are below kChamferUnreached =
  // 0x7FFF, so raw + 1 as a signed 16-bit value is positive for them and wraps to -0x8000 for an
  // unreached cell: a plain signed maximum (one SSE2 instruction per 8 cells once vectorised).
  static_assert(kChamferUnreached == 0x7FFF);
  std::int16_t largest_plus_one = 0;
  for (const std::uint16_t raw : dt)
    largest_plus_one =
        std::max(largest_plus_one, static_cast<std::int16_t>(static_cast<std::uint16_t>(raw + 1)));
  const std::uint16_t largest = largest_plus_one == 0 ? 0 : std::uint16_t(largest_plus_one - 1);
  if (!(table.valid && table.law == law && table.metric == metric && table.tan_per_px == tan_per_px)) {
    table.values.clear();
    table.valid = true, table.law = law, table.metric = metric, table.tan_per_px = tan_per_px;
  }
  for (std::uint32_t raw = std::uint32_t(table.values.size()); raw <= largest; ++raw)
    table.values.push_back(law_factor(law, distance_px(raw, metric), tan_per_px));
}

bool AllowedErrorField::hidden(std::uint32_t cell, float clip_w, std::uint32_t vertex) const {
  const float* p = inputs_.positions.data() + 3 * std::size_t{vertex};
  // The vertex's eye depth the way the rasteriser computes a surface's (from ndc z), so that both
  // sides of the comparison agree for perspective and orthographic cameras alike.
  const float depth = mapping_->eye_depth_from_ndc_z(mapping_->clip_z(p[0], p[1], p[2]) / clip_w);
  return depth > inputs_.visible_depth[cell] * (1.0f + options_.hidden_depth_margin);
}

float AllowedErrorField::finish(float m, std::uint32_t cell, float clip_w, std::uint32_t vertex) const {
  const AllowedErrorOptions& o = options_;
  const bool has_cell = cell != kNoCell;
  if (!has_cell) m *= o.outside_view_factor;
  if (has_cell && o.hidden_factor != 1.0f && !inputs_.visible_depth.empty() && hidden(cell, clip_w, vertex))
    m *= o.hidden_factor;
  if (o.back_face_factor != 1.0f && !inputs_.normals.empty()) {
    const float* p = inputs_.positions.data() + 3 * std::size_t{vertex};
    const float* n = inputs_.normals.data() + 3 * std::size_t{vertex};
    const glm::vec4& eye = mapping_->eye_model();
    const float vx = eye.x - eye.w * p[0], vy = eye.y - eye.w * p[1], vz = eye.z - eye.w * p[2];
    const float dot = n[0] * vx + n[1] * vy + n[2] * vz;
    // dot(n, v̂) < cos  ⇔  dot(n, v) < cos·|v|, without a division.
    if (dot < o.back_face_cos * std::sqrt(vx * vx + vy * vy + vz * vz)) m *= o.back_face_factor;
  }
  if (o.units == ErrorUnits::kModel) return o.error * m;
  // A pixel bound has no meaning behind the eye; such a vertex leaves the decision to the triangle's
  // other vertices, and a triangle wholly behind the eye is invisible.
  if (!(clip_w > 0.0f)) return kInfinity;
  return pixel_bound_per_clip_w_ * clip_w * m;
}

void AllowedErrorField::compute_all(std::span<float> vertex_allowed_error) {
  assert(mapping_ != nullptr);
  const std::size_t n = inputs_.positions.size() / 3;
  assert(vertex_allowed_error.size() == n);
  // Blocks small enough for the projected cells and depths to stay in L1 between the two loops.
  constexpr std::size_t kBlock = 1024;
  cells_.resize(kBlock);
  clip_w_.resize(kBlock);
  // With fewer cells than vertices, the label part of the multiplier is tabulated per cell first
  // (cell_multiplier, as vertex_allowed_error uses it), so the values are bit for bit the same.
  const std::size_t cells = mapping_->grid().cell_count();
  const bool per_cell = cells <= n;
  if (per_cell) {
    cell_multiplier_.resize(cells);
    for (std::uint32_t c = 0; c < cells; ++c) cell_multiplier_[c] = cell_multiplier(c);
  }
  const float no_cell = cell_multiplier(kNoCell);
  for (std::size_t first = 0; first < n; first += kBlock) {
    const std::size_t count = std::min(kBlock, n - first);
    map_vertices(*mapping_, inputs_.positions.subspan(3 * first, 3 * count), std::span(cells_).first(count),
                 std::span(clip_w_).first(count));
    for (std::size_t k = 0; k < count; ++k) {
      const std::uint32_t cell = cells_[k];
      const bool has_cell = cell != kNoCell;
      const float m = !has_cell ? no_cell : per_cell ? cell_multiplier_[cell] : cell_multiplier(cell);
      vertex_allowed_error[first + k] = finish(m, cell, clip_w_[k], static_cast<std::uint32_t>(first + k));
    }
  }
}

float AllowedErrorField::cell_multiplier(std::uint32_t cell) const {
  // kStricter criteria: the smallest multiplier wins. A focus law may grow past 1 (foveal with
  // f ≥ 1: the bound holds at the focus and grows outwards), which a silhouette law caps at its 1.
  // kScales criteria then multiply the result.
  float m = kInfinity;
  for (const Criterion c : kAllCriteria) {
    if (traits(c).combine == Combine::kStricter && options_.criteria[c])
      m = std::min(m, criterion_factor(c, cell));
  }
  if (m == kInfinity) m = 1.0f;
  for (const Criterion c : kAllCriteria) {
    if (traits(c).combine == Combine::kScales && options_.criteria[c]) m *= criterion_factor(c, cell);
  }
  return m;
}

float AllowedErrorField::vertex_allowed_error(std::uint32_t vertex) const {
  assert(mapping_ != nullptr && 3 * std::size_t{vertex} + 2 < inputs_.positions.size());
  const float* p = inputs_.positions.data() + 3 * std::size_t{vertex};
  float clip_w = 0.0f;
  const std::uint32_t cell = mapping_->map_point(p[0], p[1], p[2], &clip_w);
  return finish(cell_multiplier(cell), cell, clip_w, vertex);
}

void AllowedErrorField::fill(std::span<const std::uint32_t> vertices, std::span<float> field) const {
  constexpr std::size_t kBatch = 16;
  std::uint32_t cells[kBatch];
  float clip_w[kBatch];
  for (std::size_t first = 0; first < vertices.size(); first += kBatch) {
    const std::size_t count = std::min(kBatch, vertices.size() - first);
    fill_mapped(vertices.subspan(first, count), field, std::span(cells, count), std::span(clip_w, count));
  }
}

void AllowedErrorField::fill_mapped(std::span<const std::uint32_t> vertices, std::span<float> field,
                                    std::span<std::uint32_t> cells, std::span<float> clip_w) const {
  assert(mapping_ != nullptr && cells.size() == vertices.size() && clip_w.size() == vertices.size());
  constexpr std::size_t kBatch = 16;
  float positions[3 * kBatch];
  for (std::size_t first = 0; first < vertices.size(); first += kBatch) {
    const std::size_t count = std::min(kBatch, vertices.size() - first);
    for (std::size_t k = 0; k < count; ++k) {
      const float* p = inputs_.positions.data() + 3 * std::size_t{vertices[first + k]};
      std::copy_n(p, 3, positions + 3 * k);
    }
    // map_vertices gives the cells and clip.w of map_point, bit for bit.
    const std::span<std::uint32_t> batch_cells = cells.subspan(first, count);
    const std::span<float> batch_w = clip_w.subspan(first, count);
    map_vertices(*mapping_, std::span<const float>(positions, 3 * count), batch_cells, batch_w);
    for (std::size_t k = 0; k < count; ++k) {
      const std::uint32_t v = vertices[first + k];
      field[v] = finish(cell_multiplier(batch_cells[k]), batch_cells[k], batch_w[k], v);
    }
  }
}

void compute_vertex_allowed_error(const ViewMapping& mapping, const AllowedErrorOptions& options,
                                  const AllowedErrorInputs& inputs, std::span<float> vertex_allowed_error) {
  AllowedErrorField field;
  field.bind(mapping, options, inputs);
  field.compute_all(vertex_allowed_error);
}

}  // namespace mtlod::core::view

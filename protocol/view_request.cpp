// protocol::Extract → core::ViewRequest (see view_request.hpp).
#include "protocol/view_request.hpp"

#include <algorithm>

namespace mtlod::protocol {
glm::mat4 to_glm(const Matrix4& m) {
  glm::mat4 out;
  for (int col = 0; col < 4; ++col)
    for (int row = 0; row < 4; ++row) out[col][row] = static_cast<float>(m[col * 4 + row]);
  return out;
}

core::view::ViewRequest to_view_request(const Extract& e, bool model_has_normals) {
  core::view::ViewRequest v;
  v.camera.view = to_glm(e.view);
  v.camera.projection = to_glm(e.projection);
  v.grid = {e.grid[0], e.grid[1]};
  core::view::AllowedErrorOptions& a = v.allowed;
  a.error = static_cast<float>(e.error);
  a.units = e.error_unit;
  a.viewport_height_px = static_cast<float>(e.viewport[1]);
  a.metric = e.criteria.distance;
  // Thresholds in raw units become pixels; exact Euclidean distances count fifths of a pixel.
  const float per_pixel = a.metric == core::view::DistanceMetric::kEuclidean
                              ? 5.0f
                              : static_cast<float>(core::view::units_per_pixel(a.metric));
  const float to_px = e.criteria.units == DistanceUnit::kChamfer ? 1.0f / per_pixel : 1.0f;
  for (const core::view::Criterion c : core::view::kAllCriteria) {
    const std::optional<Region>& region = e.criteria.regions[c];
    if (!region) continue;
    core::view::RegionLaw law;
    const bool foveal = e.criteria.falloff == core::view::FalloffLaw::kFoveal;
    law.law = foveal && !core::view::traits(c).foveal ? core::view::FalloffLaw::kStep : e.criteria.falloff;
    law.distance_px = static_cast<float>(region->distance) * to_px;
    law.factor = static_cast<float>(region->factor);
    a.criteria[c] = law;
    for (const Point& p : region->points)
      v.points[c].push_back({static_cast<float>(p.x), static_cast<float>(p.y)});
  }
  a.outside_view_factor = static_cast<float>(e.criteria.frustum_factor);
  a.back_face_factor = model_has_normals ? static_cast<float>(e.criteria.backface_factor) : 1.0f;
  a.hidden_factor = static_cast<float>(e.criteria.hidden_factor);
  v.internal_silhouettes = e.criteria.internal_silhouettes;
  if (e.budget) v.budget = *e.budget;
  v.labels = e.labels;
  return v;
}

core::codec::EncodeOptions to_encode_options(const Extract& e, const EncodeContext& context) {
  core::codec::EncodeOptions options;
  options.codec = e.codec.value_or(core::codec::Codec::kDraco);
  core::codec::PayloadOptions& p = options.payload;
  p.position_bits = e.quantization.position_bits;
  p.normal_bits = e.quantization.normal_bits;
  p.normals = e.normals;
  p.colors = e.colors.value_or(context.model_has_colors) && context.model_has_colors;
  p.labels = e.labels;
  p.keep_triangle_order = e.delta;
  if (e.delta) {
    // One grid for every payload of the model: a vertex kept from an earlier delta and the same
    // vertex in a new one decode to the same floats.
    core::codec::DracoOptions::Grid grid;
    grid.origin = context.bounds_min;
    for (int c = 0; c < 3; ++c)
      grid.range = std::max(grid.range, context.bounds_max[c] - context.bounds_min[c]);
    p.position_grid = grid;
  }
  const bool fast = context.gaze || e.delta;
  options.draco.method = e.draco.method.value_or(fast ? core::codec::DracoMethod::kSequential
                                                      : core::codec::DracoMethod::kEdgebreaker);
  options.draco.speed = e.draco.speed;
  options.draco.entropy_coding = e.draco.entropy_coding.value_or(!context.gaze);
  return options;
}

}  // namespace mtlod::protocol

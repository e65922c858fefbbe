// Allowed-error functions (core/ARCHITECTURE.md §1.5): turn per-vertex labels into the error a
// triangle may keep. The papers' law is two-level: allowed_error(t) = e·f if label(t) ≤ d, e otherwise
// (JVRB 2006 §4, DGCI 2006 §3.3). Beyond the papers: linear, smoothstep and foveal falloffs,
// focus-of-neglect regions, frustum, back-face and hidden-surface coarsening, and error bounds in
// screen pixels.
//
// Contract with the refinement (core/cut/refine): the output is one allowed error per VERTEX, in model
// units, and the refiner uses as a triangle's allowed error the MINIMUM over its three vertices.
// Why that is the papers' definition: the papers apply the law g to the triangle label, the minimum of
// its vertex labels. For a law g that is non-decreasing in the distance, min_v g(label_v) =
// g(min_v label_v), so the minimum of the per-vertex values is exactly g(label(t)). The step law with
// f ≤ 1 and the linear, smoothstep and foveal falloffs (which rise towards 1) are non-decreasing, and
// so is the minimum of two of them (silhouette and focus combined, the stricter wins). Factors that are
// not functions of the label (the depth of a pixel bound, back-face, hidden and frustum coarsening, the
// neglect factor > 1, which decreases with distance) make the minimum the conservative choice: a
// triangle is only coarsened when all three of its vertices allow it.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "core/cut/refine.hpp"
#include "core/view/criteria.hpp"
#include "core/view/distance_transform.hpp"
#include "core/view/labels.hpp"
#include "core/view/view_grid.hpp"

namespace mtlod::core::view {

// How one criterion (criteria.hpp) scales the allowed error with a label's distance.
struct RegionLaw {
  FalloffLaw law = FalloffLaw::kStep;
  // d: the region R = {label ≤ d} (in pixels of the grid). Ignored by kFoveal.
  float distance_px = 2.0f;
  // f: multiplier of the allowed error inside R; < 1 refines, 0 means "no simplification in R", > 1
  // coarsens (focus of neglect).
  float factor = 0.0f;
  // kLinear, kSmoothstep: width of the ramp beyond d where the multiplier goes from f to 1.
  float falloff_px = 16.0f;
  // kFoveal: eccentricity (degrees) at which the minimum angle of resolution doubles; ~2.3° is the
  // usual value for the linear acuity model MAR(e) = MAR0·(1 + e/e2).
  float foveal_e2_deg = 2.3f;

  bool operator==(const RegionLaw&) const = default;
};

struct AllowedErrorOptions {
  float error = 1.0f;  // e: the allowed error outside every region, in `units`
  ErrorUnits units = ErrorUnits::kModel;
  float viewport_height_px = 0.0f;  // kScreenPixels: the screen's height; 0 = the grid's height
  DistanceMetric metric = DistanceMetric::kChamfer5711;  // of the labels, to turn raw units into pixels
  // The law of each criterion in use (criteria.hpp: kStricter ones compete, kScales ones multiply);
  // unset: the criterion is off. The points of a point-seeded criterion share one transform.
  PerCriterion<std::optional<RegionLaw>> criteria;
  // Frustum coarsening: multiplier for vertices with no cell (1 = off). A vertex-based test: a large
  // triangle whose three vertices all lie outside the view while it crosses the view is coarsened too,
  // so keep it off for close-up views of coarse cuts.
  float outside_view_factor = 1.0f;
  // Back-face coarsening (needs normals): multiplier for vertices whose unit normal n and unit
  // direction to the eye v have dot(n, v) < back_face_cos (1 = off). Slightly negative so vertices on
  // the rim, which shape the silhouette, keep their error.
  float back_face_factor = 1.0f;
  float back_face_cos = -0.2f;
  // Hidden-surface coarsening (needs AllowedErrorInputs::visible_depth): multiplier for vertices
  // farther from the eye than (1 + hidden_depth_margin) times the visible surface around their cell
  // (1 = off). A depth test rather than a normal test, so it also finds occluded front faces and does
  // not depend on how consistently a scan's triangles are oriented. The margin absorbs the
  // difference between the coarse cut whose depths the grid holds and the model's surface.
  float hidden_factor = 1.0f;
  float hidden_depth_margin = 0.01f;
  // kFoveal: vertical field of view in degrees used to turn pixels into eccentricity; 0 = from the
  // projection (2·atan(1/P[1][1]), perspective cameras).
  float fovy_deg = 0.0f;

  bool operator==(const AllowedErrorOptions&) const = default;
};

// Eccentricity in degrees of a point distance_px grid pixels from the focus, for a view whose grid
// pixel subtends tan_per_px = 2·tan(fovy/2)/H at the view centre: atan(distance_px·tan_per_px). Exact
// for a focus at the view centre; a small-angle approximation elsewhere.
float eccentricity_deg(float distance_px, float tan_per_px);

// The multiplier a law gives at a distance of distance_px grid pixels (+inf for unlabeled vertices,
// which gives 1). tan_per_px is used by kFoveal only. Pure; exposed for tests and for the refiner.
float law_factor(const RegionLaw& law, float distance_px, float tan_per_px);
// A distance in grid pixels beyond which the law's multiplier is exactly 1 (none: it never is, a
// foveal law with f ≥ 1 or f ≤ 0).
std::optional<float> law_reach_px(const RegionLaw& law, float tan_per_px);
// The tan_per_px of a view's grid pixel that AllowedErrorField uses: 2·tan(fovy/2)/H, fovy from the
// options or else from the projection.
float grid_tan_per_px(const ViewMapping& mapping, const AllowedErrorOptions& options);

// Per-request inputs: the grids of the criteria in use (W×H chamfer transforms of the metric in the
// options, which must not be kEuclidean, seeded as the criterion's traits say; an unused criterion's
// span may be empty) and the mesh's vertex arrays.
struct AllowedErrorInputs {
  PerCriterion<std::span<const std::uint16_t>> transforms;
  std::span<const float> positions;  // x, y, z per vertex
  std::span<const float> normals;    // empty, or unit x, y, z per vertex (back-face coarsening)
  // Hidden-surface coarsening: per cell, the farthest visible eye depth (−z_eye) in the cell and its 8
  // neighbours (visible_depth_bound), +inf where any of them is background; empty = off.
  std::span<const float> visible_depth;
};

// The whole allowed-error function for one request: full (every vertex, struct-of-arrays passes) or
// lazy (one vertex on demand). Keeps its scratch arrays between requests.
class AllowedErrorField final : public cut::VertexErrorSource {
 public:
  // Binds a request. The spans must outlive the calls below.
  void bind(const ViewMapping& mapping, const AllowedErrorOptions& options, const AllowedErrorInputs& inputs);

  // Full variant: vertex_allowed_error[v] for every vertex (size = vertex count), in model units;
  // +inf for a vertex behind the camera when the bound is in pixels.
  void compute_all(std::span<float> vertex_allowed_error);

  // Bytes of scratch memory held.
  std::size_t memory_bytes() const {
    std::size_t floats = clip_w_.capacity() + cell_multiplier_.capacity();
    for (const LawTable& table : tables_.entries) floats += table.values.capacity();
    return floats * sizeof(float) + cells_.capacity() * sizeof(std::uint32_t);
  }

  // Lazy variant: the same value for one vertex, projecting it on demand (what
  // an on-demand Refinement asks for).
  float vertex_allowed_error(std::uint32_t vertex) const override;
  // The same for a batch, projected together up to 16 at a time (bit for bit the same values).
  void fill(std::span<const std::uint32_t> vertices, std::span<float> field) const override;
  // The same, also writing each vertex's grid cell (kNoCell off the grid) and clip-space w: what
  // vertex_allowed_error_in_cell takes when only the cell's labels change (cells and clip_w: one
  // entry per entry of `vertices`).
  void fill_mapped(std::span<const std::uint32_t> vertices, std::span<float> field,
                   std::span<std::uint32_t> cells, std::span<float> clip_w) const;
  // The same value for a vertex already known to lie in a grid cell with this clip-space w (as
  // map_point or map_vertices give them), with multiplier = cell_multiplier(cell).
  float vertex_allowed_error_in_cell(float multiplier, std::uint32_t cell, float clip_w,
                                     std::uint32_t vertex) const {
    return finish(multiplier, cell, clip_w, vertex);
  }
  // The part of the multiplier the cell's labels give (every law combined), for a grid cell.
  float cell_multiplier(std::uint32_t cell) const;
  // The gaze criterion's (kGazeCriterion) multiplier is 1 for every label from this one on (0:
  // everywhere; the table's length when it never reaches 1 within it).
  std::size_t gaze_reach() const {
    if (!options_.criteria[kGazeCriterion]) return 0;
    const std::vector<float>& f = tables_[kGazeCriterion].values;
    std::size_t reach = f.size();
    while (reach > 0 && f[reach - 1] == 1.0f) --reach;
    return reach;
  }

  // The gaze criterion's multiplier in a grid cell (1 when it is off). A vertex's allowed error
  // depends on the gaze transform only through this value of its cell, so when the gaze moves, only
  // vertices in cells where it changed need their allowed error again.
  float gaze_factor(std::uint32_t cell) const {
    return options_.criteria[kGazeCriterion] ? criterion_factor(kGazeCriterion, cell) : 1.0f;
  }

 private:
  // A vertex's value in two parts: the multiplier of its cell's labels (cell_multiplier), then the
  // per-vertex factors and units.
  float criterion_factor(Criterion c, std::uint32_t cell) const {
    return lookup(tables_[c], cell_label(inputs_.transforms[c], cell));
  }
  float finish(float label_multiplier, std::uint32_t cell, float clip_w, std::uint32_t vertex) const;
  // Whether a vertex in a grid cell lies behind the visible surface around it.
  bool hidden(std::uint32_t cell, float clip_w, std::uint32_t vertex) const;
  // Multiplier of a law at every raw label value present in its grid, so that no vertex pays for
  // the law itself (the foveal law's atan costs more than the rest of a vertex). A table keeps the
  // law it was made for: the next request with the same law (every gaze of a stream) only extends
  // it when its grid holds larger labels.
  struct LawTable {
    std::vector<float> values;
    bool valid = false;
    RegionLaw law{};
    DistanceMetric metric{};
    float tan_per_px = 0.0f;
  };
  static void tabulate(const RegionLaw& law, DistanceMetric metric, float tan_per_px,
                       std::span<const std::uint16_t> dt, LawTable& table);
  static float lookup(const LawTable& table, std::uint32_t label) {
    // Labels past the largest tabulated: unlabeled. (A table kept from an earlier request may reach
    // further than this grid's largest label; its values are the law's all the same.)
    return label < table.values.size() ? table.values[label] : 1.0f;
  }

  const ViewMapping* mapping_ = nullptr;
  AllowedErrorOptions options_{};
  AllowedErrorInputs inputs_{};
  float tan_per_px_ = 0.0f;
  float pixel_bound_per_clip_w_ = 0.0f;
  float viewport_height_px_ = 0.0f;
  PerCriterion<LawTable> tables_;
  std::vector<std::uint32_t> cells_;  // full variant scratch
  std::vector<float> cell_multiplier_;
  std::vector<float> clip_w_;
};

// One-off: fills vertex_allowed_error for every vertex (see AllowedErrorField::compute_all).
void compute_vertex_allowed_error(const ViewMapping& mapping, const AllowedErrorOptions& options,
                                  const AllowedErrorInputs& inputs, std::span<float> vertex_allowed_error);

}  // namespace mtlod::core::view

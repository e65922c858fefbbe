// Grid mapping (core/ARCHITECTURE.md §1.1; "mesh mapping" in JVRB 2006 §3.1, DGCI 2006 §3.1),
// computed per request: clip = P·V·M·p, ndc = clip.xyz / clip.w, cell i = floor((ndc.x+1)/2·W),
// j = floor((1−ndc.y)/2·H). A vertex behind the camera (clip.w ≤ 0) or off the grid has kNoCell.
// Matrices are GLM's, column-major like OpenGL (glm::lookAt, glm::perspective, glm::ortho).
#pragma once

#include <cstdint>
#include <span>

#include <glm/mat4x4.hpp>
#include <glm/vec4.hpp>

#include "core/view/grid.hpp"

namespace mtlod::core::view {

struct Camera {
  glm::mat4 model{1.0f};       // model → world
  glm::mat4 view{1.0f};        // world → eye (glm::lookAt)
  glm::mat4 projection{1.0f};  // eye → clip, OpenGL conventions (glm::perspective or glm::ortho)
};

// One projected point: its continuous grid coordinates (cell (i, j) covers [i, i+1) × [j, j+1)),
// and clip.w, which is the eye-space depth −z_eye for a perspective camera and 1 for an orthographic one.
struct GridPoint {
  float x = 0.0f;
  float y = 0.0f;
  float clip_w = 0.0f;
};

// The per-request mapping: the combined matrix P·V·M and the grid. Cheap to build (one matrix
// product), so a request builds one and every stage shares it.
class ViewMapping {
 public:
  ViewMapping() = default;
  // grid.valid() must hold.
  ViewMapping(const Camera& camera, GridSize grid);

  GridSize grid() const { return grid_; }
  const glm::mat4& model_view_projection() const { return mvp_; }

  // clip.x, clip.y and clip.w of a model-space point, summed in the order glm::mat4 * glm::vec4
  // uses ((c0·x + c1·y) + (c2·z + c3)), so cells agree bit for bit with the matrix product.
  void clip_xyw(float x, float y, float z, float& cx, float& cy, float& cw) const {
    cx = (m_[0] * x + m_[3] * y) + (m_[6] * z + m_[9]);
    cy = (m_[1] * x + m_[4] * y) + (m_[7] * z + m_[10]);
    cw = (m_[2] * x + m_[5] * y) + (m_[8] * z + m_[11]);
  }
  // clip.z of a model-space point (needed only for depth: occupancy's nearest-depth grid).
  float clip_z(float x, float y, float z) const {
    return (mvp_[0][2] * x + mvp_[1][2] * y) + (mvp_[2][2] * z + mvp_[3][2]);
  }
  // Eye-space depth (−z_eye, positive in front of the camera) of a point whose ndc.z is ndc_z, for
  // projections whose z and w rows depend on z_eye only (glm::perspective, glm::frustum, glm::ortho).
  float eye_depth_from_ndc_z(float ndc_z) const {
    return -(projection_[3][2] - ndc_z * projection_[3][3]) / (ndc_z * projection_[2][3] - projection_[2][2]);
  }
  // Continuous grid coordinates of clip coordinates with clip_w > 0.
  GridPoint to_grid(float cx, float cy, float cw) const {
    return {(cx / cw + 1.0f) * 0.5f * width_f_, (1.0f - cy / cw) * 0.5f * height_f_, cw};
  }
  // Cell of a grid point, or kNoCell when behind the camera or off the grid. NaNs give kNoCell.
  std::uint32_t cell_of(const GridPoint& g) const {
    if (!(g.clip_w > 0.0f && g.x >= 0.0f && g.x < width_f_ && g.y >= 0.0f && g.y < height_f_)) return kNoCell;
    // Truncation is floor here because both coordinates are non-negative.
    return static_cast<std::uint32_t>(g.y) * grid_.width + static_cast<std::uint32_t>(g.x);
  }
  // Cell of one model-space point, and its clip.w through *clip_w when given.
  std::uint32_t map_point(float x, float y, float z, float* clip_w = nullptr) const {
    float cx, cy, cw;
    clip_xyw(x, y, z, cx, cy, cw);
    if (clip_w != nullptr) *clip_w = cw;
    if (!(cw > 0.0f)) return kNoCell;
    return cell_of(to_grid(cx, cy, cw));
  }

  // Size in model units of one pixel of a viewport viewport_height_px pixels tall, at a point whose
  // clip.w is clip_w: 2·clip_w / (H·P[1][1]·s), s being how far V·M stretches a length at most. For
  // glm::perspective this is 2·depth·tan(fovy/2)/(H·s); for glm::ortho (clip_w = 1) it is
  // (top − bottom)/(H·s). A model placed by a scaling matrix (in `model`, or folded into `view` by a
  // client) is held to the pixel bound on the screen, not in its own units. Requires clip_w > 0.
  float model_units_per_pixel(float clip_w, float viewport_height_px) const {
    return 2.0f * clip_w / (viewport_height_px * projection_y_scale_ * model_view_stretch_);
  }
  // s above: 1 for a rigid view of an unscaled model.
  float model_view_stretch() const { return model_view_stretch_; }
  // P[1][1]: 1/tan(fovy/2) for glm::perspective.
  float projection_y_scale() const { return projection_y_scale_; }
  // The eye in model space as a homogeneous point: (eye, 1) for a perspective camera, (direction
  // towards the viewer, 0) for an orthographic one. The view vector at p is eye.xyz − eye.w·p.
  const glm::vec4& eye_model() const { return eye_model_; }

 private:
  GridSize grid_{};
  glm::mat4 mvp_{1.0f};
  glm::mat4 projection_{1.0f};
  float m_[12] = {};  // columns of P·V·M restricted to rows x, y, w
  float width_f_ = 0.0f;
  float height_f_ = 0.0f;
  float projection_y_scale_ = 1.0f;
  float model_view_stretch_ = 1.0f;
  glm::vec4 eye_model_{0.0f, 0.0f, 1.0f, 0.0f};
};

// The largest factor by which `m` stretches a length: its 3×3 part's largest singular value; 0 when
// an entry is not finite.
float largest_stretch(const glm::mat4& m);

// Maps every vertex: cells[v] = its cell or kNoCell, clip_w[v] = its clip.w (the depth used to turn a
// pixel error into model units). positions holds x, y, z per vertex; cells and clip_w hold
// positions.size()/3 entries each. Struct-of-arrays output so the loop vectorises.
void map_vertices(const ViewMapping& mapping, std::span<const float> positions,
                  std::span<std::uint32_t> cells, std::span<float> clip_w);

// Cell of a focus given in normalised viewport coordinates (x to the right, y downwards, both in
// [0, 1]; 1 maps to the last cell), or kNoCell outside that range.
std::uint32_t focus_cell(GridSize grid, float x01, float y01);

}  // namespace mtlod::core::view

// Grid mapping (DESIGN.md §1.1). The hot loop is the hand-written struct-of-arrays projection in
// map_vertices: 1M vertices through a generic glm::mat4 product cost more than twice as much.
#include "core/view_grid.hpp"

#include <cassert>
#include <cmath>

#include <glm/matrix.hpp>

namespace mtlod::core {

ViewMapping::ViewMapping(const Camera& camera, GridSize grid) : grid_(grid) {
  assert(grid.valid());
  mvp_ = camera.projection * camera.view * camera.model;
  // Rows x, y and w of the column-major matrix, stored column by column.
  for (int c = 0; c < 4; ++c) {
    m_[3 * c + 0] = mvp_[c][0];
    m_[3 * c + 1] = mvp_[c][1];
    m_[3 * c + 2] = mvp_[c][3];
  }
  width_f_ = static_cast<float>(grid.width);
  height_f_ = static_cast<float>(grid.height);
  projection_y_scale_ = camera.projection[1][1];
  // A projection whose w row ignores z (P[2][3] == 0) is orthographic: the viewer is a direction.
  const glm::mat4 model_view_inverse = glm::inverse(camera.view * camera.model);
  const bool perspective = camera.projection[2][3] != 0.0f;
  eye_model_ = perspective ? model_view_inverse * glm::vec4(0.0f, 0.0f, 0.0f, 1.0f)
                           : model_view_inverse * glm::vec4(0.0f, 0.0f, 1.0f, 0.0f);
  if (perspective) eye_model_ /= eye_model_.w;
}

void map_vertices(const ViewMapping& mapping, std::span<const float> positions,
                  std::span<std::uint32_t> cells, std::span<float> clip_w) {
  assert(positions.size() % 3 == 0);
  const std::size_t n = positions.size() / 3;
  assert(cells.size() == n && clip_w.size() == n);
  const float* p = positions.data();
  std::uint32_t* out_cell = cells.data();
  float* out_w = clip_w.data();
  for (std::size_t v = 0; v < n; ++v) {
    float cx, cy, cw;
    mapping.clip_xyw(p[3 * v], p[3 * v + 1], p[3 * v + 2], cx, cy, cw);
    out_w[v] = cw;
    // The division by a non-positive w yields garbage or NaN that cell_of rejects through cw > 0.
    out_cell[v] = mapping.cell_of(mapping.to_grid(cx, cy, cw));
  }
}

std::uint32_t focus_cell(GridSize grid, float x01, float y01) {
  if (!(x01 >= 0.0f && x01 <= 1.0f && y01 >= 0.0f && y01 <= 1.0f)) return kNoCell;
  const auto i = std::min(static_cast<std::uint32_t>(x01 * static_cast<float>(grid.width)), grid.width - 1);
  const auto j = std::min(static_cast<std::uint32_t>(y01 * static_cast<float>(grid.height)), grid.height - 1);
  return grid.cell(i, j);
}

}  // namespace mtlod::core

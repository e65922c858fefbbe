// Grid mapping (core/ARCHITECTURE.md §1.1). The hot loop is the hand-written SoA projection in
// map_vertices: 1M vertices through a generic glm::mat4 product cost more than twice as much.
#include "core/view/view_grid.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

#include <glm/matrix.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#include <xmmintrin.h>
#endif

namespace mtlod::core::view {

ViewMapping::ViewMapping(const Camera& camera, GridSize grid) : grid_(grid) {
  assert(grid.valid());
  mvp_ = camera.projection * camera.view * camera.model;
  projection_ = camera.projection;
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
  // A rotation's float entries are orthonormal only to rounding: a rigid view of an unscaled model
  // keeps the exact conversion rather than one off by an ulp.
  const float stretch = largest_stretch(camera.view * camera.model);
  if (stretch > 0.0f && std::abs(stretch - 1.0f) > 1e-5f) model_view_stretch_ = stretch;
}

float largest_stretch(const glm::mat4& m) {
  // The largest singular value of the 3×3 part: the square root of AᵀA's largest eigenvalue, by power
  // iteration (AᵀA is symmetric and positive semi-definite, so it converges from any start with a
  // component along that eigenvector; the largest column is one).
  double a[3][3];
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) {
      a[c][r] = m[c][r];
      if (!std::isfinite(a[c][r])) return 0.0f;
    }
  double b[3][3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) b[i][j] = a[i][0] * a[j][0] + a[i][1] * a[j][1] + a[i][2] * a[j][2];
  int largest = 0;
  for (int i = 1; i < 3; ++i)
    if (b[i][i] > b[largest][largest]) largest = i;
  double v[3] = {b[largest][0], b[largest][1], b[largest][2]};
  double eigen = 0;
  for (int step = 0; step < 64; ++step) {
    const double norm = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(norm > 0)) return 0.0f;
    const double u[3] = {v[0] / norm, v[1] / norm, v[2] / norm};
    for (int i = 0; i < 3; ++i) v[i] = b[i][0] * u[0] + b[i][1] * u[1] + b[i][2] * u[2];
    const double next = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];  // Rayleigh quotient
    if (std::abs(next - eigen) <= 1e-12 * next) {
      eigen = next;
      break;
    }
    eigen = next;
  }
  return static_cast<float>(std::sqrt(std::max(eigen, 0.0)));
}

void map_vertices(const ViewMapping& mapping, std::span<const float> positions,
                  std::span<std::uint32_t> cells, std::span<float> clip_w) {
  assert(positions.size() % 3 == 0);
  const std::size_t n = positions.size() / 3;
  assert(cells.size() == n && clip_w.size() == n);
  const float* p = positions.data();
  std::uint32_t* out_cell = cells.data();
  float* out_w = clip_w.data();
  std::size_t v = 0;
#if defined(__SSE2__)
  // Four vertices per step. Same operations in the same order as clip_xyw/to_grid/cell_of (SSE2 has
  // no fused multiply-add), so results are bit-identical to the scalar path and to GLM.
  const glm::mat4& m = mapping.model_view_projection();
  const __m128 x0 = _mm_set1_ps(m[0][0]), x1 = _mm_set1_ps(m[1][0]), x2 = _mm_set1_ps(m[2][0]),
               x3 = _mm_set1_ps(m[3][0]);
  const __m128 y0 = _mm_set1_ps(m[0][1]), y1 = _mm_set1_ps(m[1][1]), y2 = _mm_set1_ps(m[2][1]),
               y3 = _mm_set1_ps(m[3][1]);
  const __m128 w0 = _mm_set1_ps(m[0][3]), w1 = _mm_set1_ps(m[1][3]), w2 = _mm_set1_ps(m[2][3]),
               w3 = _mm_set1_ps(m[3][3]);
  const __m128 width = _mm_set1_ps(static_cast<float>(mapping.grid().width));
  const __m128 height = _mm_set1_ps(static_cast<float>(mapping.grid().height));
  const __m128 one = _mm_set1_ps(1.0f), half = _mm_set1_ps(0.5f), zero = _mm_setzero_ps();
  for (; v + 4 <= n; v += 4) {
    // De-interleave x0 y0 z0 x1 | y1 z1 x2 y2 | z2 x3 y3 z3 into x, y and z registers.
    const __m128 a = _mm_loadu_ps(p + 3 * v), b = _mm_loadu_ps(p + 3 * v + 4),
                 c = _mm_loadu_ps(p + 3 * v + 8);
    const __m128 px =
        _mm_shuffle_ps(a, _mm_shuffle_ps(b, c, _MM_SHUFFLE(1, 1, 2, 2)), _MM_SHUFFLE(2, 0, 3, 0));
    const __m128 py = _mm_shuffle_ps(_mm_shuffle_ps(a, b, _MM_SHUFFLE(0, 0, 1, 1)),
                                     _mm_shuffle_ps(b, c, _MM_SHUFFLE(2, 2, 3, 3)), _MM_SHUFFLE(2, 0, 2, 0));
    const __m128 pz = _mm_shuffle_ps(_mm_shuffle_ps(a, b, _MM_SHUFFLE(1, 1, 2, 2)),
                                     _mm_shuffle_ps(c, c, _MM_SHUFFLE(3, 3, 0, 0)), _MM_SHUFFLE(2, 0, 2, 0));
    const __m128 cx =
        _mm_add_ps(_mm_add_ps(_mm_mul_ps(x0, px), _mm_mul_ps(x1, py)), _mm_add_ps(_mm_mul_ps(x2, pz), x3));
    const __m128 cy =
        _mm_add_ps(_mm_add_ps(_mm_mul_ps(y0, px), _mm_mul_ps(y1, py)), _mm_add_ps(_mm_mul_ps(y2, pz), y3));
    const __m128 cw =
        _mm_add_ps(_mm_add_ps(_mm_mul_ps(w0, px), _mm_mul_ps(w1, py)), _mm_add_ps(_mm_mul_ps(w2, pz), w3));
    _mm_storeu_ps(out_w + v, cw);
    const __m128 gx = _mm_mul_ps(_mm_mul_ps(_mm_add_ps(_mm_div_ps(cx, cw), one), half), width);
    const __m128 gy = _mm_mul_ps(_mm_mul_ps(_mm_sub_ps(one, _mm_div_ps(cy, cw)), half), height);
    // Ordered comparisons are false for NaN, so a NaN coordinate has no cell.
    const __m128 valid = _mm_and_ps(_mm_and_ps(_mm_and_ps(_mm_cmpgt_ps(cw, zero), _mm_cmpge_ps(gx, zero)),
                                               _mm_and_ps(_mm_cmplt_ps(gx, width), _mm_cmpge_ps(gy, zero))),
                                    _mm_cmplt_ps(gy, height));
    // Cell ids stay below 2^24, so i + j·W is exact in float, avoiding SSE2's missing 32-bit multiply.
    const __m128 i = _mm_cvtepi32_ps(_mm_cvttps_epi32(_mm_and_ps(gx, valid)));
    const __m128 j = _mm_cvtepi32_ps(_mm_cvttps_epi32(_mm_and_ps(gy, valid)));
    const __m128i cell = _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(j, width), i));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(out_cell + v),
                     _mm_or_si128(cell, _mm_castps_si128(_mm_cmpeq_ps(valid, zero))));
  }
#endif
  for (; v < n; ++v) {
    float cx, cy, cw;
    mapping.clip_xyw(p[3 * v], p[3 * v + 1], p[3 * v + 2], cx, cy, cw);
    out_w[v] = cw;
    out_cell[v] = cw > 0.0f ? mapping.cell_of(mapping.to_grid(cx, cy, cw)) : kNoCell;
  }
}

std::uint32_t focus_cell(GridSize grid, float x01, float y01) {
  if (!(x01 >= 0.0f && x01 <= 1.0f && y01 >= 0.0f && y01 <= 1.0f)) return kNoCell;
  const auto i = std::min(static_cast<std::uint32_t>(x01 * static_cast<float>(grid.width)), grid.width - 1);
  const auto j = std::min(static_cast<std::uint32_t>(y01 * static_cast<float>(grid.height)), grid.height - 1);
  return grid.cell(i, j);
}

}  // namespace mtlod::core::view

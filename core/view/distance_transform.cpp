// Chamfer transforms (papers/000 Algorithm 1, core/ARCHITECTURE.md §1.3) and Meijster's exact
// Euclidean transform. The chamfer grid is padded with +inf so the inner loops need no bounds
// checks, and held in 16-bit ints so SSE2 processes 8 cells per instruction.
//
// Each pass of Algorithm 1 is split per row into (a) the steps from the two previous rows, which do
// not depend on each other and run 8 cells at a time, and (b) the in-row step, a min-plus prefix scan
// done with log-step shifts inside the 8-cell register and a carry between registers. (a) then (b)
// gives the same value as the cell-by-cell loop because the in-row neighbour's own upper steps were
// already folded in when the scan reaches it.
#include "core/view/distance_transform.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace mtlod::core::view {

namespace {

// Left padding of 8 keeps rows 16-byte aligned relative to the buffer; 2 would suffice for the mask.
constexpr std::size_t kPadLeft = 8;
constexpr std::size_t kPadRows = 2;
constexpr std::uint16_t kInf = kChamferUnreached;

std::size_t round_up8(std::size_t n) {
  return (n + 7) & ~std::size_t{7};
}

#if defined(__SSE2__)

// Lanes at and beyond `valid` lanes set to +inf. ORing works because values never exceed 0x7FFF.
__m128i lanes_from(int first_inf_lane) {
  alignas(16) std::uint16_t lanes[8];
  for (int k = 0; k < 8; ++k) lanes[k] = k >= first_inf_lane ? kInf : 0;
  return _mm_load_si128(reinterpret_cast<const __m128i*>(lanes));
}
__m128i lanes_below(int first_finite_lane) {
  alignas(16) std::uint16_t lanes[8];
  for (int k = 0; k < 8; ++k) lanes[k] = k < first_finite_lane ? kInf : 0;
  return _mm_load_si128(reinterpret_cast<const __m128i*>(lanes));
}
__m128i ramp(std::uint16_t step, bool rising) {
  alignas(16) std::uint16_t lanes[8];
  for (int k = 0; k < 8; ++k) lanes[k] = static_cast<std::uint16_t>(step * (rising ? k + 1 : 8 - k));
  return _mm_load_si128(reinterpret_cast<const __m128i*>(lanes));
}

// Saturating adds keep +inf at 0x7FFF; signed 16-bit min is SSE2's pminsw.
inline __m128i relax(__m128i t, __m128i neighbour, __m128i weight) {
  return _mm_min_epi16(t, _mm_adds_epi16(neighbour, weight));
}

template <const auto& kMask>
void forward_pass(std::uint16_t* buffer, std::size_t stride, GridSize grid) {
  constexpr std::size_t kUpper = kMask.size() - 1;
  const __m128i e1 = _mm_set1_epi16(static_cast<std::int16_t>(kMask[kUpper].weight));
  const __m128i e2 = _mm_set1_epi16(static_cast<std::int16_t>(2 * kMask[kUpper].weight));
  const __m128i e4 = _mm_set1_epi16(static_cast<std::int16_t>(4 * kMask[kUpper].weight));
  const __m128i carry_ramp = ramp(kMask[kUpper].weight, true);
  const __m128i fill1 = lanes_below(1), fill2 = lanes_below(2), fill4 = lanes_below(4);
  const __m128i tail = lanes_from(static_cast<int>(grid.width % 8 == 0 ? 8 : grid.width % 8));
  __m128i weights[kUpper];
  std::ptrdiff_t offsets[kUpper];
  for (std::size_t k = 0; k < kUpper; ++k) {
    weights[k] = _mm_set1_epi16(static_cast<std::int16_t>(kMask[k].weight));
    offsets[k] = kMask[k].dy * static_cast<std::ptrdiff_t>(stride) + kMask[k].dx;
  }
  const std::size_t last_chunk = round_up8(grid.width) - 8;
  for (std::size_t y = 0; y < grid.height; ++y) {
    std::uint16_t* row = buffer + (y + kPadRows) * stride + kPadLeft;
    __m128i carry = _mm_set1_epi16(static_cast<std::int16_t>(kInf));
    for (std::size_t x = 0; x <= last_chunk; x += 8) {
      std::uint16_t* cell = row + x;
      __m128i t = _mm_loadu_si128(reinterpret_cast<const __m128i*>(cell));
      for (std::size_t k = 0; k < kUpper; ++k) {
        t = relax(t, _mm_loadu_si128(reinterpret_cast<const __m128i*>(cell + offsets[k])), weights[k]);
      }
      if (x == last_chunk) t = _mm_or_si128(t, tail);  // cells past the row end stay +inf
      // In-row scan: lane k takes min over m ≤ k of t[m] + e·(k − m), then the carry from the left.
      t = relax(t, _mm_or_si128(_mm_slli_si128(t, 2), fill1), e1);
      t = relax(t, _mm_or_si128(_mm_slli_si128(t, 4), fill2), e2);
      t = relax(t, _mm_or_si128(_mm_slli_si128(t, 8), fill4), e4);
      t = relax(t, carry, carry_ramp);
      _mm_storeu_si128(reinterpret_cast<__m128i*>(cell), t);
      carry = _mm_shuffle_epi32(_mm_shufflehi_epi16(t, 0xFF), 0xFF);
    }
    // The last register wrote into the right padding; later rows must see +inf there.
    std::fill(row + grid.width, row + stride - kPadLeft, kInf);
  }
}

template <const auto& kMask>
void backward_pass(std::uint16_t* buffer, std::size_t stride, GridSize grid, std::uint16_t* out) {
  constexpr std::size_t kUpper = kMask.size() - 1;
  const __m128i e1 = _mm_set1_epi16(static_cast<std::int16_t>(kMask[kUpper].weight));
  const __m128i e2 = _mm_set1_epi16(static_cast<std::int16_t>(2 * kMask[kUpper].weight));
  const __m128i e4 = _mm_set1_epi16(static_cast<std::int16_t>(4 * kMask[kUpper].weight));
  const __m128i carry_ramp = ramp(kMask[kUpper].weight, false);
  const __m128i fill1 = lanes_from(7), fill2 = lanes_from(6), fill4 = lanes_from(4);
  const __m128i tail = lanes_from(static_cast<int>(grid.width % 8 == 0 ? 8 : grid.width % 8));
  __m128i weights[kUpper];
  std::ptrdiff_t offsets[kUpper];
  for (std::size_t k = 0; k < kUpper; ++k) {
    weights[k] = _mm_set1_epi16(static_cast<std::int16_t>(kMask[k].weight));
    // The backward half of the mask is the forward half mirrored through the cell.
    offsets[k] = -(kMask[k].dy * static_cast<std::ptrdiff_t>(stride) + kMask[k].dx);
  }
  const std::size_t last_chunk = round_up8(grid.width) - 8;
  for (std::size_t y = grid.height; y-- > 0;) {
    std::uint16_t* row = buffer + (y + kPadRows) * stride + kPadLeft;
    __m128i carry = _mm_set1_epi16(static_cast<std::int16_t>(kInf));
    for (std::size_t x = last_chunk + 8; x > 0;) {
      x -= 8;
      std::uint16_t* cell = row + x;
      __m128i t = _mm_loadu_si128(reinterpret_cast<const __m128i*>(cell));
      for (std::size_t k = 0; k < kUpper; ++k) {
        t = relax(t, _mm_loadu_si128(reinterpret_cast<const __m128i*>(cell + offsets[k])), weights[k]);
      }
      if (x == last_chunk) t = _mm_or_si128(t, tail);
      // Mirror of the forward scan: lane k takes min over m ≥ k of t[m] + e·(m − k).
      t = relax(t, _mm_or_si128(_mm_srli_si128(t, 2), fill1), e1);
      t = relax(t, _mm_or_si128(_mm_srli_si128(t, 4), fill2), e2);
      t = relax(t, _mm_or_si128(_mm_srli_si128(t, 8), fill4), e4);
      t = relax(t, carry, carry_ramp);
      _mm_storeu_si128(reinterpret_cast<__m128i*>(cell), t);
      carry = _mm_shuffle_epi32(_mm_shufflelo_epi16(t, 0x00), 0x00);
    }
    std::fill(row + grid.width, row + stride - kPadLeft, kInf);
    std::memcpy(out + y * grid.width, row, grid.width * sizeof(std::uint16_t));
  }
}

#endif

// Portable scalar passes, cell by cell exactly as Algorithm 1: the fallback without SSE2, and a second
// implementation the tests hold against the same Dijkstra reference.
template <const auto& kMask>
void forward_pass_scalar(std::uint16_t* buffer, std::size_t stride, GridSize grid) {
  for (std::size_t y = 0; y < grid.height; ++y) {
    std::uint16_t* row = buffer + (y + kPadRows) * stride + kPadLeft;
    for (std::size_t x = 0; x < grid.width; ++x) {
      std::uint32_t best = row[x];
      for (const ChamferStep& s : kMask) {
        best = std::min<std::uint32_t>(best,
                                       row[x + s.dy * static_cast<std::ptrdiff_t>(stride) + s.dx] + s.weight);
      }
      row[x] = static_cast<std::uint16_t>(std::min<std::uint32_t>(best, kInf));
    }
  }
}

template <const auto& kMask>
void backward_pass_scalar(std::uint16_t* buffer, std::size_t stride, GridSize grid, std::uint16_t* out) {
  for (std::size_t y = grid.height; y-- > 0;) {
    std::uint16_t* row = buffer + (y + kPadRows) * stride + kPadLeft;
    for (std::size_t x = grid.width; x-- > 0;) {
      std::uint32_t best = row[x];
      for (const ChamferStep& s : kMask) {
        best = std::min<std::uint32_t>(best,
                                       row[x - s.dy * static_cast<std::ptrdiff_t>(stride) - s.dx] + s.weight);
      }
      row[x] = static_cast<std::uint16_t>(std::min<std::uint32_t>(best, kInf));
    }
    std::memcpy(out + y * grid.width, row, grid.width * sizeof(std::uint16_t));
  }
}

template <const auto& kMask>
void two_pass(std::uint16_t* buffer, std::size_t stride, GridSize grid, std::uint16_t* out, bool scalar) {
#if defined(__SSE2__)
  if (!scalar) {
    forward_pass<kMask>(buffer, stride, grid);
    backward_pass<kMask>(buffer, stride, grid, out);
    return;
  }
#endif
  (void)scalar;
  forward_pass_scalar<kMask>(buffer, stride, grid);
  backward_pass_scalar<kMask>(buffer, stride, grid, out);
}

// floor(a / b) for b > 0; C++ division truncates towards zero.
inline std::int64_t floor_div(std::int64_t a, std::int64_t b) {
  return a >= 0 ? a / b : -((-a + b - 1) / b);
}

}  // namespace

std::uint32_t units_per_pixel(DistanceMetric metric) {
  switch (metric) {
    case DistanceMetric::kChamfer5711:
      return 5;
    case DistanceMetric::kChamfer34:
      return 3;
    case DistanceMetric::kCityBlock:
    case DistanceMetric::kChessboard:
    case DistanceMetric::kEuclidean:
      return 1;
  }
  return 1;
}

float distance_px(std::uint32_t raw, DistanceMetric metric) {
  if (metric == DistanceMetric::kEuclidean) return std::sqrt(static_cast<float>(raw));
  return static_cast<float>(raw) / static_cast<float>(units_per_pixel(metric));
}

std::uint32_t raw_threshold(float threshold_px, DistanceMetric metric) {
  assert(threshold_px >= 0.0f);
  // Double precision so that e.g. 2 px · 5 is exactly 10 and 3 px squared exactly 9.
  const double d = threshold_px;
  const double raw = metric == DistanceMetric::kEuclidean ? d * d : d * units_per_pixel(metric);
  return raw >= 4294967295.0 ? 0xFFFFFFFFu : static_cast<std::uint32_t>(std::floor(raw));
}

void DistanceTransformer::prepare_padded(GridSize grid) {
  assert(grid.valid());
  stride_ = kPadLeft + round_up8(grid.width) + 8;
  const std::size_t size = stride_ * (grid.height + 2 * kPadRows);
  // Only the grow path allocates; a reused buffer is refilled with +inf, padding included.
  padded_.resize(size);
  std::fill(padded_.begin(), padded_.begin() + static_cast<std::ptrdiff_t>(size), kInf);
}

void DistanceTransformer::run_chamfer(DistanceMetric metric, GridSize grid, std::span<std::uint16_t> out) {
  std::uint16_t* buffer = padded_.data();
  switch (metric) {
    case DistanceMetric::kChamfer5711:
      two_pass<kChamfer5711Forward>(buffer, stride_, grid, out.data(), scalar_);
      break;
    case DistanceMetric::kChamfer34:
      two_pass<kChamfer34Forward>(buffer, stride_, grid, out.data(), scalar_);
      break;
    case DistanceMetric::kCityBlock:
      two_pass<kCityBlockForward>(buffer, stride_, grid, out.data(), scalar_);
      break;
    case DistanceMetric::kChessboard:
      two_pass<kChessboardForward>(buffer, stride_, grid, out.data(), scalar_);
      break;
    case DistanceMetric::kEuclidean:
      assert(false && "use euclidean_squared");
      break;
  }
}

void DistanceTransformer::chamfer(DistanceMetric metric, std::span<const std::uint8_t> image, GridSize grid,
                                  std::span<std::uint16_t> out) {
  assert(image.size() == grid.cell_count() && out.size() == grid.cell_count());
  prepare_padded(grid);
  for (std::size_t y = 0; y < grid.height; ++y) {
    const std::uint8_t* in = image.data() + y * grid.width;
    std::uint16_t* row = padded_.data() + (y + kPadRows) * stride_ + kPadLeft;
    for (std::size_t x = 0; x < grid.width; ++x) row[x] = in[x] != 0 ? kInf : 0;
  }
  run_chamfer(metric, grid, out);
}

void DistanceTransformer::chamfer_from_cells(DistanceMetric metric, std::span<const std::uint32_t> seed_cells,
                                             GridSize grid, std::span<std::uint16_t> out) {
  assert(out.size() == grid.cell_count());
  prepare_padded(grid);
  for (const std::uint32_t c : seed_cells) {
    if (c == kNoCell) continue;
    assert(c < grid.cell_count());
    padded_[(c / grid.width + kPadRows) * stride_ + kPadLeft + c % grid.width] = 0;
  }
  run_chamfer(metric, grid, out);
}

namespace {

// One forward and one backward pass restricted to passable cells; returns whether any value fell.
template <const auto& kMask>
bool constrained_round(std::uint16_t* buffer, const std::uint8_t* passable, std::size_t stride,
                       GridSize grid) {
  bool changed = false;
  auto relax = [&](std::size_t y, std::size_t x, int sign) {
    const std::size_t c = (y + kPadRows) * stride + kPadLeft + x;
    if (!passable[c]) return;
    std::uint32_t best = buffer[c];
    for (const ChamferStep& s : kMask) {
      const std::ptrdiff_t n =
          static_cast<std::ptrdiff_t>(c) + sign * (s.dy * static_cast<std::ptrdiff_t>(stride) + s.dx);
      // A blocked neighbour keeps +inf unless it is a seed, so it needs no test of its own.
      best = std::min<std::uint32_t>(best, buffer[n] + s.weight);
    }
    if (best < buffer[c]) {
      buffer[c] = static_cast<std::uint16_t>(best);
      changed = true;
    }
  };
  for (std::size_t y = 0; y < grid.height; ++y)
    for (std::size_t x = 0; x < grid.width; ++x) relax(y, x, 1);
  for (std::size_t y = grid.height; y-- > 0;)
    for (std::size_t x = grid.width; x-- > 0;) relax(y, x, -1);
  return changed;
}

template <const auto& kMask>
std::size_t constrained_rounds(std::uint16_t* buffer, const std::uint8_t* passable, std::size_t stride,
                               GridSize grid, std::size_t max_rounds) {
  std::size_t rounds = 0;
  while (rounds < max_rounds) {
    ++rounds;
    if (!constrained_round<kMask>(buffer, passable, stride, grid)) break;
  }
  return rounds;
}

}  // namespace

std::size_t DistanceTransformer::chamfer_constrained(DistanceMetric metric,
                                                     std::span<const std::uint32_t> seed_cells,
                                                     std::span<const std::uint8_t> passable, GridSize grid,
                                                     std::span<std::uint16_t> out, std::size_t max_rounds) {
  assert(passable.size() == grid.cell_count() && out.size() == grid.cell_count());
  prepare_padded(grid);
  passable_.assign(padded_.size(), 0);  // padding is blocked
  for (std::size_t y = 0; y < grid.height; ++y) {
    const std::size_t row = (y + kPadRows) * stride_ + kPadLeft;
    for (std::size_t x = 0; x < grid.width; ++x) passable_[row + x] = passable[y * grid.width + x] != 0;
  }
  for (const std::uint32_t c : seed_cells) {
    if (c == kNoCell) continue;
    assert(c < grid.cell_count());
    const std::size_t p = (c / grid.width + kPadRows) * stride_ + kPadLeft + c % grid.width;
    padded_[p] = 0;
    passable_[p] = 1;
  }
  std::size_t rounds = 0;
  switch (metric) {
    case DistanceMetric::kChamfer5711:
      rounds = constrained_rounds<kChamfer5711Forward>(padded_.data(), passable_.data(), stride_, grid,
                                                       max_rounds);
      break;
    case DistanceMetric::kChamfer34:
      rounds =
          constrained_rounds<kChamfer34Forward>(padded_.data(), passable_.data(), stride_, grid, max_rounds);
      break;
    case DistanceMetric::kCityBlock:
      rounds =
          constrained_rounds<kCityBlockForward>(padded_.data(), passable_.data(), stride_, grid, max_rounds);
      break;
    case DistanceMetric::kChessboard:
      rounds =
          constrained_rounds<kChessboardForward>(padded_.data(), passable_.data(), stride_, grid, max_rounds);
      break;
    case DistanceMetric::kEuclidean:
      assert(false && "no constrained Euclidean transform");
      break;
  }
  for (std::size_t y = 0; y < grid.height; ++y) {
    std::memcpy(out.data() + y * grid.width, padded_.data() + (y + kPadRows) * stride_ + kPadLeft,
                grid.width * sizeof(std::uint16_t));
  }
  return rounds;
}

void DistanceTransformer::euclidean_squared(std::span<const std::uint8_t> image, GridSize grid,
                                            std::span<std::uint32_t> out) {
  assert(grid.valid() && image.size() == grid.cell_count() && out.size() == grid.cell_count());
  // Phase 1 (Meijster): column[y][x] = distance from (x, y) to the nearest seed in column x, done
  // row by row (down, then up) so that the loops run along memory and vectorise.
  const std::size_t w = grid.width, h = grid.height;
  const std::uint16_t far = static_cast<std::uint16_t>(w + h);  // beyond any in-column distance
  column_.resize(w * h);
  std::uint16_t* g = column_.data();
  for (std::size_t x = 0; x < w; ++x) g[x] = image[x] == 0 ? 0 : far;
  for (std::size_t y = 1; y < h; ++y) {
    const std::uint8_t* in = image.data() + y * w;
    std::uint16_t* cur = g + y * w;
    const std::uint16_t* prev = cur - w;
    for (std::size_t x = 0; x < w; ++x) {
      cur[x] = in[x] == 0 ? 0 : static_cast<std::uint16_t>(std::min<std::uint32_t>(prev[x] + 1u, far));
    }
  }
  for (std::size_t y = h - 1; y-- > 0;) {
    std::uint16_t* cur = g + y * w;
    const std::uint16_t* next = cur + w;
    for (std::size_t x = 0; x < w; ++x) cur[x] = std::min<std::uint16_t>(cur[x], next[x] + 1u);
  }
  run_euclidean(grid, out);
}

void DistanceTransformer::euclidean_squared_from_cells(std::span<const std::uint32_t> seed_cells,
                                                       GridSize grid, std::span<std::uint32_t> out) {
  assert(grid.valid() && out.size() == grid.cell_count());
  const std::size_t w = grid.width, h = grid.height;
  const std::uint16_t far = static_cast<std::uint16_t>(w + h);
  column_.assign(w * h, far);
  std::uint16_t* g = column_.data();
  for (const std::uint32_t c : seed_cells) {
    if (c == kNoCell) continue;
    assert(c < grid.cell_count());
    g[c] = 0;
  }
  for (std::size_t y = 1; y < h; ++y) {
    std::uint16_t* cur = g + y * w;
    for (std::size_t x = 0; x < w; ++x)
      cur[x] = std::min<std::uint16_t>(cur[x], std::min<std::uint32_t>((cur - w)[x] + 1u, far));
  }
  for (std::size_t y = h - 1; y-- > 0;) {
    std::uint16_t* cur = g + y * w;
    for (std::size_t x = 0; x < w; ++x) cur[x] = std::min<std::uint16_t>(cur[x], cur[x + w] + 1u);
  }
  run_euclidean(grid, out);
}

void DistanceTransformer::run_euclidean(GridSize grid, std::span<std::uint32_t> out) {
  // Phase 2 (Meijster): per row, the lower envelope of the parabolas f_i(x) = (x − i)² + g(i)².
  // s[q] is the column of the q-th parabola of the envelope, t[q] the first x where it is lowest.
  const std::int64_t w = grid.width;
  const std::uint16_t far = static_cast<std::uint16_t>(grid.width + grid.height);
  envelope_.resize(2 * grid.width);
  std::uint32_t* s = envelope_.data();
  std::uint32_t* t = s + grid.width;
  for (std::size_t y = 0; y < grid.height; ++y) {
    const std::uint16_t* g = column_.data() + y * grid.width;
    std::uint32_t* row_out = out.data() + y * grid.width;
    auto f = [g](std::int64_t x, std::int64_t i) { return (x - i) * (x - i) + std::int64_t{g[i]} * g[i]; };
    std::int64_t q = 0;
    s[0] = 0;
    t[0] = 0;
    for (std::int64_t u = 1; u < w; ++u) {
      while (q >= 0 && f(t[q], s[q]) > f(t[q], u)) --q;
      if (q < 0) {
        q = 0;
        s[0] = static_cast<std::uint32_t>(u);
      } else {
        const std::int64_t i = s[q];
        // Sep(i, u): the first x from which parabola u is not above parabola i, minus one.
        const std::int64_t sep =
            floor_div(u * u - i * i + std::int64_t{g[u]} * g[u] - std::int64_t{g[i]} * g[i], 2 * (u - i));
        const std::int64_t first = 1 + sep;
        if (first < w) {
          ++q;
          s[q] = static_cast<std::uint32_t>(u);
          t[q] = static_cast<std::uint32_t>(first);
        }
      }
    }
    for (std::int64_t u = w - 1; u >= 0; --u) {
      const std::int64_t i = s[q];
      // A parabola from a seedless column lies above every real distance, so it is the minimum only
      // when the whole grid has no seed.
      row_out[u] = g[i] >= far ? kEuclideanUnreached : static_cast<std::uint32_t>(f(u, i));
      if (u == t[q]) --q;
    }
  }
}

void chamfer_5_7_11(std::span<const std::uint8_t> image, GridSize grid, std::span<std::uint16_t> out) {
  DistanceTransformer().chamfer(DistanceMetric::kChamfer5711, image, grid, out);
}
void chamfer_3_4(std::span<const std::uint8_t> image, GridSize grid, std::span<std::uint16_t> out) {
  DistanceTransformer().chamfer(DistanceMetric::kChamfer34, image, grid, out);
}
void city_block(std::span<const std::uint8_t> image, GridSize grid, std::span<std::uint16_t> out) {
  DistanceTransformer().chamfer(DistanceMetric::kCityBlock, image, grid, out);
}
void chessboard(std::span<const std::uint8_t> image, GridSize grid, std::span<std::uint16_t> out) {
  DistanceTransformer().chamfer(DistanceMetric::kChessboard, image, grid, out);
}
void euclidean_squared(std::span<const std::uint8_t> image, GridSize grid, std::span<std::uint32_t> out) {
  DistanceTransformer().euclidean_squared(image, grid, out);
}

namespace {

void to_fifths_of_pixel(std::span<const std::uint32_t> squared, std::span<std::uint16_t> out) {
  for (std::size_t c = 0; c < out.size(); ++c) {
    out[c] = squared[c] == kEuclideanUnreached
                 ? kChamferUnreached
                 : static_cast<std::uint16_t>(std::lround(5.0 * std::sqrt(static_cast<double>(squared[c]))));
  }
}

}  // namespace

void DistanceTransformer::labels(DistanceMetric metric, std::span<const std::uint8_t> image, GridSize grid,
                                 std::span<std::uint16_t> out) {
  if (metric != DistanceMetric::kEuclidean) return chamfer(metric, image, grid, out);
  squared_.resize(out.size());
  euclidean_squared(image, grid, squared_);
  to_fifths_of_pixel(squared_, out);
}

void DistanceTransformer::labels_from_cells(DistanceMetric metric, std::span<const std::uint32_t> seed_cells,
                                            GridSize grid, std::span<std::uint16_t> out) {
  if (metric != DistanceMetric::kEuclidean) return chamfer_from_cells(metric, seed_cells, grid, out);
  squared_.resize(out.size());
  euclidean_squared_from_cells(seed_cells, grid, squared_);
  to_fifths_of_pixel(squared_, out);
}

void DistanceTransformer::labels_from_cells_within(DistanceMetric metric,
                                                   std::span<const std::uint32_t> seed_cells, GridSize grid,
                                                   CellRect rect, std::span<std::uint16_t> out) {
  assert(out.size() == grid.cell_count() && !rect.empty() && rect.x1 <= grid.width && rect.y1 <= grid.height);
  const GridSize sub{rect.width(), rect.height()};
  rect_seeds_.clear();
  for (const std::uint32_t c : seed_cells) {
    if (c == kNoCell) continue;
    const std::uint32_t x = c % grid.width, y = c / grid.width;
    assert(x >= rect.x0 && x < rect.x1 && y >= rect.y0 && y < rect.y1);
    rect_seeds_.push_back(sub.cell(x - rect.x0, y - rect.y0));
  }
  rect_out_.resize(sub.cell_count());
  labels_from_cells(metric, rect_seeds_, sub, rect_out_);
  std::fill(out.begin(), out.end(), kChamferUnreached);
  for (std::uint32_t y = 0; y < sub.height; ++y)
    std::copy_n(rect_out_.data() + std::size_t{y} * sub.width, sub.width,
                out.data() + grid.cell(rect.x0, rect.y0 + y));
}

}  // namespace mtlod::core::view

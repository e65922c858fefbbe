// Version-0 vertex streams and the octahedral filter (layout in vertex_encode.hpp), written as
// meshoptimizer 0.18 writes them but in a fraction of its time. The library turns each byte of each
// vertex into its zigzagged delta one at a time, then measures every group of 16 four times over
// (once per encoding) and packs it byte by byte. Here, with SSE2:
// - Deltas are taken on whole vertices, 16 bytes at a time (a vertex less its predecessor, one
//   stride back), and 16 vertices are then transposed into their stride's columns with unpacks (in
//   registers for strides 4 and 8, through a copy for others).
// - A group is measured with three compares into bit masks (zero, 3 or more, 15 or more): a mask's
//   population is the count of values that do not fit in 2 or 4 bits, so the choice takes no loop.
// - 2- and 4-bit values are packed with shifts within 16- and 32-bit lanes; only the values that do
//   not fit are written one by one, found by their mask bits. (Writing all 16 and counting only
//   those, without a loop, was slower, as was choosing the encoding's bytes without a switch.)
// BM_VertexEncode compares it with the library (BENCHMARKS.md, "Codecs side by side").
// The capacity checks are the library's, which keep every group's writes within its 24 bytes of room.
// The filter computes four normals at a time with the library's operations in its order (a division,
// not a reciprocal estimate; no fused multiply-add), so that every float rounds as it does.
#include "core/codec/vertex_encode.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace mtlod::core::codec {
namespace {

constexpr std::size_t kGroupSize = 16;
// A block's vertices: as many as fit the decoder's 8 KiB scratch, in whole groups, at most 256.
constexpr std::size_t kBlockBytes = 8192, kBlockMaxVertices = 256;
// A group starts only with this many bytes left: the most the decoder reads for one, unchecked.
constexpr std::size_t kGroupRoom = 24;
// The tail is the first vertex, padded in front with zeros to at least this many bytes.
constexpr std::size_t kTailMinBytes = 32;
constexpr std::size_t kMaxStride = 256;
// How far ahead of the filter the gathered normals are fetched.
constexpr std::size_t kAheadIds = 16;

// The group encodings, as the header's 2-bit codes.
enum Mode : unsigned { kZero = 0, kTwoBits = 1, kFourBits = 2, kBytes = 3 };

std::size_t block_vertices(std::size_t stride) {
  return std::min((kBlockBytes / stride) & ~(kGroupSize - 1), kBlockMaxVertices);
}

std::size_t tail_bytes(std::size_t stride) {
  return std::max(stride, kTailMinBytes);
}

std::uint8_t zigzag(std::uint8_t delta) {
  return static_cast<std::uint8_t>((delta << 1) ^ (0u - (delta >> 7)));
}

// The library's choice among the encodings from the group's sizes under each: the shortest, the first
// tried on a tie, in its order of trial (8 bits, then 1 (all zero), 2 and 4).
unsigned choose_mode(bool all_zero, unsigned wide_for_2, unsigned wide_for_4) {
  if (all_zero) return kZero;
  unsigned mode = kBytes, size = kGroupSize;
  if (4 + wide_for_2 < size) mode = kTwoBits, size = 4 + wide_for_2;
  if (8 + wide_for_4 < size) mode = kFourBits;
  return mode;
}

// ---- Portable --------------------------------------------------------------------------------------

// The block's vertices from `first` (n of them) as columns: byte k's zigzagged deltas from the vertex
// before (the first vertex is its own predecessor), `block` bytes apart, zero after the n-th.
void columns_portable(const std::uint8_t* vertices, std::size_t first, std::size_t n, std::size_t stride,
                      std::size_t block, std::uint8_t* columns) {
  const std::uint8_t* v = vertices + first * stride;
  const std::uint8_t* before = first > 0 ? v - stride : v;
  const std::size_t padded = (n + kGroupSize - 1) & ~(kGroupSize - 1);
  for (std::size_t k = 0; k < stride; ++k) {
    std::uint8_t* column = columns + k * block;
    std::uint8_t previous = before[k];
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint8_t value = v[i * stride + k];
      column[i] = zigzag(static_cast<std::uint8_t>(value - previous));
      previous = value;
    }
    std::fill(column + n, column + padded, std::uint8_t{0});
  }
}

// Writes one group at `data` and returns its mode and the end of what it wrote.
std::uint8_t* group_portable(const std::uint8_t* values, std::uint8_t* data, unsigned& mode) {
  bool all_zero = true;
  unsigned wide_for_2 = 0, wide_for_4 = 0;
  for (std::size_t i = 0; i < kGroupSize; ++i) {
    all_zero &= values[i] == 0;
    wide_for_2 += values[i] >= 3;
    wide_for_4 += values[i] >= 15;
  }
  mode = choose_mode(all_zero, wide_for_2, wide_for_4);
  if (mode == kZero) return data;
  if (mode == kBytes) {
    std::memcpy(data, values, kGroupSize);
    return data + kGroupSize;
  }
  const unsigned bits = mode == kTwoBits ? 2 : 4, per_byte = 8 / bits;
  const std::uint8_t escape = static_cast<std::uint8_t>((1u << bits) - 1);
  for (std::size_t i = 0; i < kGroupSize; i += per_byte) {
    unsigned byte = 0;
    for (unsigned k = 0; k < per_byte; ++k) byte = byte << bits | std::min(values[i + k], escape);
    *data++ = static_cast<std::uint8_t>(byte);
  }
  for (std::size_t i = 0; i < kGroupSize; ++i)
    if (values[i] >= escape) *data++ = values[i];
  return data;
}

struct PortableKernel {
  static void columns(const std::uint8_t* vertices, std::size_t first, std::size_t n, std::size_t count,
                      std::size_t stride, std::size_t block, std::uint8_t* columns) {
    (void)count;
    columns_portable(vertices, first, n, stride, block, columns);
  }
  static std::uint8_t* group(const std::uint8_t* values, std::uint8_t* data, unsigned& mode) {
    return group_portable(values, data, mode);
  }
};

// ---- SSE2 ------------------------------------------------------------------------------------------

#if defined(__SSE2__)
constexpr std::array<std::uint8_t, 256> kPopulation = [] {
  std::array<std::uint8_t, 256> counts{};
  for (unsigned m = 0; m < 256; ++m) counts[m] = static_cast<std::uint8_t>(std::popcount(m));
  return counts;
}();

// The set bits of a 16-bit mask, by table: x86-64's baseline has no popcnt instruction.
unsigned population(unsigned mask16) {
  return kPopulation[mask16 & 255] + kPopulation[mask16 >> 8];
}

__m128i load(const std::uint8_t* at) {
  return _mm_loadu_si128(reinterpret_cast<const __m128i*>(at));
}

void store(std::uint8_t* at, __m128i v) {
  _mm_storeu_si128(reinterpret_cast<__m128i*>(at), v);
}

// The zigzagged byte deltas of the 16 bytes at `at` from those a stride before.
__m128i zigzag_delta(const std::uint8_t* at, std::size_t stride) {
  const __m128i delta = _mm_sub_epi8(load(at), load(at - stride));
  return _mm_xor_si128(_mm_add_epi8(delta, delta), _mm_cmpgt_epi8(_mm_setzero_si128(), delta));
}

// Four registers of four 4-byte vertex slices (vertex 4m + i in dword i of r[m]) into four columns of
// 16 bytes: column b holds byte b of the 16 slices in vertex order. Each round of unpacks halves the
// distance between a column's neighbours.
void transpose_4x16(const __m128i r[4], std::uint8_t* column, std::size_t column_step) {
  const __m128i a = _mm_unpacklo_epi8(r[0], r[1]), b = _mm_unpackhi_epi8(r[0], r[1]);
  const __m128i c = _mm_unpacklo_epi8(r[2], r[3]), d = _mm_unpackhi_epi8(r[2], r[3]);
  const __m128i e = _mm_unpacklo_epi8(a, b), f = _mm_unpackhi_epi8(a, b);
  const __m128i g = _mm_unpacklo_epi8(c, d), h = _mm_unpackhi_epi8(c, d);
  const __m128i low01 = _mm_unpacklo_epi8(e, f), low23 = _mm_unpackhi_epi8(e, f);    // vertices 0..7
  const __m128i high01 = _mm_unpacklo_epi8(g, h), high23 = _mm_unpackhi_epi8(g, h);  // vertices 8..15
  store(column, _mm_unpacklo_epi64(low01, high01));
  store(column + column_step, _mm_unpackhi_epi64(low01, high01));
  store(column + 2 * column_step, _mm_unpacklo_epi64(low23, high23));
  store(column + 3 * column_step, _mm_unpackhi_epi64(low23, high23));
}

// 16 vertices from `v` (the 16 bytes before each readable) into their stride's columns at `column`,
// `column_step` bytes apart: strides 4 and 8 in registers throughout, others through a copy in rows.
template <std::size_t kStride>
void chunk_columns(const std::uint8_t* v, std::size_t stride, std::uint8_t* column, std::size_t column_step) {
  if constexpr (kStride == 4) {
    __m128i r[4];
    for (int m = 0; m < 4; ++m) r[m] = zigzag_delta(v + 16 * m, 4);
    transpose_4x16(r, column, column_step);
  } else if constexpr (kStride == 8) {
    // Each register holds two vertices; their low and high dwords go to separate sets of four.
    __m128i low[4], high[4];
    for (int m = 0; m < 4; ++m) {
      const __m128i r0 = _mm_shuffle_epi32(zigzag_delta(v + 32 * m, 8), _MM_SHUFFLE(3, 1, 2, 0));
      const __m128i r1 = _mm_shuffle_epi32(zigzag_delta(v + 32 * m + 16, 8), _MM_SHUFFLE(3, 1, 2, 0));
      low[m] = _mm_unpacklo_epi64(r0, r1);
      high[m] = _mm_unpackhi_epi64(r0, r1);
    }
    transpose_4x16(low, column, column_step);
    transpose_4x16(high, column + 4 * column_step, column_step);
  } else {
    alignas(16) std::uint8_t rows[kGroupSize * kMaxStride];
    for (std::size_t at = 0; at < kGroupSize * stride; at += 16)
      store(rows + at, zigzag_delta(v + at, stride));
    for (std::size_t dword = 0; dword < stride / 4; ++dword) {
      __m128i r[4];
      for (std::size_t m = 0; m < 4; ++m) {
        std::uint32_t slice[4];
        for (std::size_t i = 0; i < 4; ++i)
          std::memcpy(&slice[i], rows + (4 * m + i) * stride + 4 * dword, 4);
        r[m] = _mm_setr_epi32(static_cast<int>(slice[0]), static_cast<int>(slice[1]),
                              static_cast<int>(slice[2]), static_cast<int>(slice[3]));
      }
      transpose_4x16(r, column + 4 * dword * column_step, column_step);
    }
  }
}

template <std::size_t kStride>
void columns_sse(const std::uint8_t* vertices, std::size_t first, std::size_t n, std::size_t count,
                 std::size_t stride, std::size_t block, std::uint8_t* columns) {
  for (std::size_t chunk = 0; chunk < n; chunk += kGroupSize) {
    const std::size_t start = first + chunk;
    const std::uint8_t* v = vertices + start * stride;
    if (start > 0 && start + kGroupSize <= count) {
      chunk_columns<kStride>(v, stride, columns + chunk, block);
      continue;
    }
    // The stream's first chunk, whose first vertex is its own predecessor, and its last when it is
    // short, which must read nothing past the vertices: copied after their predecessor, the last
    // vertex repeated to 16 so that the padding's deltas are 0, as the library's zeros.
    alignas(16) std::uint8_t padded[(kGroupSize + 1) * kMaxStride];
    const std::size_t here = std::min(kGroupSize, count - start);
    std::memcpy(padded, start > 0 ? v - stride : v, stride);
    std::memcpy(padded + stride, v, here * stride);
    for (std::size_t i = here; i < kGroupSize; ++i)
      std::memcpy(padded + (i + 1) * stride, v + (here - 1) * stride, stride);
    chunk_columns<kStride>(padded + stride, stride, columns + chunk, block);
  }
}

// 2-bit values (below 4), four to a byte, the first in the high bits: 4 bytes in the low dword.
__m128i pack_2_bits(__m128i v) {
  // Pairs in 16-bit lanes (first << 2 | second), then pairs of those in 32-bit lanes.
  __m128i pairs = _mm_or_si128(_mm_slli_epi16(v, 2), _mm_srli_epi16(v, 8));
  pairs = _mm_and_si128(pairs, _mm_set1_epi16(0x0f));
  __m128i quads = _mm_or_si128(_mm_slli_epi32(pairs, 4), _mm_srli_epi32(pairs, 16));
  quads = _mm_and_si128(quads, _mm_set1_epi32(0xff));
  quads = _mm_packs_epi32(quads, quads);
  return _mm_packus_epi16(quads, quads);
}

// 4-bit values (below 16), two to a byte, the first in the high bits: 8 bytes in the low qword.
__m128i pack_4_bits(__m128i v) {
  __m128i pairs = _mm_or_si128(_mm_slli_epi16(v, 4), _mm_srli_epi16(v, 8));
  pairs = _mm_and_si128(pairs, _mm_set1_epi16(0xff));
  return _mm_packus_epi16(pairs, pairs);
}

// The values of a group that its packed bits mark as stored in full, in order, at `data`.
std::uint8_t* put_wide(__m128i v, unsigned wide, std::uint8_t* data) {
  alignas(16) std::uint8_t values[kGroupSize];
  store(values, v);
  for (; wide != 0; wide &= wide - 1) *data++ = values[std::countr_zero(wide)];
  return data;
}

// Inlined by force: GCC keeps it out of line otherwise, and the call per group cost 15 % of the
// positions' encoding time on a 50k-triangle cut and 30 % of the normals'.
[[gnu::always_inline]] inline std::uint8_t* group_sse(const std::uint8_t* values, std::uint8_t* data,
                                                      unsigned& mode) {
  const __m128i v = load(values);
  const __m128i three = _mm_set1_epi8(3), fifteen = _mm_set1_epi8(15);
  const unsigned zero = static_cast<unsigned>(_mm_movemask_epi8(_mm_cmpeq_epi8(v, _mm_setzero_si128())));
  // v >= 3 (and >= 15) unsigned: the maximum is v itself.
  const unsigned wide_for_2 =
      static_cast<unsigned>(_mm_movemask_epi8(_mm_cmpeq_epi8(_mm_max_epu8(v, three), v)));
  const unsigned wide_for_4 =
      static_cast<unsigned>(_mm_movemask_epi8(_mm_cmpeq_epi8(_mm_max_epu8(v, fifteen), v)));
  mode = choose_mode(zero == 0xffff, population(wide_for_2), population(wide_for_4));
  switch (mode) {
    case kZero:
      return data;
    case kTwoBits: {
      const int packed = _mm_cvtsi128_si32(pack_2_bits(_mm_min_epu8(v, three)));
      std::memcpy(data, &packed, 4);
      return put_wide(v, wide_for_2, data + 4);
    }
    case kFourBits:
      _mm_storel_epi64(reinterpret_cast<__m128i*>(data), pack_4_bits(_mm_min_epu8(v, fifteen)));
      return put_wide(v, wide_for_4, data + 8);
    default:
      store(data, v);
      return data + kGroupSize;
  }
}

template <std::size_t kStride>
struct SseKernel {
  static void columns(const std::uint8_t* vertices, std::size_t first, std::size_t n, std::size_t count,
                      std::size_t stride, std::size_t block, std::uint8_t* columns) {
    columns_sse<kStride>(vertices, first, n, count, stride, block, columns);
  }
  static std::uint8_t* group(const std::uint8_t* values, std::uint8_t* data, unsigned& mode) {
    return group_sse(values, data, mode);
  }
};
#endif

// The stream, with the library's capacity checks; Kernel makes the columns and writes the groups.
template <class Kernel>
std::size_t encode(const void* vertices, std::size_t count, std::size_t stride, std::span<std::uint8_t> out) {
  assert(stride > 0 && stride <= kMaxStride && stride % 4 == 0);
  assert(vertices != nullptr || count == 0);
  // The library's first check, which a stream of no vertices meets too.
  if (out.size() < 1 + stride) return 0;
  const auto* v = static_cast<const std::uint8_t*>(vertices);
  std::uint8_t* data = out.data();
  const std::uint8_t* const end = data + out.size();
  *data++ = kVertexStreamV0Header;

  const std::size_t block = block_vertices(stride);
  alignas(16) std::uint8_t columns[kBlockBytes];
  for (std::size_t first = 0; first < count; first += block) {
    const std::size_t n = std::min(block, count - first);
    Kernel::columns(v, first, n, count, stride, block, columns);
    const std::size_t groups = (n + kGroupSize - 1) / kGroupSize;
    const std::size_t header_bytes = (groups + 3) / 4;
    for (std::size_t k = 0; k < stride; ++k) {
      if (static_cast<std::size_t>(end - data) < header_bytes) return 0;
      std::uint8_t* const header = data;
      data += header_bytes;
      std::uint32_t modes = 0;  // 2 bits a group, at most 16 groups
      for (std::size_t g = 0; g < groups; ++g) {
        // Every group's writes stay within these bytes.
        if (static_cast<std::size_t>(end - data) < kGroupRoom) return 0;
        unsigned mode;
        data = Kernel::group(columns + k * block + g * kGroupSize, data, mode);
        modes |= mode << (2 * g);
      }
      for (std::size_t h = 0; h < header_bytes; ++h) header[h] = static_cast<std::uint8_t>(modes >> (8 * h));
    }
  }

  const std::size_t tail = tail_bytes(stride);
  if (static_cast<std::size_t>(end - data) < tail) return 0;
  std::memset(data, 0, tail - stride);
  data += tail - stride;
  if (count > 0)
    std::memcpy(data, v, stride);
  else
    std::memset(data, 0, stride);
  data += stride;
  return static_cast<std::size_t>(data - out.data());
}

// ---- Octahedral filter -----------------------------------------------------------------------------

// meshopt_quantizeSnorm: the rounding offset is chosen before the clamp, so NaN (neither ≥ 0 nor
// ≥ −1) becomes −1 with offset −0.5.
int quantize_snorm(float v, int bits) {
  const float scale = static_cast<float>((1 << (bits - 1)) - 1);
  const float round = v >= 0 ? 0.5f : -0.5f;
  v = v >= -1 ? v : -1;
  v = v <= 1 ? v : 1;
  return static_cast<int>(v * scale + round);
}

// One vector as the library encodes it, stored as `stride` / 4-byte integers (their low bits).
void filter_oct_one(std::uint8_t* destination, std::size_t stride, int bits, float nx, float ny, float nz,
                    float nw) {
  const float length = std::fabs(nx) + std::fabs(ny) + std::fabs(nz);
  const float scale = length == 0.f ? 0.f : 1.f / length;
  nx *= scale;
  ny *= scale;
  // The lower half folds over the diagonals; the side is z's before the scaling (the library's).
  const float u = nz >= 0.f ? nx : (1 - std::fabs(ny)) * (nx >= 0.f ? 1.f : -1.f);
  const float v = nz >= 0.f ? ny : (1 - std::fabs(nx)) * (ny >= 0.f ? 1.f : -1.f);
  const int lanes[4] = {quantize_snorm(u, bits), quantize_snorm(v, bits), quantize_snorm(1.f, bits),
                        quantize_snorm(nw, static_cast<int>(stride * 2))};
  for (int k = 0; k < 4; ++k) {
    if (stride == 4) {
      destination[k] = static_cast<std::uint8_t>(lanes[k]);
    } else {
      destination[2 * k] = static_cast<std::uint8_t>(lanes[k]);
      destination[2 * k + 1] = static_cast<std::uint8_t>(lanes[k] >> 8);
    }
  }
}

#if defined(__SSE2__)
__m128i quantize_snorm(__m128 v, int bits) {
  const __m128 scale = _mm_set1_ps(static_cast<float>((1 << (bits - 1)) - 1));
  const __m128 round = _mm_or_ps(_mm_and_ps(_mm_cmpge_ps(v, _mm_setzero_ps()), _mm_set1_ps(0.5f)),
                                 _mm_andnot_ps(_mm_cmpge_ps(v, _mm_setzero_ps()), _mm_set1_ps(-0.5f)));
  // maxps gives its second operand when the first is NaN: the library's −1.
  v = _mm_min_ps(_mm_max_ps(v, _mm_set1_ps(-1.f)), _mm_set1_ps(1.f));
  return _mm_cvttps_epi32(_mm_add_ps(_mm_mul_ps(v, scale), round));
}

__m128 select(__m128 mask, __m128 yes, __m128 no) {
  return _mm_or_ps(_mm_and_ps(mask, yes), _mm_andnot_ps(mask, no));
}

// Four vectors, one per lane of x, y, z, w, encoded as filter_oct_one does, to 4 · stride bytes.
void filter_oct_four(std::uint8_t* destination, std::size_t stride, int bits, __m128 x, __m128 y, __m128 z,
                     __m128 w) {
  const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.f);
  const __m128 magnitude = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
  const __m128 length =
      _mm_add_ps(_mm_add_ps(_mm_and_ps(x, magnitude), _mm_and_ps(y, magnitude)), _mm_and_ps(z, magnitude));
  const __m128 scale = _mm_andnot_ps(_mm_cmpeq_ps(length, zero), _mm_div_ps(one, length));
  x = _mm_mul_ps(x, scale);
  y = _mm_mul_ps(y, scale);
  const __m128 upper = _mm_cmpge_ps(z, zero), minus_one = _mm_set1_ps(-1.f);
  const __m128 u = select(
      upper, x,
      _mm_mul_ps(_mm_sub_ps(one, _mm_and_ps(y, magnitude)), select(_mm_cmpge_ps(x, zero), one, minus_one)));
  const __m128 v = select(
      upper, y,
      _mm_mul_ps(_mm_sub_ps(one, _mm_and_ps(x, magnitude)), select(_mm_cmpge_ps(y, zero), one, minus_one)));
  const __m128i qu = quantize_snorm(u, bits), qv = quantize_snorm(v, bits);
  const __m128i qo = _mm_set1_epi32(quantize_snorm(1.f, bits));
  const __m128i qw = quantize_snorm(w, static_cast<int>(stride * 2));
  // Lanes to vectors (u, v, o, w each), cut to the lane width keeping the low bits as the library's
  // casts do: shifted up and back with the sign, so that the saturating packs change nothing.
  const __m128i uv01 = _mm_unpacklo_epi32(qu, qv), uv23 = _mm_unpackhi_epi32(qu, qv);
  const __m128i ow01 = _mm_unpacklo_epi32(qo, qw), ow23 = _mm_unpackhi_epi32(qo, qw);
  __m128i vectors[4] = {_mm_unpacklo_epi64(uv01, ow01), _mm_unpackhi_epi64(uv01, ow01),
                        _mm_unpacklo_epi64(uv23, ow23), _mm_unpackhi_epi64(uv23, ow23)};
  const int drop = stride == 4 ? 24 : 16;
  for (__m128i& vector : vectors) vector = _mm_srai_epi32(_mm_slli_epi32(vector, drop), drop);
  const __m128i first = _mm_packs_epi32(vectors[0], vectors[1]),
                second = _mm_packs_epi32(vectors[2], vectors[3]);
  if (stride == 4) {
    store(destination, _mm_packs_epi16(first, second));
  } else {
    store(destination, first);
    store(destination + 16, second);
  }
}
#endif

}  // namespace

std::size_t vertex_stream_bound(std::size_t count, std::size_t stride) {
  assert(stride > 0 && stride <= kMaxStride && stride % 4 == 0);
  const std::size_t block = block_vertices(stride);
  const std::size_t blocks = (count + block - 1) / block;
  const std::size_t header_bytes = (block / kGroupSize + 3) / 4;
  return 1 + blocks * stride * (header_bytes + block) + tail_bytes(stride);
}

std::size_t encode_vertex_stream_v0(const void* vertices, std::size_t count, std::size_t stride,
                                    std::span<std::uint8_t> out) {
#if defined(__SSE2__)
  if (stride == 4) return encode<SseKernel<4>>(vertices, count, stride, out);
  if (stride == 8) return encode<SseKernel<8>>(vertices, count, stride, out);
  return encode<SseKernel<0>>(vertices, count, stride, out);
#else
  return encode<PortableKernel>(vertices, count, stride, out);
#endif
}

std::size_t encode_vertex_stream_v0_portable(const void* vertices, std::size_t count, std::size_t stride,
                                             std::span<std::uint8_t> out) {
  return encode<PortableKernel>(vertices, count, stride, out);
}

void encode_filter_oct_portable(void* destination, std::size_t count, std::size_t stride, int bits,
                                const float* data) {
  assert(stride == 4 || stride == 8);
  assert(bits >= 1 && bits <= 16);
  auto* d = static_cast<std::uint8_t*>(destination);
  for (std::size_t i = 0; i < count; ++i) {
    const float* n = data + 4 * i;
    filter_oct_one(d + i * stride, stride, bits, n[0], n[1], n[2], n[3]);
  }
}

void encode_filter_oct_portable(void* destination, std::size_t stride, int bits,
                                std::span<const float> normals, std::span<const std::uint32_t> ids) {
  assert(stride == 4 || stride == 8);
  assert(bits >= 1 && bits <= 16);
  auto* d = static_cast<std::uint8_t*>(destination);
  for (std::size_t i = 0; i < ids.size(); ++i) {
    assert(3 * std::size_t{ids[i]} + 3 <= normals.size());
    const float* n = normals.data() + 3 * std::size_t{ids[i]};
    filter_oct_one(d + i * stride, stride, bits, n[0], n[1], n[2], 0.f);
  }
}

void encode_filter_oct(void* destination, std::size_t count, std::size_t stride, int bits,
                       const float* data) {
#if defined(__SSE2__)
  assert(stride == 4 || stride == 8);
  assert(bits >= 1 && bits <= 16);
  auto* d = static_cast<std::uint8_t*>(destination);
  std::size_t i = 0;
  for (; i + 4 <= count; i += 4) {
    __m128 x = _mm_loadu_ps(data + 4 * i), y = _mm_loadu_ps(data + 4 * i + 4);
    __m128 z = _mm_loadu_ps(data + 4 * i + 8), w = _mm_loadu_ps(data + 4 * i + 12);
    _MM_TRANSPOSE4_PS(x, y, z, w);
    filter_oct_four(d + i * stride, stride, bits, x, y, z, w);
  }
  encode_filter_oct_portable(d + i * stride, count - i, stride, bits, data + 4 * i);
#else
  encode_filter_oct_portable(destination, count, stride, bits, data);
#endif
}

void encode_filter_oct(void* destination, std::size_t stride, int bits, std::span<const float> normals,
                       std::span<const std::uint32_t> ids) {
#if defined(__SSE2__)
  assert(stride == 4 || stride == 8);
  assert(bits >= 1 && bits <= 16);
  auto* d = static_cast<std::uint8_t*>(destination);
  const float* n = normals.data();
  std::size_t i = 0;
  for (; i + 4 <= ids.size(); i += 4) {
    // The ids land anywhere in a model's normals: each read is asked for well ahead.
    if (i + kAheadIds + 4 <= ids.size())
      for (std::size_t k = 0; k < 4; ++k) __builtin_prefetch(n + 3 * std::size_t{ids[i + kAheadIds + k]});
    const float* a = n + 3 * std::size_t{ids[i]};
    const float* b = n + 3 * std::size_t{ids[i + 1]};
    const float* c = n + 3 * std::size_t{ids[i + 2]};
    const float* e = n + 3 * std::size_t{ids[i + 3]};
    assert(std::max({ids[i], ids[i + 1], ids[i + 2], ids[i + 3]}) < normals.size() / 3);
    filter_oct_four(d + i * stride, stride, bits, _mm_setr_ps(a[0], b[0], c[0], e[0]),
                    _mm_setr_ps(a[1], b[1], c[1], e[1]), _mm_setr_ps(a[2], b[2], c[2], e[2]),
                    _mm_setzero_ps());
  }
  encode_filter_oct_portable(d + i * stride, stride, bits, normals, ids.subspan(i));
#else
  encode_filter_oct_portable(destination, stride, bits, normals, ids);
#endif
}

}  // namespace mtlod::core::codec

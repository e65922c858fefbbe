// meshoptimizer encoding of a cut (layout in meshopt_encode.hpp). The cut's vertices are renumbered by
// first use through a table over the model's vertices, whose touched entries are reset afterwards, so
// the cost follows the cut and not the model; a reordering of the triangles then works on those compact
// ids. Each attribute is quantized into its own stream, the normals through the octahedral filter
// straight from the model's array, and written by encode_vertex_stream_v0 (meshoptimizer's vertex
// codec, version 0); the triangles by encode_index_stream_v1 (its index codec, version 1): our faster
// writers of the library's bytes, both writing straight into the caller's buffer at their place in
// the payload.
#include "core/codec/meshopt_encode.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include "core/codec/index_encode.hpp"
#include "core/codec/vertex_encode.hpp"
#include "core/model/bounds.hpp"
#include "fmt/format.h"

namespace mtlod::core::codec {
namespace {

constexpr std::uint32_t kUnused = std::numeric_limits<std::uint32_t>::max();

void put_u32(std::uint8_t* at, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) at[i] = static_cast<std::uint8_t>(value >> (8 * i));
}

void put_f32(std::uint8_t* at, float value) {
  put_u32(at, std::bit_cast<std::uint32_t>(value));
}

bool finite_grid(const DracoOptions::Grid& grid) {
  return std::isfinite(grid.origin[0]) && std::isfinite(grid.origin[1]) && std::isfinite(grid.origin[2]) &&
         std::isfinite(grid.range) && grid.range > 0;
}

// The options in range and the attributes they ask for present.
Status check_input(const DracoInput& input, const MeshoptOptions& options) {
  if (options.position_bits < 1 || options.position_bits > 16 || options.normal_bits < 2 ||
      options.normal_bits > 16) {
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("meshopt quantization bits {} / {} outside 1..16 / 2..16",
                                  options.position_bits, options.normal_bits));
  }
  if (options.position_grid && !finite_grid(*options.position_grid)) {
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("meshopt position grid range {} is not a finite positive size with a "
                                  "finite origin",
                                  options.position_grid->range));
  }
  if (options.normals && input.normals.size() != input.positions.size()) {
    return make_error(ErrorCode::kInvalidArgument, "normals requested but the model has none");
  }
  if (options.colors && input.colors.size() != input.positions.size()) {
    return make_error(ErrorCode::kInvalidArgument, "colours requested but the model has none");
  }
  if (input.triangles.empty()) {
    return make_error(ErrorCode::kInvalidArgument, "the cut has no triangles to encode");
  }
  return Ok{};
}

// Appends one vertex stream (length, then the stream) at `at`; returns the end.
std::uint8_t* put_vertex_stream(std::uint8_t* at, const void* values, std::size_t count, std::size_t stride) {
  const std::size_t size =
      encode_vertex_stream_v0(values, count, stride, {at + 4, vertex_stream_bound(count, stride)});
  assert(size > 0);  // the bound is always enough
  put_u32(at, static_cast<std::uint32_t>(size));
  return at + 4 + size;
}

}  // namespace

namespace {

// Three 8-bit coordinates interleaved: a point's place along a Z-order curve.
std::uint32_t morton_code(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
  auto spread = [](std::uint32_t v) {
    v = (v | (v << 8)) & 0x0300f00fu;
    v = (v | (v << 4)) & 0x030c30c3u;
    return (v | (v << 2)) & 0x09249249u;
  };
  return spread(x) | (spread(y) << 1) | (spread(z) << 2);
}

}  // namespace

// Triangles in Z-order of their lowest corner come in patches of neighbours, most of which share an
// edge with one of the sixteen triangles before them: meshoptimizer's index codec stores such a
// triangle in a few bits. On a refined cut of the dragon this takes the triangles stream from 2.9 to
// 1.7 bytes a triangle (meshopt_optimizeVertexCacheFifo: 1.45) at a small part of the FIFO
// optimizer's cost: codes from the quantized positions, a radix sort of 24-bit keys (two passes
// of twelve bits) and one more renumbering by first use, which also puts the vertices in Z-order for
// the vertex codec.
void MeshoptEncoder::reorder_spatially(int position_bits) {
  const std::size_t n = used_.size(), count = indices_.size() / 3;
  const int drop = std::max(0, position_bits - 8);
  keys_.resize(n + 2 * count);
  std::uint32_t* const code = keys_.data();
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint16_t* q = &quantized_[4 * i];
    code[i] = morton_code(q[0] >> drop, q[1] >> drop, q[2] >> drop);
  }
  std::uint32_t *key = code + n, *key_out = key + count;
  order_.resize(2 * count);
  std::uint32_t *order = order_.data(), *order_out = order + count;
  for (std::size_t t = 0; t < count; ++t) {
    const std::uint32_t* corner = &indices_[3 * t];
    key[t] = std::min({code[corner[0]], code[corner[1]], code[corner[2]]});
    order[t] = static_cast<std::uint32_t>(t);
  }
  constexpr int kBits = 12;
  constexpr std::uint32_t kBuckets = 1u << kBits;
  for (int shift = 0; shift < 24; shift += kBits) {
    std::array<std::uint32_t, kBuckets> start{};
    for (std::size_t t = 0; t < count; ++t) ++start[(key[t] >> shift) & (kBuckets - 1)];
    std::uint32_t sum = 0;
    for (std::uint32_t& s : start) sum += std::exchange(s, sum);
    for (std::size_t t = 0; t < count; ++t) {
      const std::uint32_t at = start[(key[t] >> shift) & (kBuckets - 1)]++;
      key_out[at] = key[t];
      order_out[at] = order[t];
    }
    std::swap(key, key_out);
    std::swap(order, order_out);
  }
  // Renumber by first use in the new order; the vertices' data and model ids follow. Without
  // branches, as in encode(): each vertex's data is written at the next id whether it is new or
  // not, and kept by counting it only when it is.
  renumber_.assign(n, kUnused);
  reordered_.resize(indices_.size());
  reordered_quantized_.resize(quantized_.size() + 4);
  reordered_used_.resize(n + 1);
  std::uint32_t* index = reordered_.data();
  std::uint32_t* const renumber = renumber_.data();
  const std::uint32_t* const used = used_.data();
  const std::uint16_t* const quantized = quantized_.data();
  std::uint16_t* const reordered_quantized = reordered_quantized_.data();
  std::uint32_t* const reordered_used = reordered_used_.data();
  std::uint32_t next = 0;
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint32_t* corner = &indices_[3 * std::size_t{order[i]}];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t old = corner[k];
      const std::uint32_t seen = renumber[old];
      const bool fresh = seen == kUnused;
      const std::uint32_t id = fresh ? next : seen;
      renumber[old] = id;
      std::memcpy(&reordered_quantized[4 * std::size_t{next}], &quantized[4 * std::size_t{old}], 8);
      reordered_used[next] = used[old];
      next += fresh;
      *index++ = id;
    }
  }
  assert(next == n);
  reordered_quantized_.resize(quantized_.size());
  reordered_used_.resize(n);
  indices_.swap(reordered_);
  quantized_.swap(reordered_quantized_);
  used_.swap(reordered_used_);  // the same vertices, so the encoded-id table is still reset right
}

Result<EncodeStats> MeshoptEncoder::encode(const DracoInput& input, const MeshoptOptions& options,
                                           std::vector<std::uint8_t>& out) {
  out.clear();
  if (Status checked = check_input(input, options); !checked) return checked.error();
  assert(input.triangles.size() % 3 == 0);

  // Renumber by first use. The table's entries go back to kUnused when the call ends, even when a
  // buffer below throws, so the next cut starts from a clean table without a pass over the model.
  const std::size_t model_vertices = input.positions.size() / 3;
  if (encoded_id_.size() < model_vertices) encoded_id_.resize(model_vertices, kUnused);
  used_.clear();
  struct ResetUsed {
    util::GrowOnlyVector<std::uint32_t>& encoded_id;
    const util::GrowOnlyVector<std::uint32_t>& used;
    ~ResetUsed() {
      for (const std::uint32_t v : used) encoded_id[v] = kUnused;
    }
  } reset_used{encoded_id_, used_};
  const std::size_t triangles = input.triangles.size() / 3;
  indices_.resize(input.triangles.size());
  // The table is as large as the model and the cut's corners land anywhere in it: each entry is asked
  // for well ahead.
  constexpr std::size_t kAheadCorners = 32;
  // Without branches (whether a corner's vertex is new goes either way too often to predict): each
  // corner writes its vertex at the next id, which counts only when the vertex is new. used_ has
  // room for that write after the last new vertex, and is cut to size after the loop, so the table
  // is reset from it whatever happens.
  used_.resize(std::min(input.triangles.size(), model_vertices) + 1);
  {
    const std::uint32_t* const corners = input.triangles.data();
    const std::size_t corner_count = input.triangles.size();
    std::uint32_t* const table = encoded_id_.data();
    std::uint32_t* const used = used_.data();
    std::uint32_t* const indices = indices_.data();
    std::uint32_t next = 0;
    for (std::size_t c = 0; c < corner_count; ++c) {
      if (c + kAheadCorners < corner_count) __builtin_prefetch(&table[corners[c + kAheadCorners]], 1);
      const std::uint32_t v = corners[c];
      assert(v < model_vertices);
      const std::uint32_t seen = table[v];
      const bool fresh = seen == kUnused;
      const std::uint32_t id = fresh ? next : seen;
      table[v] = id;
      used[next] = v;
      next += fresh;
      indices[c] = id;
    }
    used_.resize(next);
  }
  const std::size_t n = used_.size();
  // Gather the used positions (sparse in the model's arrays: each read is asked for well ahead, as in
  // draco_encode) and find the grid.
  constexpr std::size_t kAhead = 16;
  gathered_.resize(3 * n);
  model::Bounds box;
  for (std::size_t i = 0; i < n; ++i) {
    if (i + kAhead < n) __builtin_prefetch(&input.positions[3 * std::size_t{used_[i + kAhead]}]);
    std::memcpy(&gathered_[3 * i], &input.positions[3 * std::size_t{used_[i]}], 12);
    box.add(&gathered_[3 * i]);
  }
  std::array<float, 3> origin = box.lo;
  float range = box.largest_side();
  if (options.position_grid) origin = options.position_grid->origin, range = options.position_grid->range;
  const int levels = (1 << options.position_bits) - 1;
  const float step = range / static_cast<float>(levels);
  // Divided in double by the step as stored, so that origin + q · step is within half a step of the
  // position whatever the size of the coordinates, and a position halfway between two grid points
  // (the centre of a symmetric box) rounds up as the header says. NaN goes to 0 rather than to an
  // undefined cast.
  const double divisor = step > 0 ? double{step} : std::numeric_limits<double>::infinity();
  quantized_.resize(4 * n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) {
      const double q = (double{gathered_[3 * i + k]} - double{origin[k]}) / divisor;
      const double clamped = q > 0 ? (q < levels ? q : levels) : 0;
      quantized_[4 * i + k] = static_cast<std::uint16_t>(clamped + 0.5);
    }
    quantized_[4 * i + 3] = 0;
  }
  if (!options.keep_triangle_order) reorder_spatially(options.position_bits);

  // The payload at its largest, trimmed at the end.
  const std::size_t normal_stride = options.normal_bits <= 8 ? 4 : 8;
  std::size_t bound =
      kMeshoptHeaderBytes + 4 + vertex_stream_bound(n, 8) + 4 + index_stream_bound(input.triangles.size(), n);
  if (options.normals) bound += 4 + vertex_stream_bound(n, normal_stride);
  if (options.colors) bound += 4 + vertex_stream_bound(n, 4);
  out.resize(bound);
  std::uint8_t* const header = out.data();
  std::memcpy(header, kMeshoptMagic, 4);
  header[4] = kMeshoptVersion;
  header[5] = static_cast<std::uint8_t>((options.normals ? kMeshoptHasNormals : 0) |
                                        (options.colors ? kMeshoptHasColors : 0) |
                                        (options.normals && normal_stride == 8 ? kMeshoptWideNormals : 0));
  header[6] = static_cast<std::uint8_t>(options.position_bits);
  header[7] = static_cast<std::uint8_t>(options.normals ? options.normal_bits : 0);
  put_u32(header + 8, static_cast<std::uint32_t>(n));
  put_u32(header + 12, static_cast<std::uint32_t>(triangles));
  for (int k = 0; k < 3; ++k) put_f32(header + 16 + 4 * k, origin[k]);
  put_f32(header + 28, step);
  // The streams' first bytes are constants of our writers: the versions the payload promises.
  static_assert(kVertexStreamV0Header == kMeshoptVertexStreamHeader);
  std::uint8_t* at = put_vertex_stream(header + kMeshoptHeaderBytes, quantized_.data(), n, 8);
  if (options.normals) {
    attribute_.resize(normal_stride * n);
    encode_filter_oct(attribute_.data(), normal_stride, options.normal_bits, input.normals, used_);
    at = put_vertex_stream(at, attribute_.data(), n, normal_stride);
  }
  if (options.colors) {
    attribute_.resize(4 * n);
    for (std::size_t i = 0; i < n; ++i) {
      std::memcpy(&attribute_[4 * i], &input.colors[3 * std::size_t{used_[i]}], 3);
      attribute_[4 * i + 3] = 255;
    }
    at = put_vertex_stream(at, attribute_.data(), n, 4);
  }
  static_assert(kIndexStreamV1Header == kMeshoptIndexStreamHeader);
  const std::size_t index_size =
      encode_index_stream_v1(indices_, {at + 4, index_stream_bound(indices_.size(), n)});
  assert(index_size > 0);  // the bound is always enough
  put_u32(at, static_cast<std::uint32_t>(index_size));
  at += 4 + index_size;
  out.resize(static_cast<std::size_t>(at - out.data()));
  return EncodeStats{n, triangles, out.size()};
}

}  // namespace mtlod::core::codec

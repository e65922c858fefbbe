// Draco encoding of a cut. The cut refers to model vertex ids; Draco wants a compact point list,
// so used vertices are renumbered in model vertex order: a bit per model vertex marks the used ones
// and a vertex's new id is the number of used vertices before it (a popcount rank). The bit array
// is 1/32 of a 32-bit table's size, so the renumbering's lookups stay in cache, and model order
// keeps neighbouring points close, which Draco's delta coding of positions rewards.
#include "core/codec/draco_encode.hpp"

#include <draco/compression/config/compression_shared.h>
#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>

#include <algorithm>
#include <bit>
#include <cassert>
#include <cstring>

#include "fmt/format.h"

namespace mtlod::core::codec {
namespace {

// Adds an attribute with one value per point (identity mapping) and copies `bytes` into it.
int add_attribute(draco::Mesh& mesh, draco::GeometryAttribute::Type type, int components,
                  draco::DataType data_type, int component_bytes, const void* values,
                  bool normalized = false) {
  draco::GeometryAttribute attribute;
  attribute.Init(type, nullptr, static_cast<std::uint8_t>(components), data_type, normalized,
                 components * component_bytes, 0);
  const int id = mesh.AddAttribute(attribute, true, mesh.num_points());
  mesh.attribute(id)->buffer()->Write(0, values,
                                      std::size_t{mesh.num_points()} * components * component_bytes);
  return id;
}

// Writes the cut's triangles in encoded ids: a vertex's id is the number of used vertices before it
// (rank per 64-bit word plus a popcount within the word). Cloned for CPUs with a popcount
// instruction, which the baseline x86-64 target lacks; the loader picks the clone once.
#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target_clones("popcnt", "default")))
#endif
void add_faces(draco::Mesh& mesh, std::span<const std::uint32_t> triangles, const std::uint64_t* used_bits,
               const std::uint32_t* rank) {
  auto encoded_id = [&](std::uint32_t v) {
    const std::uint64_t below = used_bits[v >> 6] & ((std::uint64_t{1} << (v & 63)) - 1);
    return draco::PointIndex(rank[v >> 6] + static_cast<std::uint32_t>(std::popcount(below)));
  };
  const std::size_t count = triangles.size() / 3;
  mesh.SetNumFaces(count);
  for (std::size_t t = 0; t < count; ++t) {
    const std::uint32_t* corners = &triangles[3 * t];
    mesh.SetFace(draco::FaceIndex(static_cast<std::uint32_t>(t)),
                 {encoded_id(corners[0]), encoded_id(corners[1]), encoded_id(corners[2])});
  }
}

// The options in range and the attributes they ask for present.
Status check_input(const DracoInput& input, const DracoOptions& options) {
  const std::size_t model_vertices = input.positions.size() / 3;
  if (options.speed < 0 || options.speed > 10) {
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("draco speed {} is outside 0..10", options.speed));
  }
  if (options.position_bits < 0 || options.position_bits > 30 || options.normal_bits < 1 ||
      options.normal_bits > 30) {
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("draco quantization bits {} / {} outside 0..30 / 1..30",
                                  options.position_bits, options.normal_bits));
  }
  if (options.normals && input.normals.size() != input.positions.size()) {
    return make_error(ErrorCode::kInvalidArgument, "normals requested but the model has none");
  }
  if (options.colors && input.colors.size() != 3 * model_vertices) {
    return make_error(ErrorCode::kInvalidArgument, "colours requested but the model has none");
  }
  if (options.labels && input.labels.size() != model_vertices) {
    return make_error(ErrorCode::kInvalidArgument,
                      "labels requested but none were computed for this request");
  }
  if (input.triangles.empty()) {
    return make_error(ErrorCode::kInvalidArgument, "the cut has no triangles to encode");
  }
  return Ok{};
}

void configure(draco::Encoder& encoder, const DracoOptions& options) {
  // Edgebreaker splits the vertices of non-manifold corners (a scan's, or two faces stacked at a
  // coarse level): the reply announces what the payload decodes to, not the cut's vertex count.
  encoder.SetTrackEncodedProperties(true);
  encoder.SetSpeedOptions(options.speed, options.speed);
  if (options.position_bits > 0 && options.position_grid && options.position_grid->range > 0) {
    encoder.SetAttributeExplicitQuantization(draco::GeometryAttribute::POSITION, options.position_bits, 3,
                                             options.position_grid->origin.data(),
                                             options.position_grid->range);
  } else if (options.position_bits > 0) {
    encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, options.position_bits);
  }
  if (options.normals)
    encoder.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, options.normal_bits);
  if (!options.entropy_coding) {
    encoder.options().SetGlobalBool("use_built_in_attribute_compression", false);
    // Stored raw, a 14-bit coordinate takes two bytes whether or not it is predicted first.
    encoder.SetAttributePredictionScheme(draco::GeometryAttribute::POSITION, draco::PREDICTION_NONE);
  }
  encoder.SetEncodingMethod(options.method == DracoMethod::kSequential ? draco::MESH_SEQUENTIAL_ENCODING
                                                                       : draco::MESH_EDGEBREAKER_ENCODING);
}

}  // namespace

void DracoEncoder::list_used(std::span<const std::uint32_t> triangles) {
  for (std::uint32_t v : triangles) {
    assert(v < 64 * used_bits_.size());
    std::uint64_t& word = used_bits_[v >> 6];
    if (word == 0) touched_words_.push_back(v >> 6);
    word |= std::uint64_t{1} << (v & 63);
  }
  std::sort(touched_words_.begin(), touched_words_.end());
  used_.clear();
  std::uint32_t count = 0;
  for (const std::uint32_t w : touched_words_) {
    rank_[w] = count;
    for (std::uint64_t bits = used_bits_[w]; bits != 0; bits &= bits - 1) {
      used_.push_back(
          static_cast<std::uint32_t>(64 * std::size_t{w} + static_cast<unsigned>(std::countr_zero(bits))));
    }
    count += static_cast<std::uint32_t>(std::popcount(used_bits_[w]));
  }
}

Result<EncodeStats> DracoEncoder::encode(const DracoInput& input, const DracoOptions& options,
                                         std::vector<std::uint8_t>& out) {
  out.clear();
  const std::size_t model_vertices = input.positions.size() / 3;
  if (Status checked = check_input(input, options); !checked) return checked.error();
  // Renumber the used vertices: mark, rank, list. Only the words the cut's vertices fall in are
  // visited (sorted, so ids keep the model's order), and cleared again once the faces are written:
  // the cost follows the cut, not the model's vertex count.
  const std::size_t words = (model_vertices + 63) / 64;
  if (used_bits_.size() != words) {
    used_bits_.assign(words, 0);
    rank_.assign(words, 0);
  }
  touched_words_.clear();
  // All zero again for the next cut, even when the encoding below throws.
  struct ClearTouched {
    std::vector<std::uint64_t>& bits;
    const std::vector<std::uint32_t>& words;
    ~ClearTouched() {
      for (const std::uint32_t w : words) bits[w] = 0;
    }
  } clear_touched{used_bits_, touched_words_};
  list_used(input.triangles);
  const std::size_t n = used_.size();

  draco::Mesh mesh;
  mesh.set_num_points(static_cast<std::uint32_t>(n));
  add_faces(mesh, input.triangles, used_bits_.data(), rank_.data());
  auto gather3 = [&](std::span<const float> values) {
    // The used vertices are sparse in the model's arrays (one in 17 for a 50k-triangle dragon cut):
    // each read misses the cache unless it is asked for well ahead.
    constexpr std::size_t kAhead = 16;
    scratch_.resize(3 * n);
    for (std::size_t i = 0; i < n; ++i) {
      if (i + kAhead < n) __builtin_prefetch(&values[3 * std::size_t{used_[i + kAhead]}]);
      std::memcpy(&scratch_[3 * i], &values[3 * std::size_t{used_[i]}], 12);
    }
    return scratch_.data();
  };
  add_attribute(mesh, draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32, 4, gather3(input.positions));
  if (options.normals) {
    add_attribute(mesh, draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32, 4, gather3(input.normals));
  }
  if (options.colors) {
    colors_.resize(3 * n);
    for (std::size_t i = 0; i < n; ++i)
      std::memcpy(&colors_[3 * i], &input.colors[3 * std::size_t{used_[i]}], 3);
    // Normalized: glTF's COLOR_0 and three.js read 255 as 1.0.
    add_attribute(mesh, draco::GeometryAttribute::COLOR, 3, draco::DT_UINT8, 1, colors_.data(), true);
  }
  if (options.labels) {
    std::vector<std::uint16_t> labels(n);
    for (std::size_t i = 0; i < n; ++i)
      labels[i] = static_cast<std::uint16_t>(std::min<std::uint32_t>(input.labels[used_[i]], 65535));
    const int id =
        add_attribute(mesh, draco::GeometryAttribute::GENERIC, 1, draco::DT_UINT16, 2, labels.data());
    auto metadata = std::make_unique<draco::AttributeMetadata>();
    metadata->AddEntryString("name", "label");
    mesh.AddAttributeMetadata(id, std::move(metadata));
  }

  draco::Encoder encoder;
  configure(encoder, options);
  draco::EncoderBuffer buffer;
  const draco::Status status = encoder.EncodeMeshToBuffer(mesh, &buffer);
  if (!status.ok()) {
    return make_error(ErrorCode::kInternal,
                      fmt::format("draco refused the mesh: {}", status.error_msg_string()));
  }
  out.assign(buffer.data(), buffer.data() + buffer.size());
  return EncodeStats{encoder.num_encoded_points(), encoder.num_encoded_faces(), out.size()};
}

}  // namespace mtlod::core::codec

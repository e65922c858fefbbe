// Draco encoding of a cut. The cut refers to model vertex ids; Draco wants a compact point list,
// so used vertices are renumbered in first-use order with a table kept between calls (resetting
// only the touched entries keeps the cost proportional to the cut, not the model).
#include "core/draco_encode.hpp"

#include <draco/compression/config/compression_shared.h>
#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>

#include <algorithm>
#include <cassert>
#include <cstring>

#include "fmt/format.h"

namespace mtlod::core {
namespace {

constexpr std::uint32_t kUnused = UINT32_MAX;

// Adds an attribute with one value per point (identity mapping) and copies `bytes` into it.
int add_attribute(draco::Mesh& mesh, draco::GeometryAttribute::Type type, int components, draco::DataType data_type,
                  int component_bytes, const void* values) {
  draco::GeometryAttribute attribute;
  attribute.Init(type, nullptr, static_cast<std::uint8_t>(components), data_type, false,
                 components * component_bytes, 0);
  const int id = mesh.AddAttribute(attribute, true, mesh.num_points());
  mesh.attribute(id)->buffer()->Write(0, values, std::size_t{mesh.num_points()} * components * component_bytes);
  return id;
}

}  // namespace

Result<DracoStats> DracoEncoder::encode(const DracoInput& input, const DracoOptions& options,
                                        std::vector<std::uint8_t>& out) {
  out.clear();
  const std::size_t model_vertices = input.positions.size() / 3;
  if (options.speed < 0 || options.speed > 10) {
    return make_error(ErrorCode::kInvalidArgument, fmt::format("draco speed {} is outside 0..10", options.speed));
  }
  if (options.position_bits < 0 || options.position_bits > 30 || options.normal_bits < 1 || options.normal_bits > 30) {
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("draco quantization bits {} / {} outside 0..30 / 1..30", options.position_bits,
                                  options.normal_bits));
  }
  if (options.normals && input.normals.size() != input.positions.size()) {
    return make_error(ErrorCode::kInvalidArgument, "normals requested but the model has none");
  }
  if (options.labels && input.labels.size() != model_vertices) {
    return make_error(ErrorCode::kInvalidArgument, "labels requested but none were computed for this request");
  }
  if (input.triangles.empty()) {
    return make_error(ErrorCode::kInvalidArgument, "the cut has no triangles to encode");
  }

  // Renumber the used vertices.
  if (remap_.size() < model_vertices) remap_.resize(model_vertices, kUnused);
  used_.clear();
  for (std::uint32_t v : input.triangles) {
    assert(v < model_vertices);
    if (remap_[v] == kUnused) {
      remap_[v] = static_cast<std::uint32_t>(used_.size());
      used_.push_back(v);
    }
  }
  const std::size_t n = used_.size();

  draco::Mesh mesh;
  mesh.set_num_points(static_cast<std::uint32_t>(n));
  const std::size_t triangle_count = input.triangles.size() / 3;
  mesh.SetNumFaces(triangle_count);
  for (std::size_t t = 0; t < triangle_count; ++t) {
    mesh.SetFace(draco::FaceIndex(static_cast<std::uint32_t>(t)),
                 {draco::PointIndex(remap_[input.triangles[3 * t]]), draco::PointIndex(remap_[input.triangles[3 * t + 1]]),
                  draco::PointIndex(remap_[input.triangles[3 * t + 2]])});
  }
  auto gather3 = [&](std::span<const float> values) {
    scratch_.resize(3 * n);
    for (std::size_t i = 0; i < n; ++i) std::memcpy(&scratch_[3 * i], &values[3 * std::size_t{used_[i]}], 12);
    return scratch_.data();
  };
  add_attribute(mesh, draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32, 4, gather3(input.positions));
  if (options.normals) {
    add_attribute(mesh, draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32, 4, gather3(input.normals));
  }
  if (options.labels) {
    std::vector<std::uint16_t> labels(n);
    for (std::size_t i = 0; i < n; ++i) labels[i] = static_cast<std::uint16_t>(std::min<std::uint32_t>(input.labels[used_[i]], 65535));
    const int id = add_attribute(mesh, draco::GeometryAttribute::GENERIC, 1, draco::DT_UINT16, 2, labels.data());
    auto metadata = std::make_unique<draco::AttributeMetadata>();
    metadata->AddEntryString("name", "label");
    mesh.AddAttributeMetadata(id, std::move(metadata));
  }
  for (std::uint32_t v : used_) remap_[v] = kUnused;  // leave the table clean for the next call

  draco::Encoder encoder;
  encoder.SetSpeedOptions(options.speed, options.speed);
  if (options.position_bits > 0) encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, options.position_bits);
  if (options.normals) encoder.SetAttributeQuantization(draco::GeometryAttribute::NORMAL, options.normal_bits);
  encoder.SetEncodingMethod(options.method == DracoMethod::kSequential ? draco::MESH_SEQUENTIAL_ENCODING
                                                                       : draco::MESH_EDGEBREAKER_ENCODING);
  draco::EncoderBuffer buffer;
  const draco::Status status = encoder.EncodeMeshToBuffer(mesh, &buffer);
  if (!status.ok()) {
    return make_error(ErrorCode::kInternal, fmt::format("draco refused the mesh: {}", status.error_msg_string()));
  }
  out.assign(buffer.data(), buffer.data() + buffer.size());
  return DracoStats{n, triangle_count, out.size()};
}

}  // namespace mtlod::core

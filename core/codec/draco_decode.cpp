// Draco payload → Mesh (see draco_decode.hpp).
#include "core/codec/draco_decode.hpp"

#include <draco/compression/decode.h>

#include <algorithm>
#include <cmath>

#include "fmt/format.h"

namespace mtlod::core::codec {

Result<DecodedMesh> decode_draco(std::span<const std::uint8_t> bytes) {
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) {
    return make_error(ErrorCode::kCorrupt,
                      fmt::format("not a Draco mesh: {}", decoded.status().error_msg_string()));
  }
  const draco::Mesh& in = *decoded.value();
  const draco::PointAttribute* position = in.GetNamedAttribute(draco::GeometryAttribute::POSITION);
  if (!position || position->num_components() != 3) {
    return make_error(ErrorCode::kCorrupt, "Draco mesh has no 3-component positions");
  }
  DecodedMesh out;
  out.attribute_ids.position = static_cast<int>(position->unique_id());
  const std::size_t n = in.num_points();
  out.mesh.positions.resize(3 * n);
  for (draco::PointIndex i(0); i < in.num_points(); ++i) {
    position->ConvertValue<float, 3>(position->mapped_index(i), &out.mesh.positions[3 * i.value()]);
  }
  if (const auto* normal = in.GetNamedAttribute(draco::GeometryAttribute::NORMAL);
      normal && normal->num_components() == 3) {
    out.attribute_ids.normal = static_cast<int>(normal->unique_id());
    out.mesh.normals.resize(3 * n);
    for (draco::PointIndex i(0); i < in.num_points(); ++i) {
      normal->ConvertValue<float, 3>(normal->mapped_index(i), &out.mesh.normals[3 * i.value()]);
    }
  }
  if (const auto* color = in.GetNamedAttribute(draco::GeometryAttribute::COLOR);
      color && (color->num_components() == 3 || color->num_components() == 4)) {
    out.attribute_ids.color = static_cast<int>(color->unique_id());
    out.mesh.colors.resize(3 * n);
    // Bytes as they are; other types are read as 0..1 (and RGBA loses its alpha).
    const bool bytes = color->data_type() == draco::DT_UINT8;
    for (draco::PointIndex i(0); i < in.num_points(); ++i) {
      float value[4] = {};
      std::uint8_t byte[4] = {};
      if (bytes)
        color->ConvertValue<std::uint8_t>(color->mapped_index(i), byte);
      else
        color->ConvertValue<float>(color->mapped_index(i), value);
      for (int k = 0; k < 3; ++k) {
        out.mesh.colors[3 * i.value() + k] =
            bytes ? byte[k]
                  : static_cast<std::uint8_t>(std::lround(std::clamp(value[k], 0.0f, 1.0f) * 255.0f));
      }
    }
  }
  if (const auto* label = in.GetNamedAttribute(draco::GeometryAttribute::GENERIC);
      label && label->num_components() == 1) {
    out.attribute_ids.label = static_cast<int>(label->unique_id());
    out.labels.resize(n);
    for (draco::PointIndex i(0); i < in.num_points(); ++i) {
      label->ConvertValue<std::uint16_t, 1>(label->mapped_index(i), &out.labels[i.value()]);
    }
  }
  out.mesh.triangles.resize(3 * std::size_t{in.num_faces()});
  for (draco::FaceIndex f(0); f < in.num_faces(); ++f) {
    const auto& face = in.face(f);
    for (int c = 0; c < 3; ++c) out.mesh.triangles[3 * f.value() + c] = face[c].value();
  }
  return out;
}

}  // namespace mtlod::core::codec

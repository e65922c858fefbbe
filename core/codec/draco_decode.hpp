// Decoding a Draco payload back into a Mesh (positions, normals and colours when present) plus the per-vertex
// labels the server may attach. For clients writing PLY/OBJ and for tests. Safe on any bytes.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/model/mesh.hpp"
#include "core/result.hpp"

namespace mtlod::core::codec {

// The Draco unique ids of a payload's attributes, -1 for those it lacks: what glTF's
// KHR_draco_mesh_compression names them by.
struct DracoAttributeIds {
  int position = -1;
  int normal = -1;
  int color = -1;
  int label = -1;
};

struct DecodedMesh {
  model::Mesh mesh;                   // positions; normals and colours (r, g, b) when present
  std::vector<std::uint16_t> labels;  // empty, or one per vertex (the generic attribute "label")
  DracoAttributeIds attribute_ids;
};

// Errors: kCorrupt with Draco's reason when the bytes are not a Draco triangle mesh.
Result<DecodedMesh> decode_draco(std::span<const std::uint8_t> bytes);

}  // namespace mtlod::core::codec

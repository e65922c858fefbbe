// Decoding a Draco payload back into a Mesh (positions, normals when present) plus the per-vertex
// labels the server may attach. For clients writing PLY/OBJ and for tests. Safe on any bytes.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/mesh.hpp"
#include "core/result.hpp"

namespace mtlod::core {

struct DecodedMesh {
  Mesh mesh;
  std::vector<std::uint16_t> labels;  // empty, or one per vertex (the generic attribute "label")
};

// Errors: kCorrupt with Draco's reason when the bytes are not a Draco triangle mesh.
Result<DecodedMesh> decode_draco(std::span<const std::uint8_t> bytes);

}  // namespace mtlod::core

// Decoding a meshoptimizer payload (layout in meshopt_encode.hpp) back into a Mesh: dequantized positions,
// unit normals and colours when present, triangles indexing the decoded vertices. For clients writing
// PLY/OBJ, for glTF writers that pass the streams on as they are, and for tests. Safe on any bytes.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "core/model/mesh.hpp"
#include "core/result.hpp"

namespace mtlod::core::codec {

// A payload's header and streams, checked for consistency (magic, version, flags, bits, counts against
// stream sizes, lengths within the bytes) but not decoded. The spans view the payload.
struct MeshoptPayload {
  std::uint32_t vertex_count = 0;
  std::uint32_t triangle_count = 0;
  int position_bits = 0;          // 1..16
  int normal_bits = 0;            // 2..16, 0 without normals
  std::size_t normal_stride = 0;  // 4 or 8 bytes, 0 without normals
  bool colors = false;
  // A stored coordinate q decodes to origin + q · step (glTF: the node's translation and scale).
  std::array<float, 3> origin{};
  float step = 0;
  std::span<const std::uint8_t> positions;  // vertex buffer, stride 8
  std::span<const std::uint8_t> normals;    // vertex buffer, stride normal_stride; empty without normals
  std::span<const std::uint8_t> colours;    // vertex buffer, stride 4; empty without colours
  std::span<const std::uint8_t> triangles;  // index buffer, 3 · triangle_count indices
};

// Errors: kCorrupt naming what is wrong (and where); kUnsupported for a newer format version.
Result<MeshoptPayload> read_meshopt(std::span<const std::uint8_t> payload);

struct DecodedMeshopt {
  model::Mesh mesh;  // positions; normals (unit length) and colours (r, g, b) when present; triangles
  // How the positions were quantized: origin + q · step for q in 0 .. 2^position_bits − 1.
  std::array<float, 3> origin{};
  float step = 0;
  int position_bits = 0;
  int normal_bits = 0;  // 0 without normals
  // The smallest and largest stored q per axis (a glTF accessor's min and max of the stream).
  std::array<std::uint16_t, 3> stored_min{};
  std::array<std::uint16_t, 3> stored_max{};
};

// Errors: those of read_meshopt, and kCorrupt when a stream does not decode, a stored value is outside
// what its header allows (a coordinate past position_bits, an octahedral normal off the octahedron,
// an alpha other than 255, nonzero padding) or a triangle names a vertex past the vertex count.
Result<DecodedMeshopt> decode_meshopt(std::span<const std::uint8_t> payload);

}  // namespace mtlod::core::codec

// meshoptimizer compression of an extracted cut (core/ARCHITECTURE.md §3), beside draco_encode: larger
// payloads than Draco's edgebreaker, much smaller than its sequential method, quick to decode, and made
// of streams a glTF client takes as they are (EXT_meshopt_compression buffer views: ATTRIBUTES with
// KHR_mesh_quantization positions and OCTAHEDRAL normals, TRIANGLES indices), written by our own
// writers of meshoptimizer's codecs (index_encode.hpp, vertex_encode.hpp).
//
// The payload, little-endian:
//   offset  bytes  field
//   0       4      magic "MOPT"
//   4       1      format version, 1
//   5       1      flags: bit 0 normals, bit 1 colours, bit 2 normals stored as 16-bit components
//                  (stride 8; clear: 8-bit, stride 4; set only with bit 0); other bits 0
//   6       1      position_bits, 1..16
//   7       1      normal_bits: 2..8 with bit 2 clear, 9..16 with it set; 0 without normals
//   8       4      u32 vertex count, at least 1
//   12      4      u32 triangle count, at least 1
//   16      12     f32 origin x, y, z
//   28      4      f32 step: a stored coordinate q decodes to origin + q · step; the encoder stores
//                  q = ⌊(p − origin) / step + 1/2⌋ (in double), clamped to 0 .. 2^position_bits − 1,
//                  with step = largest side / (2^position_bits − 1) of the grid, in float
//   32             the streams, each a u32 byte length and then its bytes, in this order:
//     positions    meshoptimizer vertex buffer (codec version 0), stride 8: u16 x, y, z (each below
//                  2^position_bits) and a u16 0
//     normals      (bit 0) vertex buffer, stride 4 (int8) or 8 (int16): octahedral x, y, the
//                  normal_bits encoding of 1 and 0, as meshopt_encodeFilterOct writes them
//     colours      (bit 1) vertex buffer, stride 4: u8 r, g, b, 255
//     triangles    meshoptimizer index buffer (codec version 1), 3 u32 indices per triangle
//   and nothing after the last stream.
//
// Triangles are reordered along a Z-order curve (by their lowest corner), which puts neighbours
// together as the index codec rewards, unless MeshoptOptions::keep_triangle_order asks for the cut's
// order (deltas, whose triangle ids follow it); the index codec may also start a triangle at another corner
// (same winding). Vertices are the ones the triangles use, numbered in order of first use as the payload's
// triangles are read (what meshopt_optimizeVertexFetch gives): the index codec stores a vertex seen for the
// first time in no extra bytes, and neighbours stay close for the vertex codec. In glTF terms a position is
// the stored u16 vector under a node with translation `origin` and uniform scale `step`.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "core/codec/draco_encode.hpp"
#include "core/result.hpp"
#include "core/util/grow_only_vector.hpp"

namespace mtlod::core::codec {

inline constexpr std::uint8_t kMeshoptMagic[4] = {'M', 'O', 'P', 'T'};
inline constexpr std::uint8_t kMeshoptVersion = 1;
inline constexpr std::size_t kMeshoptHeaderBytes = 32;
// The flags byte.
inline constexpr std::uint8_t kMeshoptHasNormals = 1;
inline constexpr std::uint8_t kMeshoptHasColors = 2;
inline constexpr std::uint8_t kMeshoptWideNormals = 4;
// The first byte of each stream: a meshoptimizer vertex buffer of codec version 0, an index buffer of
// version 1, what EXT_meshopt_compression's ATTRIBUTES and TRIANGLES modes accept.
inline constexpr std::uint8_t kMeshoptVertexStreamHeader = 0xa0;
inline constexpr std::uint8_t kMeshoptIndexStreamHeader = 0xe1;

struct MeshoptOptions {
  int position_bits = 14;  // quantization of positions on the grid, 1..16 bits
  int normal_bits = 10;    // octahedral quantization of normals, 2..16 bits (≤ 8: one byte a component)
  bool normals = false;    // encode the original vertices' normals (needs them in the input)
  bool colors = false;     // encode the vertices' colours (lossless, alpha 255)
  // Keep the cut's triangle order instead of reordering the triangles spatially, which takes roughly
  // 40 % off the triangles stream of a refined cut. Deltas need the order kept (their triangle
  // ids follow it), as they need Draco's sequential method.
  bool keep_triangle_order = false;
  // Quantize positions on this grid (origin and largest side: the model's bounding box) instead of
  // the encoded vertices' own box, so that a vertex decodes to the same floats in every payload.
  // Positions outside it are clamped to its faces.
  std::optional<DracoOptions::Grid> position_grid;
};

// Reusable encoder: keeps its renumbering table (one entry per vertex of the largest model seen) and its
// stream buffers between calls, so once they have grown a call allocates nothing (the streams are
// written in the caller's buffer). Labels in the input are ignored: the payload has no generic
// attribute.
class MeshoptEncoder {
 public:
  // Encodes the cut into `out` (cleared first). Fails with kInvalidArgument when options are out of
  // range, the grid is not a finite box, attributes asked for are missing or the cut has no
  // triangles.
  Result<EncodeStats> encode(const DracoInput& input, const MeshoptOptions& options,
                             std::vector<std::uint8_t>& out);

 private:
  // Puts the triangles (indices_) in Z-order of their lowest corner and renumbers the vertices by
  // first use in that order (indices_, used_ and quantized_ follow).
  void reorder_spatially(int position_bits);

  // New elements of these arrays are left uninitialised: each call writes every element it reads.
  util::GrowOnlyVector<std::uint32_t> encoded_id_;  // per model vertex: its encoded id, kUnused between calls
  util::GrowOnlyVector<std::uint32_t> used_;        // encoded id -> model vertex id
  util::GrowOnlyVector<std::uint32_t> indices_;     // the payload's triangles in encoded ids
  util::GrowOnlyVector<std::uint32_t> keys_;        // reordering: the vertices' Z-order codes, triangle keys
  util::GrowOnlyVector<std::uint32_t> order_;       // reordering: the triangles in sorted order, and scratch
  util::GrowOnlyVector<std::uint32_t> renumber_;    // reordering: encoded id in the cut's order -> new one
  util::GrowOnlyVector<std::uint32_t> reordered_;   // reordering: the triangles renumbered
  util::GrowOnlyVector<std::uint32_t> reordered_used_;       // reordering: used_ in the new order
  util::GrowOnlyVector<std::uint16_t> reordered_quantized_;  // reordering: quantized_ in the new order
  util::GrowOnlyVector<float> gathered_;                     // positions of the used vertices
  util::GrowOnlyVector<std::uint16_t> quantized_;            // 4 per vertex: x, y, z, 0
  util::GrowOnlyVector<std::uint8_t> attribute_;  // octahedral normals or rgba colours, before the codec
};

}  // namespace mtlod::core::codec

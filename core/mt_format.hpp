// The .mt file format (DESIGN.md §2 "Storage", layout in core/FORMAT.md): serialisation of an Mt to
// and from bytes. Pure: no file access (core/io/mt_file.hpp reads and writes files).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/mt.hpp"
#include "core/result.hpp"

namespace mtlod::core {

inline constexpr std::uint32_t kMtFormatVersion = 1;
inline constexpr std::size_t kMtHeaderBytes = 64;

// 64-bit checksum over bytes: FNV-1a style mixing of little-endian 8-byte words, then the tail
// bytes. Any change to a single word changes the result (each step is a bijection of the state).
std::uint64_t mt_checksum(std::span<const std::uint8_t> bytes, std::uint64_t seed = 0xcbf29ce484222325ull);

// What an .mt header states; enough to lay the file out before its arrays exist, for writers that
// stream them (core/io/large_build.cpp).
struct MtCounts {
  bool normals = false;
  bool colors = false;
  std::uint32_t vertices = 0;
  std::uint32_t nodes = 0;
  std::uint32_t triangles = 0;
  std::uint32_t root_triangles = 0;
  std::uint32_t parents = 0;
};
// Byte offset of each array in the file (core/FORMAT.md, "Payload"); end is the file size.
struct MtLayout {
  std::uint64_t positions, normals, colors, node_vertex, node_error, node_triangle_offsets,
      node_parent_offsets, node_parents, triangle_corners, root_first_corner, triangle_remover, end;
};
MtLayout mt_layout(const MtCounts& counts);
// The header for counts, with its checksum field zero: the checksum of the whole file with this
// header goes at kMtChecksumOffset.
inline constexpr std::size_t kMtChecksumOffset = 48;
std::array<std::uint8_t, kMtHeaderBytes> mt_header(const MtCounts& counts);

// Appends the file image of mt to out (cleared first). mt must be valid (as build_mt makes it).
void serialize_mt(const Mt& mt, std::vector<std::uint8_t>& out);

// Parses and validates a file image: magic, version, flags, every size against the byte count, the
// checksum, every vertex/node/triangle index, the DAG order (parents precede children, a
// triangle's remover comes after its creator and lists it as a parent) and finite, non-negative
// errors. Never reads outside bytes. Errors: kCorrupt (with the field and offending value),
// kUnsupported (another version).
Result<Mt> deserialize_mt(std::span<const std::uint8_t> bytes);

}  // namespace mtlod::core

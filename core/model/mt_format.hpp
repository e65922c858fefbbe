// The .mt format (core/ARCHITECTURE.md §2.8, layout in core/model/FORMAT.md): serialisation of an Mt to
// and from bytes. Pure: no file access (core/io/mt_file.hpp reads and writes files).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "core/model/mt.hpp"
#include "core/result.hpp"

namespace mtlod::core::model {

// Version 2 is written (a block table: files are mapped and checked block by block); version 1
// (one checksum over the whole file) is still read, whole.
inline constexpr std::uint32_t kMtFormatVersion = 2;
inline constexpr std::size_t kMtHeaderBytes = 256;   // version 2
inline constexpr std::size_t kMtHeaderBytesV1 = 64;  // version 1
inline constexpr std::size_t kMtBlockEntryBytes = 16;

// 64-bit checksum over bytes: FNV-1a style mixing of little-endian 8-byte words, then the tail
// bytes. Any change to a single word changes the result (each step is a bijection of the state).
std::uint64_t mt_checksum(std::span<const std::uint8_t> bytes, std::uint64_t seed = 0xcbf29ce484222325ull);

// What an .mt header states; enough to lay the file out before its arrays exist, for writers that
// stream them (core/build/large_build.cpp).
struct MtCounts {
  bool normals = false;
  bool colors = false;
  std::uint32_t vertices = 0;
  std::uint32_t nodes = 0;
  std::uint32_t triangles = 0;
  std::uint32_t root_triangles = 0;
  std::uint32_t parents = 0;
  // Vertices of the root mesh: node n ≥ 1's split vertex is root_vertices + n − 1 (version 2
  // requires vertices numbered in node order).
  std::uint32_t root_vertices = 0;
};
// Byte offset of each array in a version-2 file (core/model/FORMAT.md, "Payload"), of the block table
// after them, and the file size.
struct MtLayout {
  std::uint64_t positions, normals, colors, node_vertex, node_error, node_triangle_offsets,
      node_parent_offsets, node_parents, triangle_corners, root_first_corner, triangle_remover, block_table,
      end;
};
MtLayout mt_layout(const MtCounts& counts);
// The counts of an MT in memory (root_vertices as node order numbers them).
MtCounts mt_counts(const Mt& mt);
// Node blocks of kMtBlockNodes nodes (the last one shorter).
std::uint32_t mt_block_count(std::uint32_t nodes);

// Reads out.size() bytes at a file offset (from a buffer, or with pread).
using MtReadAt = std::function<Status(std::uint64_t offset, std::span<std::uint8_t> out)>;
// The header and block table of a version-2 file whose arrays are in place at mt_layout(counts)'s
// offsets, read back through read_at: each block's first triangle and parent and its checksum, and
// the bounds of the positions. Writers put them at offset 0 and at layout.block_table.
struct MtSeal {
  std::vector<std::uint8_t> header;
  std::vector<std::uint8_t> block_table;
};
Result<MtSeal> seal_mt(const MtCounts& counts, const MtReadAt& read_at);

// Appends the file image of mt to out (cleared first). mt must be valid (as build_mt makes it).
// Version 2 when its vertices are in node order, else version 1.
void serialize_mt(const Mt& mt, std::vector<std::uint8_t>& out);

// Parses and validates a whole file image into memory: magic, version, flags, every size against
// the byte count, the checksums, every vertex/node/triangle index, the DAG order (parents precede
// children, a triangle's remover comes after its creator and lists it as a parent) and finite,
// non-negative errors. Never reads outside bytes. Errors: kCorrupt (with the field and offending
// value), kUnsupported (another version).
Result<Mt> deserialize_mt(std::span<const std::uint8_t> bytes);

// The counts an image's header states, when the header is well formed and the image as long as
// they say (its checksums are not checked: for tests and tools that reseal an altered image).
Result<MtCounts> mt_header_counts(std::span<const std::uint8_t> bytes);

// The version an image's header states (0: too short or not an MT file).
std::uint32_t mt_file_version(std::span<const std::uint8_t> bytes);

// A version-2 image used in place (4-byte aligned, as a memory map is), kept alive by `storage`:
// checks the header, the block table, the size and the root's block now, every other node block
// when a refinement first reaches it (Mt::require_node, Mt::check_node). Errors as deserialize_mt's;
// kUnsupported for version 1, which is read whole.
Result<Mt> view_mt(std::span<const std::uint8_t> bytes, std::shared_ptr<const void> storage);

}  // namespace mtlod::core::model

// meshoptimizer's index buffer codec, version 1 (the TRIANGLES mode of EXT_meshopt_compression), written
// here instead of calling meshopt_encodeIndexBuffer, which took 40 % of a meshopt payload's encoding
// time (1.9 of 4.8 ms for a 50k-triangle cut with normals), mostly in its FIFO searches. The bytes are the
// library's, so meshopt_decodeIndexBuffer and glTF clients read them as before; the stream's layout is
// meshoptimizer's (src/indexcodec.cpp, after Giesen's and Stokes's FIFO codecs):
//   0xe1, then one code byte per triangle, then the triangles' extra bytes in order (a code-aux byte
//   and zigzag varint deltas of indices seen for the first time), then meshoptimizer's fixed 16-byte
//   code-aux table, which the decoder reads and which pads the stream for it.
// A triangle that shares an edge with one of the last 15 edges pushed is stored by that edge (its
// third corner by its age in a 16-vertex FIFO, as the next new vertex, or as a delta); any other
// triangle by its three corners.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace mtlod::core::codec {

// The first byte of a version-1 index stream (meshoptimizer's 0xe0 | version).
inline constexpr std::uint8_t kIndexStreamV1Header = 0xe1;

// The most bytes encode_index_stream_v1 writes for `index_count` indices (a multiple of 3) below
// `vertex_count`: meshopt_encodeIndexBufferBound's value (a code byte, a code-aux byte and three
// varints a triangle, plus the header and the table).
std::size_t index_stream_bound(std::size_t index_count, std::size_t vertex_count);

// Encodes the triangle list `indices` (three a triangle, any 32-bit values; empty is fine) into `out`
// and returns the bytes written: byte for byte what meshopt_encodeIndexBuffer writes after
// meshopt_encodeIndexVersion(1), decoding to the same triangles, some starting at another corner
// (same winding). Returns 0 when `out` is smaller than the stream (exactly when the library fails);
// index_stream_bound bytes always suffice. `out`'s bytes past the returned size, or all of them on
// failure, are unspecified; nothing past its end is written. Allocates nothing.
std::size_t encode_index_stream_v1(std::span<const std::uint32_t> indices, std::span<std::uint8_t> out);

// The same without SSE2, as builds without it run encode_index_stream_v1: for tests.
std::size_t encode_index_stream_v1_portable(std::span<const std::uint32_t> indices,
                                            std::span<std::uint8_t> out);

}  // namespace mtlod::core::codec

// meshoptimizer's vertex buffer codec, version 0 (the ATTRIBUTES mode of EXT_meshopt_compression), and
// its octahedral normal filter, written here instead of calling meshopt_encodeVertexBuffer and
// meshopt_encodeFilterOct, which took 28 % of a meshopt payload's encoding time on a 50k-triangle cut.
// The bytes are the library's (0.18), so meshopt_decodeVertexBuffer and glTF clients read them as
// before; the stream's layout is meshoptimizer's (src/vertexcodec.cpp):
//   0xa0, then the vertices in blocks of min(256, 8192 / stride rounded down to 16) vertices, then a
//   tail of max(32, stride) bytes: zeros, then the first vertex (the decoder's initial "previous
//   vertex", and padding that lets it read a group's 24 bytes unchecked).
// A block holds its vertices byte by byte: for each of the stride's bytes in turn, that byte's
// difference from the previous vertex's (zigzagged: small steps either way are small numbers) for
// each vertex of the block, padded with zeros to groups of 16. Those groups follow a header of 2 bits
// each (four to a byte, the first group in the low bits), which gives the group's encoding:
//   0  all 16 values are 0, and nothing is stored;
//   1  2 bits a value, four to a byte with the first in the high bits, 3 meaning "in the next bytes";
//   2  4 bits a value, two to a byte likewise, 15 meaning "in the next bytes";
//   3  the 16 bytes as they are.
// The values that do not fit (3 or more, 15 or more) follow the packed bits in order. The encoder
// picks the shortest encoding, the fewest bits on a tie (meshoptimizer's order of trial).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace mtlod::core::codec {

// The first byte of a version-0 vertex stream (meshoptimizer's 0xa0 | version).
inline constexpr std::uint8_t kVertexStreamV0Header = 0xa0;

// The most bytes encode_vertex_stream_v0 writes for `count` vertices of `stride` bytes (a multiple of
// 4, at most 256): meshopt_encodeVertexBufferBound's value (every group stored as 16 bytes, every
// block full, plus the header byte and the tail).
std::size_t vertex_stream_bound(std::size_t count, std::size_t stride);

// Encodes `count` vertices of `stride` bytes each (a multiple of 4, at most 256), packed one after
// another from `vertices` (which may be null when `count` is 0), into `out` and returns the bytes
// written: byte for byte what meshopt_encodeVertexBuffer writes after meshopt_encodeVertexVersion(0).
// Returns 0 when `out` is smaller than the stream, exactly when the library fails: its checks (room
// for 1 + stride bytes first, for 24 bytes before each group, for the tail at the end) fail only
// then, since the tail of 32 bytes or more follows every group. vertex_stream_bound bytes always
// suffice. `out`'s bytes past the returned size, or all of them on failure, are unspecified; nothing
// past its end is written. Allocates nothing.
std::size_t encode_vertex_stream_v0(const void* vertices, std::size_t count, std::size_t stride,
                                    std::span<std::uint8_t> out);

// The same without SSE2, as builds without it run encode_vertex_stream_v0: for tests.
std::size_t encode_vertex_stream_v0_portable(const void* vertices, std::size_t count, std::size_t stride,
                                             std::span<std::uint8_t> out);

// meshopt_encodeFilterOct: `count` vectors of four floats from `data` (x, y, z, w) to four signed
// integers each at `destination`, 8-bit when `stride` is 4 and 16-bit when it is 8 (little-endian):
// x, y, z as their octahedral projection's u and v in `bits` bits (1..16, at most 8 for stride 4)
// and the constant 2^(bits − 1) − 1 (the decoder's scale), and w in all of the lane's bits. Byte for
// byte the library's, including for zero, non-unit and non-finite input.
void encode_filter_oct(void* destination, std::size_t count, std::size_t stride, int bits, const float* data);

// The same on normals gathered from a model: entry i is the normal at 3 · ids[i] in `normals` (three
// floats a vertex) with w = 0, as encode_filter_oct of that gathered copy would write them, without
// the copy. Writes ids.size() entries; every id must be below normals.size() / 3.
void encode_filter_oct(void* destination, std::size_t stride, int bits, std::span<const float> normals,
                       std::span<const std::uint32_t> ids);

// Both filters without SSE2, as builds without it run them: for tests.
void encode_filter_oct_portable(void* destination, std::size_t count, std::size_t stride, int bits,
                                const float* data);
void encode_filter_oct_portable(void* destination, std::size_t stride, int bits,
                                std::span<const float> normals, std::span<const std::uint32_t> ids);

}  // namespace mtlod::core::codec

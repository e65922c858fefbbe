// Our version-0 vertex streams and octahedral filter (core/codec/vertex_encode.hpp) are meshoptimizer's
// byte for byte: on hand-made groups whose encodings are worked out below, and against
// meshopt_encodeVertexBuffer (after meshopt_encodeVertexVersion(0)) and meshopt_encodeFilterOct on
// random, constant and smooth bytes at every stride and around every group and block boundary, on
// generated meshes and on the dragon's quantized positions, normals and colours. Both code paths
// (SSE2 and portable) give the same bytes, meshopt_decodeVertexBuffer gives the vertices back, and
// the capacity checks fail exactly where the library's do.
#include "core/codec/vertex_encode.hpp"

#include <gtest/gtest.h>
#include <meshoptimizer.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/build/vertex_normals.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mesh_io.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::core {
namespace {

using Bytes = std::vector<std::uint8_t>;

// The strides 0.18 accepts (multiples of 4 up to 256), a sample: ours (4, 8), the other small ones,
// and those whose blocks are shorter than 256 vertices (from 36 on).
constexpr std::size_t kStrides[] = {4, 8, 12, 16, 20, 24, 28, 32, 36, 44, 48, 64, 100, 128, 252, 256};

// A block's vertices at `stride` (the library's rule, restated: 8 KiB in groups of 16, at most 256).
std::size_t block_of(std::size_t stride) {
  return std::min<std::size_t>((8192 / stride) & ~std::size_t{15}, 256);
}

Bytes ours(const Bytes& vertices, std::size_t stride) {
  const std::size_t count = vertices.size() / stride;
  Bytes out(codec::vertex_stream_bound(count, stride));
  out.resize(codec::encode_vertex_stream_v0(vertices.data(), count, stride, out));
  return out;
}

// The code path of builds without SSE2.
Bytes portable(const Bytes& vertices, std::size_t stride) {
  const std::size_t count = vertices.size() / stride;
  Bytes out(codec::vertex_stream_bound(count, stride));
  out.resize(codec::encode_vertex_stream_v0_portable(vertices.data(), count, stride, out));
  return out;
}

Bytes library(const Bytes& vertices, std::size_t stride) {
  meshopt_encodeVertexVersion(0);
  const std::size_t count = vertices.size() / stride;
  Bytes out(meshopt_encodeVertexBufferBound(count, stride));
  out.resize(meshopt_encodeVertexBuffer(out.data(), out.size(), vertices.data(), count, stride));
  return out;
}

void expect_same_bytes(const Bytes& got, const Bytes& expected, const std::string& name) {
  ASSERT_EQ(got.size(), expected.size()) << name;
  const auto differ = std::mismatch(got.begin(), got.end(), expected.begin());
  ASSERT_TRUE(differ.first == got.end())
      << name << ": first difference at byte " << (differ.first - got.begin()) << " of " << got.size();
}

// The checks every case gets: our bytes, from both code paths, are the library's, and its decoder
// reads the vertices back.
void expect_as_library(const Bytes& vertices, std::size_t stride, const std::string& name) {
  ASSERT_EQ(vertices.size() % stride, 0u) << name;
  const Bytes expected = library(vertices, stride);
  ASSERT_GT(expected.size(), 0u) << name;
  const Bytes got = ours(vertices, stride);
  expect_same_bytes(got, expected, name);
  expect_same_bytes(portable(vertices, stride), expected, name + " (portable)");
  Bytes decoded(vertices.size());
  ASSERT_EQ(
      meshopt_decodeVertexBuffer(decoded.data(), vertices.size() / stride, stride, got.data(), got.size()), 0)
      << name;
  EXPECT_TRUE(decoded == vertices) << name << ": decodes to other vertices";
}

// What the block headers of a stream say, counted over all the cases of a test so that it can check
// that each encoding, and escaped values, turned up. Walks the stream as the decoder does.
struct ModeCounts {
  std::array<std::size_t, 4> groups{};
  std::size_t escaped = 0;  // packed values standing for a byte stored after the packed ones

  void add(const Bytes& stream, std::size_t count, std::size_t stride) {
    const std::size_t block = block_of(stride);
    std::size_t at = 1;
    for (std::size_t first = 0; first < count; first += block) {
      const std::size_t groups_here = (std::min(block, count - first) + 15) / 16;
      for (std::size_t k = 0; k < stride; ++k) {
        const std::size_t header = at;
        at += (groups_here + 3) / 4;
        for (std::size_t g = 0; g < groups_here; ++g) {
          const unsigned mode = stream[header + g / 4] >> (2 * (g % 4)) & 3;
          ++groups[mode];
          if (mode == 3) at += 16;
          if (mode != 1 && mode != 2) continue;
          const unsigned bits = mode == 1 ? 2 : 4, escape = (1u << bits) - 1;
          std::size_t here = 0;
          for (std::size_t i = 0; i < 16; ++i)
            here += (stream[at + i * bits / 8] >> (8 - bits - (i * bits) % 8) & escape) == escape;
          at += 16 * bits / 8 + here;
          escaped += here;
        }
      }
    }
  }
};

// Vertex bytes whose column `k` has the zigzagged deltas `zigzagged` (the first of which must be 0:
// the first vertex is its own predecessor), other columns 0, starting from `base`.
Bytes with_deltas(const std::vector<std::uint8_t>& zigzagged, std::size_t stride, std::size_t k,
                  std::uint8_t base) {
  Bytes vertices(zigzagged.size() * stride, 0);
  std::uint8_t value = base;
  for (std::size_t i = 0; i < zigzagged.size(); ++i) {
    const std::uint8_t z = zigzagged[i];
    value = static_cast<std::uint8_t>(value + ((z >> 1) ^ (0u - (z & 1))));
    vertices[i * stride + k] = value;
  }
  return vertices;
}

// The stream the format gives for one block of one group at stride 4 whose column 0 is encoded as
// `column0` (header byte included) and whose other columns are all zero, first vertex `first`.
Bytes stream_of(const Bytes& column0, std::array<std::uint8_t, 4> first) {
  Bytes out = {0xa0};
  out.insert(out.end(), column0.begin(), column0.end());
  out.insert(out.end(), {0x00, 0x00, 0x00});  // columns 1..3: header byte 0 (all zero), no data
  out.insert(out.end(), 28, 0);               // the tail's padding to 32 bytes
  out.insert(out.end(), first.begin(), first.end());
  return out;
}

// ---- Hand-made streams ---------------------------------------------------------------------------

TEST(VertexEncode, EmptyStreamIsHeaderAndTail) {
  // No blocks; the tail is 32 bytes (zeros, the "first vertex" zeros too) or the stride when longer.
  Bytes expected(1 + 32, 0);
  expected[0] = 0xa0;
  for (const std::size_t stride : {4u, 8u, 32u}) {
    Bytes out(codec::vertex_stream_bound(0, stride), 0xcd);
    out.resize(codec::encode_vertex_stream_v0(nullptr, 0, stride, out));
    EXPECT_EQ(out, expected) << "stride " << stride;
    EXPECT_EQ(library({}, stride), expected) << "stride " << stride;
  }
  Bytes out(codec::vertex_stream_bound(0, 64));
  EXPECT_EQ(codec::encode_vertex_stream_v0(nullptr, 0, 64, out), 1u + 64);
  EXPECT_EQ(library({}, 64).size(), 1u + 64);
}

TEST(VertexEncode, HandMadeGroupsGetTheEncodingsTheFormatGives) {
  // Byte 0 counts up by 1: deltas 0 (the first vertex is its own predecessor), then 1, zigzagged 2.
  // All below 3, so 2 bits each, four to a byte, the first value in the high bits: 0b00'10'10'10,
  // then 0b10'10'10'10 three times; the header's 2-bit code for the group is 1.
  Bytes vertices(16 * 4, 0);
  for (std::uint8_t i = 0; i < 16; ++i) vertices[4 * i] = i;
  EXPECT_EQ(ours(vertices, 4), stream_of({0x01, 0x2a, 0xaa, 0xaa, 0xaa}, {0, 0, 0, 0}));
  // Counting down by 1 from 200: delta −1, zigzagged 1.
  for (std::uint8_t i = 0; i < 16; ++i) vertices[4 * i] = static_cast<std::uint8_t>(200 - i);
  EXPECT_EQ(ours(vertices, 4), stream_of({0x01, 0x15, 0x55, 0x55, 0x55}, {200, 0, 0, 0}));
  // Steps of 4 zigzag to 8: 2 bits would take 4 + 15 escaped bytes, 4 bits 8, bytes 16: code 2,
  // 0x08 then 0x88 seven times.
  for (std::uint8_t i = 0; i < 16; ++i) vertices[4 * i] = static_cast<std::uint8_t>(4 * i);
  EXPECT_EQ(ours(vertices, 4),
            stream_of({0x02, 0x08, 0x88, 0x88, 0x88, 0x88, 0x88, 0x88, 0x88}, {0, 0, 0, 0}));
  // Steps of 64 zigzag to 128: 19 or 23 bytes packed, 16 as bytes: code 3 and the values as they are.
  for (std::uint8_t i = 0; i < 16; ++i) vertices[4 * i] = static_cast<std::uint8_t>(64 * i);
  Bytes raw = {0x03, 0};
  raw.insert(raw.end(), 15, 128);
  EXPECT_EQ(ours(vertices, 4), stream_of(raw, {0, 0, 0, 0}));
  // Escapes: values 0, 3, 1, 200, then 0: 2 bits with 3 as "stored after": 0b00'11'01'11, then zeros,
  // then the two escaped values in order (4 + 2 bytes beat 8 + 1 and 16).
  std::vector<std::uint8_t> z(16, 0);
  z[1] = 3, z[2] = 1, z[3] = 200;
  vertices = with_deltas(z, 4, 0, 10);
  EXPECT_EQ(ours(vertices, 4), stream_of({0x01, 0x37, 0x00, 0x00, 0x00, 3, 200}, {10, 0, 0, 0}));
  for (const Bytes& v : {vertices, with_deltas(std::vector<std::uint8_t>(16, 0), 4, 0, 7)})
    expect_as_library(v, 4, "hand-made");
}

TEST(VertexEncode, TiesGoToTheEncodingTriedFirst) {
  // The library tries 8 bits, then 2 and 4, and keeps a later one only when strictly shorter.
  struct Case {
    unsigned at_least_3, at_least_15, mode;
  };
  // 6 and 2 escapes: 10 bytes either way, 2 bits wins. 12 escapes for 2 bits (16 bytes) and 8 for 4
  // (16): bytes win. 11 and 7: 15 either way, 2 bits. 12 and 7: 4 bits (15 < 16).
  const Case cases[] = {{6, 2, 1}, {12, 8, 3}, {11, 7, 1}, {12, 7, 2}, {0, 0, 1}};
  for (const Case& c : cases) {
    std::vector<std::uint8_t> z(16, 1);
    z[0] = 0;
    for (unsigned i = 0; i < c.at_least_3; ++i) z[1 + i] = i < c.at_least_15 ? 40 : 5;
    const Bytes vertices = with_deltas(z, 4, 0, 0);
    const Bytes got = ours(vertices, 4);
    EXPECT_EQ(got[1] & 3, c.mode) << c.at_least_3 << " at least 3, " << c.at_least_15 << " at least 15";
    expect_as_library(vertices, 4, "tie");
  }
}

TEST(VertexEncode, GroupsAndBlocksAreLaidOutPerColumn) {
  // 17 vertices at stride 8: one block of two groups, so each column has a header byte with two codes
  // (the first group's in the low bits) and the second group holds one vertex and 15 zeros. Column 1
  // is constant (both groups code 0); column 0 counts up by 1 (both code 1); the second group of
  // column 0 is a single delta 2 followed by zeros: 0b10'00'00'00, 0, 0, 0.
  Bytes vertices(17 * 8, 0);
  for (std::uint8_t i = 0; i < 17; ++i) vertices[8 * i] = i, vertices[8 * i + 1] = 99;
  const Bytes got = ours(vertices, 8);
  const Bytes column0 = {0x05, 0x2a, 0xaa, 0xaa, 0xaa, 0x80, 0x00, 0x00, 0x00};
  EXPECT_TRUE(std::equal(column0.begin(), column0.end(), got.begin() + 1));
  EXPECT_EQ(got[1 + column0.size()], 0x00);  // column 1
  expect_as_library(vertices, 8, "two groups");
}

// ---- Against the library -------------------------------------------------------------------------

enum class Content { kRandom, kEqual, kSmooth, kMixed, kLarge };

// `count` vertices of `stride` bytes: random bytes, all one byte, slowly varying 16-bit values,
// columns of each kind, or steps near ±128 (zigzagged near 255) that fill the escapes.
Bytes vertices_of(std::mt19937& rng, Content content, std::size_t count, std::size_t stride) {
  Bytes v(count * stride);
  std::uniform_int_distribution<int> byte(0, 255), small(-3, 3), kind(0, 3);
  switch (content) {
    case Content::kRandom:
      for (std::uint8_t& b : v) b = static_cast<std::uint8_t>(byte(rng));
      break;
    case Content::kEqual:
      std::fill(v.begin(), v.end(), static_cast<std::uint8_t>(byte(rng)));
      break;
    case Content::kSmooth:
      for (std::size_t k = 0; k + 1 < stride; k += 2) {
        std::uint16_t value = static_cast<std::uint16_t>(byte(rng) << 8);
        for (std::size_t i = 0; i < count; ++i) {
          value = static_cast<std::uint16_t>(value + small(rng) * (1 + k));
          v[i * stride + k] = static_cast<std::uint8_t>(value), v[i * stride + k + 1] = value >> 8;
        }
      }
      break;
    case Content::kMixed:
      for (std::size_t k = 0; k < stride; ++k) {
        const int how = kind(rng);
        std::uint8_t value = static_cast<std::uint8_t>(byte(rng));
        for (std::size_t i = 0; i < count; ++i) {
          if (how == 0) value = static_cast<std::uint8_t>(byte(rng));
          if (how == 1) value = static_cast<std::uint8_t>(value + small(rng));
          if (how == 2) value = static_cast<std::uint8_t>(value + small(rng) * 3);
          v[i * stride + k] = value;  // how == 3: constant
        }
      }
      break;
    case Content::kLarge:
      for (std::size_t k = 0; k < stride; ++k) {
        std::uint8_t value = 0;
        for (std::size_t i = 0; i < count; ++i)
          v[i * stride + k] = value = static_cast<std::uint8_t>(value + 127 + small(rng));
      }
      break;
  }
  return v;
}

const char* name_of(Content content) {
  switch (content) {
    case Content::kRandom:
      return "random";
    case Content::kEqual:
      return "equal";
    case Content::kSmooth:
      return "smooth";
    case Content::kMixed:
      return "mixed";
    case Content::kLarge:
      return "large steps";
  }
  return "";
}

TEST(VertexEncode, EdgeCountsAndStridesAsLibrary) {
  std::mt19937 rng(20240612);
  ModeCounts modes;
  for (const std::size_t stride : kStrides) {
    const std::size_t block = block_of(stride);
    std::vector<std::size_t> counts = {0, 1, 2, 15, 16, 17, 31, 32, 33, 255, 256, 257};
    // Around the ends of the first and second block (a block of 160 at stride 48 ends mid-header-byte).
    for (const std::size_t at : {block, 2 * block})
      counts.insert(counts.end(), {at - 17, at - 16, at - 15, at - 1, at, at + 1, at + 15, at + 16, at + 17});
    for (const std::size_t count : counts) {
      for (const Content content :
           {Content::kRandom, Content::kEqual, Content::kSmooth, Content::kMixed, Content::kLarge}) {
        const Bytes vertices = vertices_of(rng, content, count, stride);
        const std::string name = std::to_string(count) + " " + name_of(content) + " vertices of " +
                                 std::to_string(stride) + " bytes";
        expect_as_library(vertices, stride, name);
        modes.add(ours(vertices, stride), count, stride);
      }
    }
  }
  for (unsigned mode = 0; mode < 4; ++mode) EXPECT_GT(modes.groups[mode], 0u) << "mode " << mode;
  EXPECT_GT(modes.escaped, 0u);
}

TEST(VertexEncode, LongRandomStreamsAsLibrary) {
  // Many blocks, and the unaligned starts a vertex pointer into a larger buffer has.
  std::mt19937 rng(99);
  for (const std::size_t stride : {4u, 8u, 12u, 16u}) {
    for (const Content content : {Content::kRandom, Content::kSmooth, Content::kMixed}) {
      const Bytes vertices = vertices_of(rng, content, 10'007, stride);
      expect_as_library(vertices, stride,
                        std::string(name_of(content)) + " stride " + std::to_string(stride));
      Bytes shifted(vertices.size() + 3);
      std::memcpy(shifted.data() + 3, vertices.data(), vertices.size());
      const std::size_t count = vertices.size() / stride;
      Bytes out(codec::vertex_stream_bound(count, stride));
      out.resize(codec::encode_vertex_stream_v0(shifted.data() + 3, count, stride, out));
      expect_same_bytes(out, library(vertices, stride), "unaligned");
    }
  }
}

// Quantized u16x4 positions (w = 0) over the bounding box, in the order of `ids`.
Bytes quantized_positions(const std::vector<float>& positions, const std::vector<std::uint32_t>& ids,
                          int bits) {
  std::array<float, 3> lo = {positions[0], positions[1], positions[2]}, hi = lo;
  for (std::size_t i = 0; i < positions.size(); ++i)
    lo[i % 3] = std::min(lo[i % 3], positions[i]), hi[i % 3] = std::max(hi[i % 3], positions[i]);
  const float range = std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
  const float levels = static_cast<float>((1 << bits) - 1);
  Bytes out(8 * ids.size(), 0);
  for (std::size_t i = 0; i < ids.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const float q = (positions[3 * std::size_t{ids[i]} + k] - lo[k]) / range * levels + 0.5f;
      const auto value = static_cast<std::uint16_t>(std::clamp(q, 0.f, levels));
      std::memcpy(&out[8 * i + 2 * k], &value, 2);
    }
  }
  return out;
}

// The vertices in the order the triangles first use them, as the payload numbers them.
std::vector<std::uint32_t> first_use_order(const std::vector<std::uint32_t>& triangles,
                                           std::size_t vertices) {
  std::vector<bool> seen(vertices, false);
  std::vector<std::uint32_t> order;
  for (const std::uint32_t v : triangles)
    if (!seen[v]) seen[v] = true, order.push_back(v);
  return order;
}

Bytes library_filter(const std::vector<float>& normals, const std::vector<std::uint32_t>& ids,
                     std::size_t stride, int bits) {
  std::vector<float> gathered(4 * ids.size(), 0.f);
  for (std::size_t i = 0; i < ids.size(); ++i)
    std::memcpy(&gathered[4 * i], &normals[3 * std::size_t{ids[i]}], 12);
  Bytes out(stride * ids.size());
  meshopt_encodeFilterOct(out.data(), ids.size(), stride, bits, gathered.data());
  return out;
}

// A mesh's streams as a payload has them: positions (16 and 11 bits), normals (8 bits at stride 4,
// 10 and 16 at stride 8) filtered by us and by the library, colours from the normals.
void expect_mesh_as_library(const model::Mesh& mesh, const std::string& name) {
  const std::vector<float> normals =
      mesh.has_normals() ? mesh.normals : build::vertex_normals(mesh.positions, mesh.triangles);
  std::vector<std::uint32_t> file_order(mesh.vertex_count());
  for (std::size_t i = 0; i < file_order.size(); ++i) file_order[i] = static_cast<std::uint32_t>(i);
  const std::vector<std::uint32_t> used = first_use_order(mesh.triangles, mesh.vertex_count());
  ModeCounts modes;
  for (const std::vector<std::uint32_t>* ids :
       std::array<const std::vector<std::uint32_t>*, 2>{&file_order, &used}) {
    const std::string order = ids == &used ? " by first use" : " in file order";
    for (const int bits : {16, 11}) {
      const Bytes positions = quantized_positions(mesh.positions, *ids, bits);
      expect_as_library(positions, 8, name + " positions, " + std::to_string(bits) + " bits" + order);
      modes.add(ours(positions, 8), ids->size(), 8);
    }
    for (const auto& [stride, bits] : {std::pair<std::size_t, int>{4, 8}, {8, 10}, {8, 16}}) {
      const std::string what = name + " normals, " + std::to_string(bits) + " bits" + order;
      Bytes filtered(stride * ids->size());
      codec::encode_filter_oct(filtered.data(), stride, bits, normals, *ids);
      expect_same_bytes(filtered, library_filter(normals, *ids, stride, bits), what + " (filter)");
      expect_as_library(filtered, stride, what);
      modes.add(ours(filtered, stride), ids->size(), stride);
    }
    Bytes colours(4 * ids->size());
    for (std::size_t i = 0; i < ids->size(); ++i) {
      for (int k = 0; k < 3; ++k)
        colours[4 * i + k] =
            static_cast<std::uint8_t>(127.5f + 127.f * normals[3 * std::size_t{(*ids)[i]} + k]);
      colours[4 * i + 3] = 255;
    }
    expect_as_library(colours, 4, name + " colours" + order);
  }
  // Real data uses every encoding.
  for (unsigned mode = 0; mode < 4; ++mode) EXPECT_GT(modes.groups[mode], 0u) << name << ": mode " << mode;
}

TEST(VertexEncode, GeneratedMeshesAsLibrary) {
  for (const eval::Shape shape : {eval::Shape::kSphere, eval::Shape::kTerrain, eval::Shape::kShell}) {
    eval::GenerateOptions options;
    options.shape = shape;
    options.target_triangles = 20'000;
    expect_mesh_as_library(eval::generate_mesh(options), "shape " + std::to_string(static_cast<int>(shape)));
  }
}

TEST(VertexEncode, DragonAsLibrary) {
  std::filesystem::path path = test::models_dir() / "dragon-871k.ply";
  if (!std::filesystem::exists(path)) path = test::shared_meshes_dir() / "dragon-vrip-871k.ply";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "no dragon at " << path;
  io::LoadOptions load;
  load.clean = false;
  auto loaded = io::load_mesh(path, load);
  ASSERT_TRUE(loaded.ok());
  expect_mesh_as_library(loaded->mesh, "dragon");
}

// ---- Capacity --------------------------------------------------------------------------------------

TEST(VertexEncode, BoundIsTheLibrarys) {
  for (const std::size_t stride : kStrides)
    for (const std::size_t count : {0u, 1u, 16u, 255u, 256u, 257u, 1000u, 100'000u})
      EXPECT_EQ(codec::vertex_stream_bound(count, stride), meshopt_encodeVertexBufferBound(count, stride))
          << count << " vertices of " << stride << " bytes";
}

TEST(VertexEncode, TooSmallCapacityReturnsZeroWhereTheLibraryDoes) {
  std::mt19937 rng(5);
  struct Case {
    Content content;
    std::size_t count, stride;
  };
  const Case cases[] = {{Content::kEqual, 0, 4},    {Content::kEqual, 0, 64},   {Content::kEqual, 5, 4},
                        {Content::kSmooth, 300, 8}, {Content::kRandom, 40, 4},  {Content::kMixed, 600, 12},
                        {Content::kEqual, 20, 48},  {Content::kSmooth, 33, 256}};
  for (const Case& c : cases) {
    const Bytes vertices = vertices_of(rng, c.content, c.count, c.stride);
    const std::size_t size = library(vertices, c.stride).size();
    // Both fail exactly below the stream's size: the room a group needs (24 bytes) and the tail (32
    // or more) always follow within the stream. Bytes past the capacity stay untouched.
    for (std::size_t capacity = 0; capacity <= size + 1; ++capacity) {
      if (capacity + 60 < size && capacity % 11 != 0) continue;  // a sample far from the size
      Bytes ours_out(capacity + 32, 0xcd), portable_out(capacity + 32, 0xcd), library_out(capacity);
      const std::string where = std::to_string(c.count) + " vertices of " + std::to_string(c.stride) +
                                " bytes, capacity " + std::to_string(capacity);
      const std::size_t got = codec::encode_vertex_stream_v0(
          vertices.data(), c.count, c.stride, std::span<std::uint8_t>(ours_out.data(), capacity));
      EXPECT_EQ(
          codec::encode_vertex_stream_v0_portable(vertices.data(), c.count, c.stride,
                                                  std::span<std::uint8_t>(portable_out.data(), capacity)),
          got)
          << where;
      meshopt_encodeVertexVersion(0);
      const std::size_t expected =
          meshopt_encodeVertexBuffer(library_out.data(), capacity, vertices.data(), c.count, c.stride);
      EXPECT_EQ(got, expected) << where;
      EXPECT_EQ(got, capacity < size ? 0 : size) << where;
      for (const Bytes* written : {&ours_out, &portable_out})
        EXPECT_TRUE(std::all_of(written->begin() + capacity, written->end(),
                                [](std::uint8_t b) { return b == 0xcd; }))
            << "wrote past " << where;
    }
  }
}

// ---- Octahedral filter -----------------------------------------------------------------------------

TEST(VertexEncode, FilterOctHandMadeVectors) {
  // Upper half: u, v are x, y over |x| + |y| + |z|; the third lane is 2^(bits − 1) − 1, the fourth w.
  // +z: (0, 0); +x: (1, 0) → 127; (1, 1, 0)/2: (0.5, 0.5) → 63.5 + 0.5 → 64. Lower half (z < 0)
  // folds: −z → (1 − 0)·sign(0 ≥ 0 → +1) for both, 127. The zero vector scales by 0: (0, 0).
  const float data[] = {0, 0, 1, 0, 1, 0, 0, 0, 1, 1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 0, 0, 0, 1, -1};
  const Bytes expected = {0,   0,   127, 0, 127, 0, 127, 0, 64, 64, 127, 0,
                          127, 127, 127, 0, 0,   0, 127, 0, 0,  0,  127, 0x81};
  Bytes got(expected.size()), lib(expected.size());
  codec::encode_filter_oct(got.data(), 6, 4, 8, data);
  meshopt_encodeFilterOct(lib.data(), 6, 4, 8, data);
  EXPECT_EQ(got, expected);
  EXPECT_EQ(lib, expected);
}

// Vectors of four floats: random directions, random lengths and signs, and the awkward values
// (zeros of both signs, infinities, NaN, denormals, huge and tiny, exact axes and diagonals).
std::vector<float> filter_inputs(std::mt19937& rng, std::size_t count) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const float awkward[] = {0.f,   -0.f, 1.f,  -1.f, 0.5f,  -0.5f, 1e-40f,     -1e-40f,     1e30f,   -1e30f,
                           3e38f, inf,  -inf, nan,  1e-7f, 2.f,   0.7071068f, -0.7071068f, 0.57735f};
  std::normal_distribution<float> gauss;
  std::uniform_real_distribution<float> unit(-1.5f, 1.5f);
  std::uniform_int_distribution<int> pick(0, std::size(awkward) - 1), kind(0, 9);
  std::vector<float> out(4 * count);
  for (std::size_t i = 0; i < count; ++i) {
    float* n = &out[4 * i];
    const int how = kind(rng);
    if (how < 5) {
      n[0] = gauss(rng), n[1] = gauss(rng), n[2] = gauss(rng);
      const float length = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      for (int k = 0; k < 3; ++k) n[k] /= length;
      n[3] = 0;
    } else if (how < 8) {
      for (int k = 0; k < 4; ++k) n[k] = unit(rng);
    } else {
      for (int k = 0; k < 4; ++k) n[k] = kind(rng) < 5 ? awkward[pick(rng)] : unit(rng);
    }
  }
  return out;
}

TEST(VertexEncode, FilterOctAsLibrary) {
  std::mt19937 rng(11);
  for (const std::size_t count : {0u, 1u, 3u, 4u, 5u, 7u, 1000u, 20'001u}) {
    const std::vector<float> data = filter_inputs(rng, count);
    for (const std::size_t stride : {4u, 8u}) {
      for (int bits = 1; bits <= 16; ++bits) {
        Bytes expected(stride * count), got(stride * count + 16, 0xcd), plain(stride * count);
        meshopt_encodeFilterOct(expected.data(), count, stride, bits, data.data());
        codec::encode_filter_oct(got.data(), count, stride, bits, data.data());
        codec::encode_filter_oct_portable(plain.data(), count, stride, bits, data.data());
        const std::string name = std::to_string(count) + " vectors, stride " + std::to_string(stride) + ", " +
                                 std::to_string(bits) + " bits";
        EXPECT_TRUE(std::all_of(got.end() - 16, got.end(), [](std::uint8_t b) { return b == 0xcd; })) << name;
        got.resize(stride * count);
        expect_same_bytes(got, expected, name);
        expect_same_bytes(plain, expected, name + " (portable)");
      }
    }
  }
}

TEST(VertexEncode, FilterOctFromIdsAsLibraryOnTheGatheredCopy) {
  std::mt19937 rng(12);
  // Three floats a model vertex; the ids repeat, skip and include the last vertex (whose normal ends
  // the array: nothing past it may be read).
  const std::size_t model_vertices = 5000;
  const std::vector<float> four = filter_inputs(rng, model_vertices);
  std::vector<float> normals(3 * model_vertices);
  for (std::size_t v = 0; v < model_vertices; ++v) std::memcpy(&normals[3 * v], &four[4 * v], 12);
  std::uniform_int_distribution<std::uint32_t> any(0, model_vertices - 1);
  for (const std::size_t count : {0u, 1u, 2u, 4u, 6u, 999u, 3001u}) {
    std::vector<std::uint32_t> ids(count);
    for (std::uint32_t& id : ids) id = any(rng);
    if (count > 0) ids.back() = model_vertices - 1;
    if (count > 2) ids[1] = model_vertices - 1;
    for (const auto& [stride, bits] : {std::pair<std::size_t, int>{4, 8}, {4, 5}, {8, 10}, {8, 16}, {8, 2}}) {
      Bytes got(stride * count), plain(stride * count);
      codec::encode_filter_oct(got.data(), stride, bits, normals, ids);
      codec::encode_filter_oct_portable(plain.data(), stride, bits, normals, ids);
      const std::string name = std::to_string(count) + " ids, stride " + std::to_string(stride);
      expect_same_bytes(got, library_filter(normals, ids, stride, bits), name);
      expect_same_bytes(plain, got, name + " (portable)");
    }
  }
}

}  // namespace
}  // namespace mtlod::core

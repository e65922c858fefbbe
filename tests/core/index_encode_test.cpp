// Our version-1 index streams (core/codec/index_encode.hpp) are meshoptimizer's byte for byte: on
// hand-made triangles whose codes are worked out below, and against meshopt_encodeIndexBuffer itself
// (after meshopt_encodeIndexVersion(1)) on random soups, grids and strips, vertex-cache-ordered and
// shuffled meshes, so that every code the format has turns up. meshopt_decodeIndexBuffer gives the
// triangles back (starting at another corner at most), and the capacity checks fail exactly where the
// library's do.
#include "core/codec/index_encode.hpp"

#include <gtest/gtest.h>
#include <meshoptimizer.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "core/eval/mesh_gen.hpp"

namespace mtlod::core {
namespace {

using Bytes = std::vector<std::uint8_t>;
using Indices = std::vector<std::uint32_t>;

// The library's code-aux table, which ends every stream.
constexpr std::array<std::uint8_t, 16> kTable = {0x00, 0x76, 0x87, 0x56, 0x67, 0x78, 0xa9, 0x86,
                                                 0x65, 0x89, 0x68, 0x98, 0x01, 0x69, 0,    0};

std::size_t vertex_count_of(const Indices& indices) {
  return indices.empty() ? 0 : std::size_t{*std::max_element(indices.begin(), indices.end())} + 1;
}

Bytes ours(const Indices& indices) {
  Bytes out(codec::index_stream_bound(indices.size(), vertex_count_of(indices)));
  out.resize(codec::encode_index_stream_v1(indices, out));
  return out;
}

// The code path of builds without SSE2.
Bytes portable(const Indices& indices) {
  Bytes out(codec::index_stream_bound(indices.size(), vertex_count_of(indices)));
  out.resize(codec::encode_index_stream_v1_portable(indices, out));
  return out;
}

Bytes library(const Indices& indices) {
  meshopt_encodeIndexVersion(1);
  Bytes out(meshopt_encodeIndexBufferBound(indices.size(), vertex_count_of(indices)));
  out.resize(meshopt_encodeIndexBuffer(out.data(), out.size(), indices.data(), indices.size()));
  return out;
}

// Triangle t of `decoded` is triangle t of `original` started at any corner (same winding).
void expect_same_up_to_rotation(const Indices& decoded, const Indices& original, const std::string& name) {
  ASSERT_EQ(decoded.size(), original.size()) << name;
  for (std::size_t t = 0; t < original.size() / 3; ++t) {
    const std::uint32_t* d = &decoded[3 * t];
    const std::uint32_t* o = &original[3 * t];
    bool same = false;
    for (int r = 0; r < 3; ++r) same |= d[0] == o[r] && d[1] == o[(r + 1) % 3] && d[2] == o[(r + 2) % 3];
    ASSERT_TRUE(same) << name << ": triangle " << t << " decodes to " << d[0] << " " << d[1] << " " << d[2]
                      << " from " << o[0] << " " << o[1] << " " << o[2];
  }
}

void expect_same_bytes(const Bytes& got, const Bytes& expected, const std::string& name) {
  ASSERT_EQ(got.size(), expected.size()) << name;
  const auto differ = std::mismatch(got.begin(), got.end(), expected.begin());
  ASSERT_TRUE(differ.first == got.end())
      << name << ": first difference at byte " << (differ.first - got.begin()) << " of " << got.size();
}

// The checks every case gets: our bytes, from both code paths, are the library's, and its decoder
// reads them back.
void expect_as_library(const Indices& indices, const std::string& name) {
  const Bytes expected = library(indices);
  ASSERT_GT(expected.size(), 0u) << name;
  const Bytes got = ours(indices);
  expect_same_bytes(got, expected, name);
  expect_same_bytes(portable(indices), expected, name + " (portable)");
  Indices decoded(indices.size());
  ASSERT_EQ(meshopt_decodeIndexBuffer(decoded.data(), decoded.size(), 4, got.data(), got.size()), 0) << name;
  expect_same_up_to_rotation(decoded, indices, name);
}

// What the code bytes of a stream say, counted over all the cases of a test so that it can check
// that each kind turned up: a triangle found by an edge names its third corner by vertex age (1..12),
// as the new vertex (0), as the last free index − 1 or + 1 (13, 14) or stored (15); one stored by
// its corners is 0xf0..0xfd (code-aux table), 0xfe (first corner new) or 0xff (stored).
struct CodeKinds {
  std::array<std::size_t, 16> edge_third{};  // by the low nibble
  std::size_t table = 0, aux_new = 0, aux_stored = 0;

  void add(const Bytes& stream, std::size_t triangles) {
    for (std::size_t t = 0; t < triangles; ++t) {
      const std::uint8_t code = stream[1 + t];
      if (code < 0xf0)
        ++edge_third[code & 15];
      else if (code < 0xfe)
        ++table;
      else if (code == 0xfe)
        ++aux_new;
      else
        ++aux_stored;
    }
  }
};

// ---- Hand-made streams ---------------------------------------------------------------------------

Bytes stream_of(std::initializer_list<std::uint8_t> head) {
  Bytes out = head;
  out.insert(out.end(), kTable.begin(), kTable.end());
  return out;
}

TEST(IndexEncode, EmptyListIsHeaderAndTable) {
  EXPECT_EQ(ours({}), stream_of({0xe1}));
  EXPECT_EQ(library({}), stream_of({0xe1}));
}

TEST(IndexEncode, HandMadeTrianglesGetTheCodesTheFormatGives) {
  // (0, 1, 2): three new vertices in order, each the expected one: (b, c) codes (0, 0) are table
  // entry 0, so the triangle is code 0xf0 and nothing else.
  EXPECT_EQ(ours({0, 1, 2}), stream_of({0xe1, 0xf0}));
  // (2, 1, 3) then shares edge 2→1, pushed second of the first triangle's three (1→0, 2→1, 0→2): age
  // 1. Its third corner 3 is the expected new vertex: code 0x10.
  EXPECT_EQ(ours({0, 1, 2, 2, 1, 3}), stream_of({0xe1, 0xf0, 0x10}));
  // (5, 7, 6): no edge, no expected vertex (next is 0), so it starts at corner 0 and stores all three
  // (0xff, code-aux 0xff) as zigzag deltas from the last stored index: +5 → 10, +2 → 4, −1 → 1.
  EXPECT_EQ(ours({5, 7, 6}), stream_of({0xe1, 0xff, 0xff, 10, 4, 1}));
  // (1, 2, 0): the expected vertex 0 is corner 2, so it is coded as (0, 1, 2): 0xf0 again.
  EXPECT_EQ(ours({1, 2, 0}), stream_of({0xe1, 0xf0}));
  // (0, 1, 2) twice: the second shares no edge in its direction (the FIFO holds 1→0, 2→1, 0→2), and
  // (0, 1, 2) once the numbering has started is the restart code, 0xfe with code-aux 0.
  EXPECT_EQ(ours({0, 1, 2, 0, 1, 2}), stream_of({0xe1, 0xf0, 0xfe, 0x00}));
  // (2, 1, 0) starts at the expected vertex 0: (0, 2, 1). 0 is new; 2 is not the expected 1, so it
  // is stored (+2 → 4), and 1 is then expected: (b, c) codes (15, 0), 0xf0, not in the table, so
  // code 0xfe and the code-aux byte. Again (2, 1, 0): none of its edges runs as one pushed (2→0,
  // 1→2, 0→1); 2 is the expected vertex now, 1 and 0 are in the vertex FIFO at ages 0 and 2, named
  // 1 and 3: code 0xfe, code-aux 0x13.
  EXPECT_EQ(ours({2, 1, 0, 2, 1, 0}), stream_of({0xe1, 0xfe, 0xfe, 0xf0, 0x04, 0x13}));
  for (const Indices& indices : {Indices{0, 1, 2}, Indices{0, 1, 2, 2, 1, 3}, Indices{5, 7, 6},
                                 Indices{1, 2, 0}, Indices{0, 1, 2, 0, 1, 2}, Indices{2, 1, 0, 2, 1, 0}})
    expect_as_library(indices, "hand-made");
}

TEST(IndexEncode, LargestIndexMatchesUnusedFifoSlots) {
  // Unused FIFO slots hold 0xffffffff in the library, so a triangle on that vertex can find an edge
  // (0xffffffff, 0xffffffff) that was never pushed. (7, top, top) finds it at age 0 (the newest
  // slot) started at corner 1; its third corner 7 is stored: +7 → 14. (top, top, top) finds it
  // started at corner 0; its third corner is in every slot of the vertex FIFO, but age 0 has no
  // code, and it is not the expected vertex 0 but the last stored index 0 − 1 (wrapping): 0x0d.
  const std::uint32_t top = 0xffffffff;
  EXPECT_EQ(ours({7, top, top}), stream_of({0xe1, 0x0f, 0x0e}));
  EXPECT_EQ(ours({top, top, top}), stream_of({0xe1, 0x0d}));
  for (const Indices& indices :
       {Indices{7, top, top}, Indices{top, top, top}, Indices{top, 0, 1, top - 1, top, 0, 1, top, top}})
    expect_as_library(indices, "largest index");
}

TEST(IndexEncode, IndicesAroundTheNarrowLanesLimit) {
  // Below 0xffff the FIFOs' lanes are 16 bits wide and 0xffff marks unused entries; from 0xffff on
  // they are 32 bits wide. Triangles up to the last narrow index, up to 0xffff itself (which must
  // not match unused entries, as 0xffffffff does), and past it.
  for (const std::uint32_t top : {0xfffeu, 0xffffu, 0x10000u, 0x1fffeu}) {
    const Indices indices = {top, top - 1, top - 2, top - 2, top - 1, top, top, top,
                             top, 0,       top,     1,       top - 1, top, 2};
    expect_as_library(indices, "up to " + std::to_string(top));
    Indices strip_down;
    for (std::uint32_t i = 0; i < 40; ++i)
      strip_down.insert(strip_down.end(), {top - i, top - i - 1, top - i - 2});
    expect_as_library(strip_down, "strip down from " + std::to_string(top));
  }
}

// ---- Against the library -------------------------------------------------------------------------

// `triangles` triangles whose corners are drawn near a point that wanders over `range` vertices
// (spread 0: anywhere in it), from `base` on, a share of them degenerate (a corner repeated).
Indices soup(std::mt19937& rng, std::size_t triangles, std::uint32_t base, std::uint32_t range,
             std::uint32_t spread, double degenerate) {
  Indices out;
  std::uniform_int_distribution<std::uint32_t> anywhere(0, range - 1);
  std::uniform_real_distribution<double> unit(0, 1);
  std::uint32_t centre = anywhere(rng);
  for (std::size_t t = 0; t < triangles; ++t) {
    if (spread > 0 && unit(rng) < 0.05) centre = anywhere(rng);
    std::array<std::uint32_t, 3> c;
    for (std::uint32_t& v : c) {
      const std::uint32_t offset =
          spread > 0 ? std::uniform_int_distribution<std::uint32_t>(0, spread)(rng) : 0;
      v = spread > 0 ? (centre + offset) % range : anywhere(rng);
    }
    if (unit(rng) < degenerate) c[std::uniform_int_distribution<int>(0, 2)(rng)] = c[(t + 1) % 3];
    for (const std::uint32_t v : c) out.push_back(base + v);
  }
  return out;
}

TEST(IndexEncode, RandomSoupsAsLibrary) {
  std::mt19937 rng(20240611);
  CodeKinds kinds;
  const std::size_t sizes[] = {0, 1, 2, 3, 5, 16, 17, 100, 1'000, 20'000};
  struct Range {
    std::uint32_t base, range, spread;
  };
  // Tiny ranges make many equal edges (several rotations and entries match at once); wide ones
  // store most corners; the last reach the top of the 32-bit range, past 2^28 (5-byte varints).
  const Range ranges[] = {{0, 3, 0},
                          {0, 8, 0},
                          {0, 40, 6},
                          {0, 1000, 12},
                          {0, 100'000, 0},
                          {0, 100'000, 20},
                          {0xfffff000, 4096, 10},
                          {0, 0xffffffff, 0},
                          {0xffffff00, 256, 0}};
  for (const std::size_t n : sizes) {
    for (const Range& r : ranges) {
      for (const double degenerate : {0.0, 0.2}) {
        const Indices indices = soup(rng, n, r.base, r.range, r.spread, degenerate);
        const std::string name = "soup of " + std::to_string(n) + " over " + std::to_string(r.range) +
                                 " from " + std::to_string(r.base) + " spread " + std::to_string(r.spread) +
                                 (degenerate > 0 ? " with degenerate" : "");
        expect_as_library(indices, name);
        kinds.add(ours(indices), n);
      }
    }
  }
  EXPECT_GT(kinds.edge_third[15], 0u);
  EXPECT_GT(kinds.aux_stored, 0u);
}

// A w × h grid of quads, two triangles each, row by row; serpentine runs every other row backwards.
// Vertex (x, y) is id(x, y), by default y · (w + 1) + x.
template <class Id>
Indices grid(std::uint32_t w, std::uint32_t h, bool serpentine, Id id) {
  Indices out;
  for (std::uint32_t y = 0; y < h; ++y) {
    for (std::uint32_t i = 0; i < w; ++i) {
      const std::uint32_t x = serpentine && y % 2 == 1 ? w - 1 - i : i;
      const std::uint32_t a = id(x, y), b = id(x + 1, y), c = id(x, y + 1), d = id(x + 1, y + 1);
      out.insert(out.end(), {a, b, d, a, d, c});
    }
  }
  return out;
}

// A triangle strip over `count` + 2 vertices as a list, winding kept.
Indices strip(std::uint32_t count, std::uint32_t first) {
  Indices out;
  for (std::uint32_t i = 0; i < count; ++i) {
    if (i % 2 == 0)
      out.insert(out.end(), {first + i, first + i + 1, first + i + 2});
    else
      out.insert(out.end(), {first + i + 1, first + i, first + i + 2});
  }
  return out;
}

// Numbered by first use, as meshopt_optimizeVertexFetch (and our encoder) would.
Indices by_first_use(const Indices& indices) {
  const std::size_t n = vertex_count_of(indices);
  std::vector<std::uint32_t> remap(n);
  meshopt_optimizeVertexFetchRemap(remap.data(), indices.data(), indices.size(), n);
  Indices out(indices.size());
  meshopt_remapIndexBuffer(out.data(), indices.data(), indices.size(), remap.data());
  return out;
}

TEST(IndexEncode, GridsAndStripsAsLibrary) {
  CodeKinds kinds;
  std::vector<std::pair<std::string, Indices>> cases;
  const std::pair<std::uint32_t, std::uint32_t> sizes[] = {{1, 1}, {2, 3}, {16, 16}, {100, 40}, {7, 300}};
  for (const auto& size : sizes) {
    const std::uint32_t w = size.first, h = size.second;
    for (const bool serpentine : {false, true}) {
      const std::string shape =
          std::to_string(w) + "x" + std::to_string(h) + (serpentine ? " serpentine" : "");
      const auto row_major = [w](std::uint32_t x, std::uint32_t y) { return y * (w + 1) + x; };
      // Numbered backwards, new corners are not the expected vertex but the last stored one − 1.
      const std::uint32_t n = (w + 1) * (h + 1);
      const auto backwards = [&](std::uint32_t x, std::uint32_t y) { return n - 1 - row_major(x, y); };
      const auto column_major = [h](std::uint32_t x, std::uint32_t y) { return x * (h + 1) + y; };
      const auto at_top = [&](std::uint32_t x, std::uint32_t y) { return 0xffffffff - row_major(x, y); };
      const Indices plain = grid(w, h, serpentine, row_major);
      cases.emplace_back("grid " + shape, plain);
      cases.emplace_back("grid " + shape + " by first use", by_first_use(plain));
      cases.emplace_back("grid " + shape + " numbered backwards", grid(w, h, serpentine, backwards));
      cases.emplace_back("grid " + shape + " by columns", grid(w, h, serpentine, column_major));
      cases.emplace_back("grid " + shape + " at the top of the range", grid(w, h, serpentine, at_top));
    }
  }
  for (const std::uint32_t count : {1u, 2u, 15u, 16u, 17u, 1000u}) {
    cases.emplace_back("strip of " + std::to_string(count), strip(count, 0));
    cases.emplace_back("strip of " + std::to_string(count) + " from 1000", strip(count, 1000));
  }
  // Meshes appended one after another, each numbered from 0: the restart code.
  Indices appended =
      by_first_use(grid(5, 5, false, [](std::uint32_t x, std::uint32_t y) { return y * 6 + x; }));
  const Indices second = appended;
  appended.insert(appended.end(), second.begin(), second.end());
  appended.insert(appended.end(), second.begin(), second.end());
  cases.emplace_back("three grids appended", appended);
  for (const auto& [name, indices] : cases) {
    expect_as_library(indices, name);
    kinds.add(ours(indices), indices.size() / 3);
  }
  // The edge codes all turn up, the second-newest vertex to the oldest one a code names.
  for (unsigned fec = 0; fec < 16; ++fec) EXPECT_GT(kinds.edge_third[fec], 0u) << "edge code " << fec;
  EXPECT_GT(kinds.table, 0u);
  EXPECT_GT(kinds.aux_new, 0u);
}

// A generated closed surface, numbered as generated.
Indices generated(eval::Shape shape, std::size_t triangles) {
  eval::GenerateOptions options;
  options.shape = shape;
  options.target_triangles = triangles;
  const model::Mesh mesh = eval::generate_mesh(options);
  return mesh.triangles;
}

TEST(IndexEncode, VertexCacheOrderedAndShuffledMeshesAsLibrary) {
  std::mt19937 rng(7);
  CodeKinds kinds;
  for (const eval::Shape shape : {eval::Shape::kSphere, eval::Shape::kTerrain, eval::Shape::kShell}) {
    for (const std::size_t triangles : {50u, 2'000u, 30'000u}) {
      const Indices original = generated(shape, triangles);
      const std::size_t n = vertex_count_of(original);
      const std::string name = "shape " + std::to_string(static_cast<int>(shape)) + ", " +
                               std::to_string(original.size() / 3) + " triangles";
      expect_as_library(original, name);
      Indices fifo(original.size()), cache(original.size());
      meshopt_optimizeVertexCacheFifo(fifo.data(), original.data(), original.size(), n, 16);
      meshopt_optimizeVertexCache(cache.data(), original.data(), original.size(), n);
      const std::pair<const char*, const Indices*> orders[] = {{"FIFO-ordered", &fifo},
                                                               {"cache-ordered", &cache}};
      for (const auto& [how, ordered] : orders) {
        expect_as_library(*ordered, name + ", " + how);
        const Indices renumbered = by_first_use(*ordered);
        expect_as_library(renumbered, name + ", " + how + " by first use");
        kinds.add(ours(renumbered), renumbered.size() / 3);
      }
      // Shuffled triangles, each started at a random corner: few shared edges, many stored corners.
      Indices shuffled = by_first_use(fifo);
      std::vector<std::uint32_t> order(shuffled.size() / 3);
      std::iota(order.begin(), order.end(), 0u);
      std::shuffle(order.begin(), order.end(), rng);
      Indices reordered;
      for (const std::uint32_t t : order) {
        const int r = std::uniform_int_distribution<int>(0, 2)(rng);
        for (int k = 0; k < 3; ++k) reordered.push_back(shuffled[3 * t + (r + k) % 3]);
      }
      expect_as_library(reordered, name + ", shuffled");
      // Shuffled only a little: runs of 64 triangles in random order, each run in order.
      std::vector<std::uint32_t> runs(order.size() / 64 + 1);
      std::iota(runs.begin(), runs.end(), 0u);
      std::shuffle(runs.begin(), runs.end(), rng);
      reordered.clear();
      for (const std::uint32_t run : runs)
        for (std::size_t t = 64 * std::size_t{run}; t < std::min(order.size(), 64 * std::size_t{run} + 64);
             ++t)
          reordered.insert(reordered.end(), shuffled.begin() + 3 * t, shuffled.begin() + 3 * t + 3);
      expect_as_library(reordered, name + ", runs shuffled");
    }
  }
  // Vertex-cache order names most third corners by age or as new.
  EXPECT_GT(kinds.edge_third[0], 0u);
  EXPECT_GT(kinds.edge_third[1], 0u);
  EXPECT_GT(kinds.table, 0u);
}

// ---- Capacity --------------------------------------------------------------------------------------

TEST(IndexEncode, BoundIsTheLibrarys) {
  for (const std::size_t indices : {0u, 3u, 300u, 30'000u})
    for (const std::size_t vertices : {0ul, 1ul, 2ul, 3ul, 127ul, 128ul, 129ul, 1ul << 20, (1ul << 20) + 1,
                                       (1ul << 27) + 1, 0xfffffffful, 0x100000000ul, 0x100000001ul})
      EXPECT_EQ(codec::index_stream_bound(indices, vertices),
                meshopt_encodeIndexBufferBound(indices, vertices))
          << indices << " indices, " << vertices << " vertices";
}

TEST(IndexEncode, TooSmallCapacityReturnsZeroWhereTheLibraryDoes) {
  std::mt19937 rng(3);
  for (const Indices& indices :
       {Indices{}, Indices{0, 1, 2}, soup(rng, 500, 0, 0xffffffff, 0, 0),
        by_first_use(grid(20, 20, true, [](std::uint32_t x, std::uint32_t y) { return y * 21 + x; }))}) {
    const std::size_t size = ours(indices).size();
    // Both fail exactly below the stream's size, including below the minimum (header, code bytes
    // and table), and a buffer of the size is enough. Bytes past the capacity stay untouched.
    for (std::size_t capacity = 0; capacity <= size + 1; ++capacity) {
      if (capacity + 40 < size && capacity % 7 != 0) continue;  // a sample far from the size
      Bytes ours_out(capacity + 32, 0xcd), portable_out(capacity + 32, 0xcd), library_out(capacity);
      const std::size_t got =
          codec::encode_index_stream_v1(indices, std::span<std::uint8_t>(ours_out.data(), capacity));
      EXPECT_EQ(codec::encode_index_stream_v1_portable(
                    indices, std::span<std::uint8_t>(portable_out.data(), capacity)),
                got)
          << indices.size() << " indices, capacity " << capacity;
      meshopt_encodeIndexVersion(1);
      const std::size_t expected =
          meshopt_encodeIndexBuffer(library_out.data(), capacity, indices.data(), indices.size());
      EXPECT_EQ(got, capacity < size ? 0 : size) << indices.size() << " indices, capacity " << capacity;
      EXPECT_EQ(got, expected) << indices.size() << " indices, capacity " << capacity;
      for (const Bytes* written : {&ours_out, &portable_out})
        EXPECT_TRUE(std::all_of(written->begin() + capacity, written->end(),
                                [](std::uint8_t b) { return b == 0xcd; }))
            << "wrote past capacity " << capacity;
    }
  }
}

}  // namespace
}  // namespace mtlod::core

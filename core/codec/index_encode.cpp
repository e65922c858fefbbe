// Version-1 index streams (layout in index_encode.hpp), encoded as meshoptimizer's encoder does but
// in a third of its time. Which code a triangle gets, what enters the FIFOs and when follow the library
// step by step, since the decoder replays the same FIFOs and any difference changes the bytes; what
// differs is how the FIFOs are kept and searched, and how the codes are chosen:
// - The library walks a FIFO entry by entry, newest first, and leaves the loop at the first match (an
//   unpredictable exit, and 16 rounds of six compares for each triangle that shares no recent edge).
//   Here a search compares all 16 entries at once (SSE2) into a mask whose bit i is the entry of age i.
// - Both FIFOs are shift registers kept in SSE registers, newest in lane 0, so the newest match is the
//   mask's lowest bit. A ring in memory with an offset, as the library keeps them, would make each
//   search's 16-byte loads wait for the 4-byte stores of the triangle before (a failed store
//   forward on every triangle), and its masks would need rotating by the offset: on a 50k-triangle cut
//   of the dragon that version took 23 ns a triangle, this one 13 (the library 34).
// - Lanes are 16 bits wide when every index is below 0xffff (twice the lanes a register, half the
//   compares), 32 bits otherwise.
// - Codes that depend on coin-toss conditions (is the third corner in the FIFO, new, or stored?) are
//   chosen without branches, and a varint is always written and then kept or overwritten: branches
//   there mispredicted about once a triangle.
#include "core/codec/index_encode.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace mtlod::core::codec {
namespace {

// Ages the codes can name. A triangle is found by an edge of age 0..14: the code byte's high nibble
// is the age, and 15 there means a triangle stored by its corners. The third corner of a triangle
// found by an edge is named by its vertex age when that is 1..12: code 0 is the expected new vertex,
// so age 0 has none, and 13 and 14 are version 1's last − 1 and last + 1. Other triangles name b and c
// by vertex age 0..13 as 1..14. Age 15 is never named, in either FIFO.
constexpr std::uint32_t kEdgeAges = 0x7fff;  // the mask of ages 0..14
constexpr unsigned kThirdCornerAges = 12;    // 1..12
constexpr unsigned kCornerAges = 14;         // 0..13
constexpr unsigned kLastMinusOne = 13, kFree = 15;
// A triangle's most extra bytes: a code-aux byte and three 5-byte varints.
constexpr std::size_t kMostPerTriangle = 16;

// meshoptimizer's fixed code-aux table (it builds none per mesh): the 14 most frequent (b, c) nibble
// pairs of triangles stored by their corners, which such a triangle names in its code byte instead of
// spending a byte. It ends the stream, where the decoder reads it; the two last entries are unused.
constexpr std::array<std::uint8_t, 16> kCodeAuxTable = {0x00, 0x76, 0x87, 0x56, 0x67, 0x78, 0xa9, 0x86,
                                                        0x65, 0x89, 0x68, 0x98, 0x01, 0x69, 0,    0};
constexpr std::uint8_t kNotInTable = 0xff;
// A code-aux byte's place among the 14 entries in use, or kNotInTable: a lookup instead of the
// library's search. Those entries are distinct, so no order question arises.
constexpr std::array<std::uint8_t, 256> kCodeAuxIndex = [] {
  std::array<std::uint8_t, 256> index{};
  index.fill(kNotInTable);
  for (std::uint8_t i = 0; i < 14; ++i) index[kCodeAuxTable[i]] = i;
  return index;
}();

// cond ? x : y without a branch. GCC compiles the plain conditional to a jump for most of the choices
// below, which depend on the data and go either way about as often.
std::uint32_t pick(bool cond, std::uint32_t x, std::uint32_t y) {
  const std::uint32_t mask = 0u - static_cast<std::uint32_t>(cond);
  return (x & mask) | (y & ~mask);
}

// The lowest set bit of a 16-bit mask, 16 when it is empty (without the zero test std::countr_zero
// makes on x86-64's baseline).
unsigned lowest_bit(std::uint32_t mask) {
  return static_cast<unsigned>(std::countr_zero(mask | 0x10000u));
}

// A varint's length and the continuation bits of its first four bytes, by the position of the value's
// highest set bit: a lookup instead of four compares.
struct VarintShape {
  std::uint32_t more;  // bit 7 of each of the first four bytes that another byte follows
  std::uint32_t length;
};
constexpr std::array<VarintShape, 32> kVarintShape = [] {
  std::array<VarintShape, 32> shapes{};
  for (unsigned bit = 0; bit < 32; ++bit) {
    const unsigned length = bit / 7 + 1;
    for (unsigned k = 0; k + 1 < length && k < 4; ++k) shapes[bit].more |= 0x80u << (8 * k);
    shapes[bit].length = length;
  }
  return shapes;
}();

// Writes an index stored in full at `data` and returns its length, which the caller skips only when
// the index is stored: otherwise the next bytes or the table overwrite it. It is the difference from
// the last index so stored, zigzagged (small steps either way are small numbers), 7 bits a byte, low
// first, bit 7 set when more follow. Always writes 5 bytes (the most a varint takes), which keeps a
// triangle within its 16 bytes wherever its varints start.
unsigned put_free_index(std::uint8_t* data, std::uint32_t index, std::uint32_t last) {
  const std::uint32_t d = index - last;
  const std::uint32_t v = (d << 1) ^ (0u - (d >> 31));
  const VarintShape shape = kVarintShape[31 - std::countl_zero(v | 1)];
  const std::uint32_t low =
      (v & 0x7f) | (v << 1 & 0x7f00) | (v << 2 & 0x7f0000) | (v << 3 & 0x7f000000) | shape.more;
  data[0] = static_cast<std::uint8_t>(low);
  data[1] = static_cast<std::uint8_t>(low >> 8);
  data[2] = static_cast<std::uint8_t>(low >> 16);
  data[3] = static_cast<std::uint8_t>(low >> 24);
  data[4] = static_cast<std::uint8_t>(v >> 28);
  return shape.length;
}

struct Edge {
  std::uint32_t from, to;
};

// The FIFOs' interface, two implementations: `Probe` is a value prepared for searching; edge_ages and
// vertex_ages give bit i set where the entry of age i matches; pushes enter values as the library's do
// (in the order given, the last one newest). An unused entry holds all ones, as the library's
// memset(-1) leaves it, so index 0xffffffff matches unused entries there and must here.

#if defined(__SSE2__)
// 16 entries of `Lane` (uint16_t or uint32_t) per FIFO in SSE registers, lane i of the concatenation
// the entry of age i. 16-bit lanes hold indices below 0xffff only, so that none equals an unused entry.
template <class Lane>
class SseFifos {
  static constexpr int kRegisters = static_cast<int>(16 * sizeof(Lane) / 16);
  // A FIFO's registers (std::array<__m128i> would drop the vector type's attributes, GCC warns).
  struct Block {
    __m128i r[kRegisters];
    __m128i& operator[](int i) { return r[i]; }
    const __m128i& operator[](int i) const { return r[i]; }
  };

 public:
  using Probe = __m128i;

  SseFifos() { from_ = to_ = vertices_ = unused(); }

  static Probe probe(std::uint32_t v) {
    if constexpr (sizeof(Lane) == 2)
      return _mm_set1_epi16(static_cast<short>(v));
    else
      return _mm_set1_epi32(static_cast<int>(v));
  }

  std::uint32_t edge_ages(Probe from, Probe to) const {
    Block both;
    for (int r = 0; r < kRegisters; ++r) both[r] = _mm_and_si128(equal(from_[r], from), equal(to_[r], to));
    return to_bits(both);
  }

  std::uint32_t vertex_ages(Probe v) const {
    Block match;
    for (int r = 0; r < kRegisters; ++r) match[r] = equal(vertices_[r], v);
    return to_bits(match);
  }

  void push_edges(Edge older, Edge newer) {
    shift_in<2>(from_, lanes(newer.from, older.from));
    shift_in<2>(to_, lanes(newer.to, older.to));
  }

  void push_edges(Edge oldest, Edge older, Edge newest) {
    shift_in<3>(from_, lanes(newest.from, older.from, oldest.from));
    shift_in<3>(to_, lanes(newest.to, older.to, oldest.to));
  }

  void push_vertex(std::uint32_t v) { shift_in<1>(vertices_, lanes(v)); }

  // Pushes v when `pushed`, without a branch: the shifted FIFO or the old one, by a mask.
  void push_vertex_if(std::uint32_t v, bool pushed) {
    Block shifted = vertices_;
    shift_in<1>(shifted, lanes(v));
    const __m128i keep_new = _mm_set1_epi32(-static_cast<int>(pushed));
    for (int r = 0; r < kRegisters; ++r)
      vertices_[r] =
          _mm_or_si128(_mm_and_si128(keep_new, shifted[r]), _mm_andnot_si128(keep_new, vertices_[r]));
  }

  void forget_vertices() { vertices_ = unused(); }

 private:
  static Block unused() {
    Block block;
    for (__m128i& r : block.r) r = _mm_set1_epi32(-1);
    return block;
  }

  static __m128i equal(__m128i x, __m128i y) {
    if constexpr (sizeof(Lane) == 2)
      return _mm_cmpeq_epi16(x, y);
    else
      return _mm_cmpeq_epi32(x, y);
  }

  // Lanes of 0 or −1 to one bit each: the saturating packs keep 0 and −1.
  static std::uint32_t to_bits(const Block& lanes) {
    __m128i bytes;
    if constexpr (kRegisters == 2) {
      bytes = _mm_packs_epi16(lanes[0], lanes[1]);
    } else {
      bytes = _mm_packs_epi16(_mm_packs_epi32(lanes[0], lanes[1]), _mm_packs_epi32(lanes[2], lanes[3]));
    }
    return static_cast<std::uint32_t>(_mm_movemask_epi8(bytes));
  }

  // The values in lanes 0, 1, 2 (newest first), zero above.
  static __m128i lanes(std::uint32_t v0, std::uint32_t v1 = 0, std::uint32_t v2 = 0) {
    if constexpr (sizeof(Lane) == 2) {
      // Two values in one move, the third shifted in: cheaper than _mm_setr_epi16's inserts.
      return _mm_or_si128(_mm_cvtsi32_si128(static_cast<int>(v0 | v1 << 16)),
                          _mm_slli_si128(_mm_cvtsi32_si128(static_cast<int>(v2)), 4));
    } else {
      return _mm_setr_epi32(static_cast<int>(v0), static_cast<int>(v1), static_cast<int>(v2), 0);
    }
  }

  // Ages every entry by kCount and puts `fresh`'s lanes 0 .. kCount − 1 in front.
  template <int kCount>
  static void shift_in(Block& block, __m128i fresh) {
    constexpr int kBytes = kCount * static_cast<int>(sizeof(Lane));
    for (int r = kRegisters - 1; r > 0; --r)
      block[r] = _mm_or_si128(_mm_slli_si128(block[r], kBytes), _mm_srli_si128(block[r - 1], 16 - kBytes));
    block[0] = _mm_or_si128(_mm_slli_si128(block[0], kBytes), fresh);
  }

  Block from_, to_, vertices_;
};
#endif

// Plain arrays by age, for builds without SSE2 and for tests (encode_index_stream_v1_portable).
class PortableFifos {
 public:
  using Probe = std::uint32_t;

  PortableFifos() { from_.fill(kUnused), to_.fill(kUnused), vertices_.fill(kUnused); }

  static Probe probe(std::uint32_t v) { return v; }

  std::uint32_t edge_ages(Probe from, Probe to) const {
    std::uint32_t bits = 0;
    for (unsigned age = 0; age < 16; ++age)
      bits |= std::uint32_t{from_[age] == from && to_[age] == to} << age;
    return bits;
  }

  std::uint32_t vertex_ages(Probe v) const {
    std::uint32_t bits = 0;
    for (unsigned age = 0; age < 16; ++age) bits |= std::uint32_t{vertices_[age] == v} << age;
    return bits;
  }

  void push_edges(Edge older, Edge newer) {
    push_edge(older);
    push_edge(newer);
  }

  void push_edges(Edge oldest, Edge older, Edge newest) {
    push_edge(oldest);
    push_edge(older);
    push_edge(newest);
  }

  void push_vertex(std::uint32_t v) { push(vertices_, v); }

  void push_vertex_if(std::uint32_t v, bool pushed) {
    if (pushed) push(vertices_, v);
  }

  void forget_vertices() { vertices_.fill(kUnused); }

 private:
  static constexpr std::uint32_t kUnused = 0xffffffff;
  using Entries = std::array<std::uint32_t, 16>;

  static void push(Entries& entries, std::uint32_t v) {
    std::copy_backward(entries.begin(), entries.end() - 1, entries.end());
    entries[0] = v;
  }

  void push_edge(Edge e) {
    push(from_, e.from);
    push(to_, e.to);
  }

  Entries from_, to_, vertices_;
};

template <class Fifos>
std::size_t encode(std::span<const std::uint32_t> indices, std::span<std::uint8_t> out) {
  assert(indices.size() % 3 == 0);
  const std::size_t triangles = indices.size() / 3;
  // The library's capacity checks, which fail exactly when the stream does not fit: room for the
  // header, the code bytes and the table first, then before each triangle and the table room for a
  // triangle's most, so that no write checks.
  if (out.size() < 1 + triangles + kCodeAuxTable.size()) return 0;
  std::uint8_t* const begin = out.data();
  const std::uint8_t* const safe_end = begin + out.size() - kMostPerTriangle;
  begin[0] = kIndexStreamV1Header;
  std::uint8_t* code = begin + 1;
  std::uint8_t* data = code + triangles;

  Fifos fifos;
  std::uint32_t next = 0;  // the vertex a new vertex is expected to be (first-use numbering)
  std::uint32_t last = 0;  // the last index stored in full, which the next one is a delta from

  for (std::size_t t = 0; t < triangles; ++t) {
    if (data > safe_end) return 0;
    const std::uint32_t t0 = indices[3 * t], t1 = indices[3 * t + 1], t2 = indices[3 * t + 2];
    // Started at corner 0 the triangle shares edge (t0, t1) with an entry, at 1 (t1, t2), at 2
    // (t2, t0). The newest such entry wins and, within it, the lowest start (the library's order;
    // one entry matches two starts only when the three corners are equal, so which wins there makes
    // no difference).
    const auto p0 = Fifos::probe(t0), p1 = Fifos::probe(t1), p2 = Fifos::probe(t2);
    const std::uint32_t start0 = fifos.edge_ages(p0, p1), start1 = fifos.edge_ages(p1, p2),
                        start2 = fifos.edge_ages(p2, p0);
    const std::uint32_t shared = (start0 | start1 | start2) & kEdgeAges;

    if (shared != 0) {
      const unsigned fe = lowest_bit(shared);
      const bool at0 = start0 >> fe & 1, at1 = start1 >> fe & 1;
      // Plain conditionals, compiled to jumps: the pushes below need a, b and c, and a predicted
      // jump lets the next triangle's search start before this one's has finished.
      const std::uint32_t a = at0 ? t0 : (at1 ? t1 : t2);
      const std::uint32_t b = at0 ? t1 : (at1 ? t2 : t0);
      const std::uint32_t c = at0 ? t2 : (at1 ? t0 : t1);
      // The decoder has a and b from the edge; c is named by its vertex age, as the expected new
      // vertex, as the last free index ± 1 (strips), or stored.
      const unsigned age = lowest_bit(fifos.vertex_ages(Fifos::probe(c)));
      const bool named = age - 1 < kThirdCornerAges, expected = c == next;
      unsigned fec = kFree - 2 * unsigned{c + 1 == last} - unsigned{c == last + 1};
      fec = pick(expected, 0, fec);
      fec = pick(named, age, fec);
      next += !named & expected;
      const unsigned length = put_free_index(data, c, last);
      data += pick(fec == kFree, length, 0);
      last = pick(fec >= kLastMinusOne, c, last);
      *code++ = static_cast<std::uint8_t>(fe << 4 | fec);
      // A vertex named by its age stays where it is; any other enters the FIFO. Edge (a, b) is in
      // the FIFO already; the triangle's two others are c's.
      fifos.push_vertex_if(c, !named);
      fifos.push_edges({c, b}, {a, c});
    } else {
      // Started where the expected new vertex is, if anywhere but corner 0, so that a new triangle
      // usually names its first corner for free.
      const bool at1 = t1 == next, at2 = !at1 & (t2 == next);
      const std::uint32_t a = pick(at1, t1, pick(at2, t2, t0)), b = pick(at1, t2, pick(at2, t0, t1)),
                          c = pick(at1, t0, pick(at2, t1, t2));
      // Triangle (0, 1, 2) after the numbering started restarts it: a new mesh appended to the
      // stream. The encoder forgets its vertices so that it never names them by age, and `next`
      // counts up from 0 again.
      const bool restart = ((a | (b ^ 1) | (c ^ 2)) == 0) & (next > 0);
      if (restart) [[unlikely]] {
        next = 0;
        fifos.forget_vertices();
      }
      const unsigned age_b = lowest_bit(fifos.vertex_ages(Fifos::probe(b)));
      const unsigned age_c = lowest_bit(fifos.vertex_ages(Fifos::probe(c)));
      // `next` moves on with each corner in turn, so a triangle of three new vertices costs nothing.
      const bool a_new = a == next;
      next += a_new;
      const bool b_named = age_b < kCornerAges, b_new = !b_named & (b == next);
      next += b_new;
      const bool c_named = age_c < kCornerAges, c_new = !c_named & (c == next);
      next += c_new;
      const unsigned feb = pick(b_named, age_b + 1, pick(b_new, 0, kFree));
      const unsigned fec = pick(c_named, age_c + 1, pick(c_new, 0, kFree));
      const auto aux = static_cast<std::uint8_t>(feb << 4 | fec);
      const std::uint8_t aux_index = kCodeAuxIndex[aux];
      // 0xf0 | i names table entry i when a is the expected vertex; 0xfe (a expected) and 0xff (a
      // stored) are followed by the code-aux byte. A restart always spends the byte: 0xfe with aux 0
      // is how the decoder recognises one.
      const bool in_table = a_new & (aux_index != kNotInTable) & !restart;
      *code++ = static_cast<std::uint8_t>(pick(in_table, 0xf0u | aux_index, 0xffu - a_new));
      *data = aux;
      data += !in_table;
      unsigned length = put_free_index(data, a, last);
      data += pick(a_new, 0, length);
      last = pick(a_new, last, a);
      length = put_free_index(data, b, last);
      data += pick(feb == kFree, length, 0);
      last = pick(feb == kFree, b, last);
      length = put_free_index(data, c, last);
      data += pick(fec == kFree, length, 0);
      last = pick(fec == kFree, c, last);
      // a is always new or stored; corners named by age stay where they are.
      fifos.push_vertex(a);
      fifos.push_vertex_if(b, !b_named);
      fifos.push_vertex_if(c, !c_named);
      fifos.push_edges({b, a}, {c, b}, {a, c});
    }
  }

  if (data > safe_end) return 0;
  // The table also pads the stream, so that the decoder may read a triangle's 16 bytes unchecked.
  std::memcpy(data, kCodeAuxTable.data(), kCodeAuxTable.size());
  data += kCodeAuxTable.size();
  return static_cast<std::size_t>(data - begin);
}

}  // namespace

std::size_t index_stream_bound(std::size_t index_count, std::size_t vertex_count) {
  assert(index_count % 3 == 0);
  // A delta between two indices below 2^bits takes bits + 1 bits zigzagged, in 7-bit groups.
  unsigned vertex_bits = 1;
  while (vertex_bits < 32 && vertex_count > std::size_t{1} << vertex_bits) ++vertex_bits;
  const std::size_t groups = (vertex_bits + 1 + 6) / 7;
  return 1 + index_count / 3 * (2 + 3 * groups) + kCodeAuxTable.size();
}

std::size_t encode_index_stream_v1(std::span<const std::uint32_t> indices, std::span<std::uint8_t> out) {
#if defined(__SSE2__)
  // 16-bit lanes when every index is below 0xffff, the value unused entries hold. The pass ORs the
  // indices' high halves (and those of index + 1, for 0xffff) rather than taking a maximum, whose
  // compare-and-select chain would hold up the vectorized loop: a small part of the encoding's time.
  std::uint32_t high = 0;
  for (const std::uint32_t v : indices) high |= (v >> 16) | ((v + 1) >> 16);
  if (high == 0) return encode<SseFifos<std::uint16_t>>(indices, out);
  return encode<SseFifos<std::uint32_t>>(indices, out);
#else
  return encode<PortableFifos>(indices, out);
#endif
}

std::size_t encode_index_stream_v1_portable(std::span<const std::uint32_t> indices,
                                            std::span<std::uint8_t> out) {
  return encode<PortableFifos>(indices, out);
}

}  // namespace mtlod::core::codec

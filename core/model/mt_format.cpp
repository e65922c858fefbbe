// .mt file format (core/ARCHITECTURE.md §2.8; layout in core/model/FORMAT.md). Untrusted input: every
// size is checked before a read, in 64-bit arithmetic, and every index before it is trusted.
#include "core/model/mt_format.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <optional>
#include <string>

namespace mtlod::core::model {
namespace {

static_assert(std::endian::native == std::endian::little,
              "the .mt format is little-endian and read by memcpy; add byte swapping for big-endian hosts");

constexpr char kMagic[8] = {'M', 'T', 'L', 'O', 'D', 'M', 'T', '\0'};
constexpr std::uint32_t kFlagNormals = 1u << 0;
constexpr std::uint32_t kFlagColors = 1u << 1;
// The checksum field sits inside the checksummed bytes and is read as zero, so writers fill it last.
// Version 1: over the whole file; version 2: over the header and the block table.
constexpr std::uint64_t kChecksumOffset = 48;
constexpr std::uint64_t kFnvPrime = 0x100000001b3ull;
constexpr std::uint64_t kFnvSeed = 0xcbf29ce484222325ull;

// Every array starts 4-byte aligned so a memory map can be read as u32/f32 arrays in place.
std::uint64_t pad4(std::uint64_t n) {
  return (n + 3) & ~std::uint64_t{3};
}
std::uint64_t pad8(std::uint64_t n) {
  return (n + 7) & ~std::uint64_t{7};
}

std::uint32_t flags_of(const MtCounts& c) {
  return (c.normals ? kFlagNormals : 0) | (c.colors ? kFlagColors : 0);
}

// Offsets of the arrays after a header of header_bytes (version 1: 64, version 2: 256).
MtLayout layout_after(const MtCounts& c, std::uint64_t header_bytes) {
  const std::uint64_t v = c.vertices, n = c.nodes, t = c.triangles;
  MtLayout l{};
  l.positions = header_bytes;
  l.normals = l.positions + 12 * v;
  l.colors = l.normals + (c.normals ? 12 * v : 0);
  l.node_vertex = l.colors + (c.colors ? pad4(3 * v) : 0);
  l.node_error = l.node_vertex + 4 * n;
  l.node_triangle_offsets = l.node_error + 4 * n;
  l.node_parent_offsets = l.node_triangle_offsets + 4 * (n + 1);
  l.node_parents = l.node_parent_offsets + 4 * (n + 1);
  l.triangle_corners = l.node_parents + 4 * std::uint64_t{c.parents};
  l.root_first_corner = l.triangle_corners + 8 * t;
  l.triangle_remover = l.root_first_corner + 4 * std::uint64_t{c.root_triangles};
  l.block_table = pad8(l.triangle_remover + 4 * t);
  l.end = l.block_table + kMtBlockEntryBytes * std::uint64_t{mt_block_count(c.nodes)};
  return l;
}

void put32(std::vector<std::uint8_t>& out, std::uint32_t x) {
  const std::size_t at = out.size();
  out.resize(at + 4);
  std::memcpy(out.data() + at, &x, 4);
}
void put64(std::vector<std::uint8_t>& out, std::uint64_t x) {
  const std::size_t at = out.size();
  out.resize(at + 8);
  std::memcpy(out.data() + at, &x, 8);
}
// Magic, version and counts: the first 36 bytes of the header in both versions.
void put_counts(std::vector<std::uint8_t>& out, std::uint32_t version, const MtCounts& c) {
  out.resize(8);
  std::memcpy(out.data(), kMagic, 8);
  put32(out, version);
  put32(out, flags_of(c));
  put32(out, c.vertices);
  put32(out, c.nodes);
  put32(out, c.triangles);
  put32(out, c.root_triangles);
  put32(out, c.parents);
}
void put_float(std::vector<std::uint8_t>& out, float x) {
  put32(out, std::bit_cast<std::uint32_t>(x));
}
template <class T>
void put_array(std::vector<std::uint8_t>& out, std::span<const T> a) {
  const std::size_t at = out.size();
  out.resize(pad4(at + a.size() * sizeof(T)), 0);
  if (!a.empty()) std::memcpy(out.data() + at, a.data(), a.size() * sizeof(T));
}

// memcpy, not a cast: the buffer may be unaligned and type punning through pointers is UB.
std::uint32_t get32(const std::uint8_t* p) {
  std::uint32_t x;
  std::memcpy(&x, p, 4);
  return x;
}
std::uint64_t get64(const std::uint8_t* p) {
  std::uint64_t x;
  std::memcpy(&x, p, 8);
  return x;
}

// Reads count elements from the cursor; sizes were checked against the buffer beforehand.
template <class T>
void take_array(const std::uint8_t*& cursor, std::uint64_t count, std::vector<T>& a) {
  a.resize(count);
  if (count) std::memcpy(a.data(), cursor, count * sizeof(T));
  cursor += pad4(count * sizeof(T));
}
// The same in place: a view of the image (4-byte aligned when the image is).
template <class T>
std::span<const T> view_array(const std::uint8_t* base, std::uint64_t offset, std::uint64_t count) {
  return {reinterpret_cast<const T*>(base + offset), std::size_t(count)};
}

Error corrupt(std::string message) {
  return make_error(ErrorCode::kCorrupt, "corrupt MT file: " + std::move(message));
}

// A range of nodes with their triangles, parents and vertices: a block of a version-2 file, or a
// whole MT.
struct NodeRange {
  std::uint64_t n0, n1, t0, t1, p0, p1, v0, v1;
};

// The node range of block b of a version-2 MT, from its block table.
NodeRange block_range(const MtCounts& c, std::span<const std::uint8_t> table, std::uint32_t b) {
  const std::uint32_t blocks = mt_block_count(c.nodes);
  NodeRange r{};
  r.n0 = std::uint64_t{b} << kMtBlockShift;
  r.n1 = std::min<std::uint64_t>(c.nodes, r.n0 + kMtBlockNodes);
  r.t0 = get32(table.data() + kMtBlockEntryBytes * b);
  r.p0 = get32(table.data() + kMtBlockEntryBytes * b + 4);
  const bool last = b + 1 == blocks;
  r.t1 = last ? c.triangles : get32(table.data() + kMtBlockEntryBytes * (b + 1));
  r.p1 = last ? c.parents : get32(table.data() + kMtBlockEntryBytes * (b + 1) + 4);
  // Block 0 holds the root's vertices, the last one the vertices no triangle uses.
  r.v0 = b == 0 ? 0 : c.root_vertices + r.n0 - 1;
  r.v1 = last ? c.vertices : c.root_vertices + r.n1 - 1;
  return r;
}

// The byte ranges of a version-2 file that block b's checksum covers, in the order it chains them:
// the block's vertices, nodes (with the closing offsets in the last block), parents and triangles.
struct Slice {
  std::uint64_t offset, bytes;
};
std::size_t block_slices(const MtCounts& c, const MtLayout& l, const NodeRange& r, bool last, Slice out[12]) {
  std::size_t k = 0;
  const std::uint64_t closing = last ? 1 : 0;
  out[k++] = {l.positions + 12 * r.v0, 12 * (r.v1 - r.v0)};
  if (c.normals) out[k++] = {l.normals + 12 * r.v0, 12 * (r.v1 - r.v0)};
  if (c.colors) out[k++] = {l.colors + 3 * r.v0, 3 * (r.v1 - r.v0)};
  out[k++] = {l.node_vertex + 4 * r.n0, 4 * (r.n1 - r.n0)};
  out[k++] = {l.node_error + 4 * r.n0, 4 * (r.n1 - r.n0)};
  out[k++] = {l.node_triangle_offsets + 4 * r.n0, 4 * (r.n1 - r.n0 + closing)};
  out[k++] = {l.node_parent_offsets + 4 * r.n0, 4 * (r.n1 - r.n0 + closing)};
  out[k++] = {l.node_parents + 4 * r.p0, 4 * (r.p1 - r.p0)};
  out[k++] = {l.triangle_corners + 8 * r.t0, 8 * (r.t1 - r.t0)};
  if (r.n0 == 0) out[k++] = {l.root_first_corner, 4 * std::uint64_t{c.root_triangles}};
  out[k++] = {l.triangle_remover + 4 * r.t0, 4 * (r.t1 - r.t0)};
  return k;
}

// A corner's position is checked with its triangle too: in a mapped file the corner's own block
// may not have been checked yet, and a refinement reads the positions of every corner it emits.
bool finite_vertex(const Mt& mt, std::uint32_t x) {
  const float* p = &mt.positions[3 * std::size_t{x}];
  return std::isfinite(p[0]) && std::isfinite(p[1]) && std::isfinite(p[2]);
}

// The positions of the range's vertices, and each node's split vertex and error.
Status check_node_values(const Mt& mt, const NodeRange& r, std::optional<std::uint32_t> root_vertices) {
  const std::uint64_t v = mt.vertex_count();
  for (std::uint64_t i = 3 * r.v0; i < 3 * r.v1; ++i)
    if (!std::isfinite(mt.positions[i])) return corrupt("positions[" + std::to_string(i) + "] is not finite");
  for (std::uint64_t i = r.n0; i < r.n1; ++i) {
    const std::uint32_t split = mt.node_vertex[i];
    if (i == 0) {
      if (split != kNoVertex) return corrupt("node_vertex[0] of the root is not the none marker");
    } else if (root_vertices ? split != *root_vertices + i - 1 : split >= v) {
      return corrupt("node_vertex[" + std::to_string(i) + "] = " + std::to_string(split) +
                     (root_vertices ? " is not the node-order id " + std::to_string(*root_vertices + i - 1)
                                    : " >= vertex count " + std::to_string(v)));
    }
    if (!(mt.node_error[i] >= 0.0f) || !std::isfinite(mt.node_error[i]))
      return corrupt("node_error[" + std::to_string(i) + "] is negative or not finite");
    // Sorted by decreasing error, so with parents before children errors never grow from a node to
    // its children; refinement relies on both.
    if (i >= 2 && mt.node_error[i] > mt.node_error[i - 1])
      return corrupt("node_error[" + std::to_string(i) + "] is larger than node_error[" +
                     std::to_string(i - 1) + "] (nodes must be sorted by decreasing error)");
  }
  return Ok{};
}

// The nodes' triangle and parent offsets, and the root's first corners.
Status check_node_offsets(const Mt& mt, const NodeRange& r) {
  const std::uint64_t v = mt.vertex_count();
  auto check_offsets = [&](std::span<const std::uint32_t> offsets, std::uint64_t first, std::uint64_t end,
                           const char* name) -> Status {
    if (offsets[r.n0] != first)
      return corrupt(std::string(name) + "[" + std::to_string(r.n0) + "] is " +
                     std::to_string(offsets[r.n0]) + ", expected " + std::to_string(first));
    for (std::uint64_t i = r.n0; i < r.n1; ++i)
      if (offsets[i + 1] < offsets[i])
        return corrupt(std::string(name) + " decrease at node " + std::to_string(i));
    if (offsets[r.n1] != end)
      return corrupt(std::string(name) + " end at " + std::to_string(offsets[r.n1]) + ", expected " +
                     std::to_string(end));
    return Ok{};
  };
  MTLOD_RETURN_IF_ERROR(check_offsets(mt.node_triangle_offsets, r.t0, r.t1, "node_triangle_offsets"));
  MTLOD_RETURN_IF_ERROR(check_offsets(mt.node_parent_offsets, r.p0, r.p1, "node_parent_offsets"));
  if (r.n0 == 0) {
    // Root triangles keep their first corner apart (they have no split vertex); the counts must agree.
    if (mt.node_triangle_offsets[1] != mt.root_triangle_count())
      return corrupt("root creates " + std::to_string(mt.node_triangle_offsets[1]) + " triangles but " +
                     std::to_string(mt.root_triangle_count()) + " root corners are stored");
    if (mt.node_parent_offsets[1] != 0) return corrupt("the root has parents");
    for (std::uint64_t i = 0; i < mt.root_triangle_count(); ++i)
      if (mt.root_first_corner[i] >= v || !finite_vertex(mt, mt.root_first_corner[i]))
        return corrupt("root_first_corner[" + std::to_string(i) + "] >= vertex count " + std::to_string(v) +
                       " or its position is not finite");
  }
  return Ok{};
}

// DAG order: parents strictly increasing and smaller than their child; every node has one. This
// also bounds the ancestor walk of refinement (ids only decrease along it).
Status check_parent_order(const Mt& mt, const NodeRange& r) {
  for (std::uint64_t i = std::max<std::uint64_t>(r.n0, 1); i < r.n1; ++i) {
    const std::uint32_t begin = mt.node_parent_offsets[i], end = mt.node_parent_offsets[i + 1];
    if (begin == end) return corrupt("node " + std::to_string(i) + " has no parent");
    for (std::uint32_t j = begin; j < end; ++j) {
      const std::uint32_t p = mt.node_parents[j];
      if (p >= i)
        return corrupt("node " + std::to_string(i) + " has parent " + std::to_string(p) + " not before it");
      if (j > begin && p <= mt.node_parents[j - 1])
        return corrupt("parents of node " + std::to_string(i) + " are not strictly increasing");
    }
  }
  return Ok{};
}

// The corners' positions and the removers' parent lists lie anywhere in the file: they are
// fetched ahead so that the misses overlap (a block's check is otherwise a cache miss per read).
constexpr std::uint64_t kAhead = 16;

// Every corner of the range's triangles: a vertex id with a finite position.
Status check_corners(const Mt& mt, const NodeRange& r) {
  const std::uint64_t v = mt.vertex_count();
  for (std::uint64_t i = 2 * r.t0; i < 2 * r.t1; ++i) {
    if (i + kAhead < 2 * r.t1) {
      const std::uint32_t ahead = mt.triangle_corners[i + kAhead];
      if (ahead < v) __builtin_prefetch(mt.positions.data() + 3 * std::size_t{ahead});
    }
    const std::uint32_t corner = mt.triangle_corners[i];
    if (corner >= v)
      return corrupt("triangle_corners[" + std::to_string(i) + "] = " + std::to_string(corner) +
                     " >= vertex count " + std::to_string(v));
    if (!finite_vertex(mt, corner))
      return corrupt("triangle_corners[" + std::to_string(i) + "]: positions of vertex " +
                     std::to_string(corner) + " are not finite");
  }
  return Ok{};
}

// Each triangle's remover comes after its creator and lists the creator as a parent: refinement
// adds a node after its parents and then expects everything the node removes to be in the mesh.
Status check_removers(const Mt& mt, const NodeRange& r) {
  const std::uint64_t n = mt.node_count(), p_total = mt.node_parents.size();
  const std::uint32_t* removers = mt.triangle_remover.data();
  for (std::uint64_t c = r.n0; c < r.n1; ++c) {
    for (std::uint32_t k = mt.node_triangle_offsets[c]; k < mt.node_triangle_offsets[c + 1]; ++k) {
      // Two stages: the parent offsets of the remover 2·kAhead triangles ahead, then the parents of
      // the one kAhead ahead (whose offsets came in meanwhile).
      if (k + 2 * kAhead < r.t1) {
        const std::uint32_t ahead = removers[k + 2 * kAhead];
        if (ahead < n) __builtin_prefetch(mt.node_parent_offsets.data() + ahead);
      }
      if (k + kAhead < r.t1) {
        const std::uint32_t ahead = removers[k + kAhead];
        if (ahead < n) {
          const std::uint32_t first = mt.node_parent_offsets[ahead];
          if (first < p_total) __builtin_prefetch(mt.node_parents.data() + first);
        }
      }
      const std::uint32_t rm = removers[k];
      if (rm == kNoNode) continue;
      if (rm >= n || rm <= c)
        return corrupt("triangle " + std::to_string(k) + " of node " + std::to_string(c) + " has remover " +
                       std::to_string(rm) + " outside (" + std::to_string(c) + ", " + std::to_string(n) +
                       ")");
      const std::uint32_t first = mt.node_parent_offsets[rm], last = mt.node_parent_offsets[rm + 1];
      if (first > last || last > p_total)
        return corrupt("node_parent_offsets of node " + std::to_string(rm) + " are out of order");
      const auto* begin = mt.node_parents.data() + first;
      const auto* end = mt.node_parents.data() + last;
      const auto* it = std::lower_bound(begin, end, std::uint32_t(c));
      if (it == end || *it != c)
        return corrupt("node " + std::to_string(rm) + " removes triangle " + std::to_string(k) + " of node " +
                       std::to_string(c) + " without listing it as a parent");
    }
  }
  return Ok{};
}

// Checks nodes [n0, n1) with their triangles [t0, t1), parents [p0, p1) and vertices [v0, v1).
// Split vertices are root_vertices + n − 1 when that is given (version 2), else any vertex. Reads
// outside the range (a remover's parents, the previous node's error) are bounds-checked: their
// values are checked with their own block.
Status check_nodes(const Mt& mt, const NodeRange& r, std::optional<std::uint32_t> root_vertices) {
  MTLOD_RETURN_IF_ERROR(check_node_values(mt, r, root_vertices));
  MTLOD_RETURN_IF_ERROR(check_node_offsets(mt, r));
  MTLOD_RETURN_IF_ERROR(check_parent_order(mt, r));
  MTLOD_RETURN_IF_ERROR(check_corners(mt, r));
  return check_removers(mt, r);
}

// A parsed header with its counts.
struct Header {
  std::uint32_t version = 0;
  MtCounts counts;
  MtLayout layout{};
  Bounds bounds;
  std::uint32_t input_triangles = 0;
};

Result<Header> parse_header(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < kMtHeaderBytesV1)
    return corrupt("file of " + std::to_string(bytes.size()) + " bytes is shorter than a header");
  const std::uint8_t* p = bytes.data();
  if (std::memcmp(p, kMagic, 8) != 0) return corrupt("bad magic (not an mtlod MT file)");
  Header h;
  h.version = get32(p + 8);
  if (h.version != 1 && h.version != 2)
    return make_error(ErrorCode::kUnsupported, "MT file version " + std::to_string(h.version) +
                                                   " is not supported (this build reads versions 1 and 2)");
  const std::uint64_t header_bytes = h.version == 1 ? kMtHeaderBytesV1 : kMtHeaderBytes;
  if (bytes.size() < header_bytes)
    return corrupt("file of " + std::to_string(bytes.size()) + " bytes is shorter than the " +
                   std::to_string(header_bytes) + "-byte header");
  const std::uint32_t flags = get32(p + 12);
  MtCounts& c = h.counts;
  c.normals = flags & kFlagNormals;
  c.colors = flags & kFlagColors;
  c.vertices = get32(p + 16);
  c.nodes = get32(p + 20);
  c.triangles = get32(p + 24);
  c.root_triangles = get32(p + 28);
  c.parents = get32(p + 32);
  if (flags & ~(kFlagNormals | kFlagColors)) return corrupt("unknown flags " + std::to_string(flags));
  bool reserved_zero = get64(p + 56) == 0;
  if (h.version == 1) {
    reserved_zero = reserved_zero && get32(p + 36) == 0;
  } else {
    c.root_vertices = get32(p + 36);
    for (std::size_t i = 92; i < kMtHeaderBytes; ++i) reserved_zero = reserved_zero && p[i] == 0;
  }
  if (!reserved_zero) return corrupt("reserved header fields are not zero");
  if (c.nodes == 0) return corrupt("node count is 0 (the root is missing)");
  if (c.nodes == kNoNode) return corrupt("node count " + std::to_string(c.nodes) + " exceeds the id range");
  if (c.root_triangles > c.triangles)
    return corrupt("root triangle count " + std::to_string(c.root_triangles) + " > triangle count " +
                   std::to_string(c.triangles));
  const MtLayout l = layout_after(c, header_bytes);
  // Version 1 has no block table: its payload ends with the removers.
  const std::uint64_t end = h.version == 1 ? l.triangle_remover + 4 * std::uint64_t{c.triangles} : l.end;
  const std::uint64_t stated = get64(p + 40);
  const std::uint64_t expected = h.version == 1 ? end - header_bytes : end;
  if (stated != expected)
    return corrupt(std::string(h.version == 1 ? "payload" : "file") + " size field " +
                   std::to_string(stated) + " does not match the counts (" + std::to_string(expected) +
                   " bytes)");
  if (bytes.size() != end)
    return corrupt("file has " + std::to_string(bytes.size()) + " bytes, its counts need " +
                   std::to_string(end) + (bytes.size() < end ? " (truncated)" : ""));
  if (h.version == 2) {
    if (std::uint64_t{c.root_vertices} + c.nodes - 1 > c.vertices)
      return corrupt("root vertex count " + std::to_string(c.root_vertices) +
                     " leaves no vertex for every node");
    for (int k = 0; k < 3; ++k) {
      h.bounds.lo[k] = std::bit_cast<float>(get32(p + 64 + 4 * k));
      h.bounds.hi[k] = std::bit_cast<float>(get32(p + 76 + 4 * k));
    }
    h.input_triangles = get32(p + 88);
    if (h.input_triangles > c.triangles)
      return corrupt("input triangle count " + std::to_string(h.input_triangles) + " > triangle count " +
                     std::to_string(c.triangles));
  }
  h.layout = l;
  return h;
}

// Version 2: the bounds the header states are a box (checked after the blocks, whose messages
// name the array a non-finite position is in).
Status check_bounds(const Header& h) {
  bool finite = true;
  for (int k = 0; k < 3; ++k)
    finite = finite && std::isfinite(h.bounds.lo[k]) && std::isfinite(h.bounds.hi[k]);
  if (h.counts.vertices > 0 && (!finite || h.bounds.empty()))
    return corrupt("the header's bounds are not a box");
  return Ok{};
}

// The checksum of bytes with the 8 at kChecksumOffset read as zero, chained from seed.
std::uint64_t checksum_without_field(std::span<const std::uint8_t> bytes, std::uint64_t seed = kFnvSeed) {
  std::uint64_t sum = mt_checksum(bytes.subspan(0, kChecksumOffset), seed);
  const std::uint8_t zeros[8] = {};
  sum = mt_checksum(std::span<const std::uint8_t>(zeros, 8), sum);
  return mt_checksum(bytes.subspan(kChecksumOffset + 8), sum);
}

// The block table's order: block 0 starts at 0, the first triangles and parents never decrease and
// stay within the counts, so every block's slices lie inside the arrays.
Status check_table_order(const MtCounts& c, std::span<const std::uint8_t> table) {
  const std::uint32_t blocks = mt_block_count(c.nodes);
  std::uint32_t previous_t = 0, previous_p = 0;
  for (std::uint32_t b = 0; b < blocks; ++b) {
    const std::uint32_t t = get32(table.data() + kMtBlockEntryBytes * b);
    const std::uint32_t q = get32(table.data() + kMtBlockEntryBytes * b + 4);
    if ((b == 0 && (t != 0 || q != 0)) || t < previous_t || q < previous_p || t > c.triangles ||
        q > c.parents)
      return corrupt("block table entry " + std::to_string(b) + " is out of order");
    previous_t = t;
    previous_p = q;
  }
  return Ok{};
}

// Version 2: the header checksum (header and block table) and the table's order.
Status check_table(const Header& h, std::span<const std::uint8_t> bytes) {
  const auto table = bytes.subspan(h.layout.block_table);
  std::uint64_t sum = checksum_without_field(bytes.subspan(0, kMtHeaderBytes));
  sum = mt_checksum(table, sum);
  if (sum != get64(bytes.data() + kChecksumOffset))
    return corrupt("header checksum mismatch (the header or the block table was altered or damaged)");
  return check_table_order(h.counts, table);
}

// The spans of an image laid out as h says.
Mt view_of(const Header& h, std::span<const std::uint8_t> bytes) {
  const MtCounts& c = h.counts;
  const MtLayout& l = h.layout;
  const std::uint8_t* base = bytes.data();
  const std::uint64_t v = c.vertices, n = c.nodes;
  Mt mt;
  mt.positions = view_array<float>(base, l.positions, 3 * v);
  if (c.normals) mt.normals = view_array<float>(base, l.normals, 3 * v);
  if (c.colors) mt.colors = view_array<std::uint8_t>(base, l.colors, 3 * v);
  mt.node_vertex = view_array<std::uint32_t>(base, l.node_vertex, n);
  mt.node_error = view_array<float>(base, l.node_error, n);
  mt.node_triangle_offsets = view_array<std::uint32_t>(base, l.node_triangle_offsets, n + 1);
  mt.node_parent_offsets = view_array<std::uint32_t>(base, l.node_parent_offsets, n + 1);
  mt.node_parents = view_array<std::uint32_t>(base, l.node_parents, c.parents);
  mt.triangle_corners = view_array<std::uint32_t>(base, l.triangle_corners, 2 * std::uint64_t{c.triangles});
  mt.root_first_corner = view_array<std::uint32_t>(base, l.root_first_corner, c.root_triangles);
  mt.triangle_remover = view_array<std::uint32_t>(base, l.triangle_remover, c.triangles);
  mt.bounds = h.bounds;
  mt.input_triangles = h.input_triangles;
  return mt;
}

// Block b of a version-2 image: its checksum, then its content.
Status check_block(const Header& h, const Mt& mt, std::span<const std::uint8_t> bytes, std::uint32_t b) {
  const auto table = bytes.subspan(h.layout.block_table);
  const NodeRange r = block_range(h.counts, table, b);
  Slice slices[12];
  const std::size_t k = block_slices(h.counts, h.layout, r, b + 1 == mt_block_count(h.counts.nodes), slices);
  std::uint64_t sum = kFnvSeed;
  for (std::size_t i = 0; i < k; ++i)
    sum = mt_checksum(bytes.subspan(slices[i].offset, slices[i].bytes), sum);
  if (sum != get64(table.data() + kMtBlockEntryBytes * b + 8))
    return corrupt("checksum mismatch in block " + std::to_string(b) + " (nodes " + std::to_string(r.n0) +
                   "–" + std::to_string(r.n1 - 1) + "; the file was altered or damaged)");
  return check_nodes(mt, r, h.counts.root_vertices);
}

// Checks a mapped image's blocks on first use.
class BlockCheck final : public MtBlockCheck {
 public:
  BlockCheck(Header header, Mt spans, std::span<const std::uint8_t> bytes)
      : MtBlockCheck(mt_block_count(header.counts.nodes)),
        header_(std::move(header)),
        spans_(std::move(spans)),
        bytes_(bytes) {}
  // Block 0 (the root) before anything else is used.
  Status check_now(std::uint32_t b) const {
    MTLOD_RETURN_IF_ERROR(model::check_block(header_, spans_, bytes_, b));
    state_[b].store(kValid, std::memory_order_release);
    return Ok{};
  }

 protected:
  Status check_block(std::uint32_t b) const override {
    if (b >= block_count_)
      return make_error(ErrorCode::kCorrupt,
                        "corrupt MT file: node block " + std::to_string(b) + " does not exist");
    return check_now(b);
  }

 private:
  Header header_;
  Mt spans_;  // without storage or checks of its own
  std::span<const std::uint8_t> bytes_;
};

}  // namespace

std::uint64_t mt_checksum(std::span<const std::uint8_t> bytes, std::uint64_t seed) {
  std::uint64_t h = seed;
  std::size_t i = 0;
  for (; i + 8 <= bytes.size(); i += 8) h = (h ^ get64(bytes.data() + i)) * kFnvPrime;
  for (; i < bytes.size(); ++i) h = (h ^ bytes[i]) * kFnvPrime;
  return h;
}

std::uint32_t mt_block_count(std::uint32_t nodes) {
  return std::uint32_t((std::uint64_t{nodes} + kMtBlockNodes - 1) >> kMtBlockShift);
}

MtLayout mt_layout(const MtCounts& counts) {
  return layout_after(counts, kMtHeaderBytes);
}

Result<MtSeal> seal_mt(const MtCounts& c, const MtReadAt& read_at) {
  const MtLayout l = mt_layout(c);
  const std::uint32_t blocks = mt_block_count(c.nodes);
  MtSeal seal;
  // Each block's first triangle and parent are the offsets of its first node.
  std::vector<std::uint8_t>& table = seal.block_table;
  table.assign(kMtBlockEntryBytes * std::size_t{blocks}, 0);
  for (std::uint32_t b = 0; b < blocks; ++b) {
    const std::uint64_t n0 = std::uint64_t{b} << kMtBlockShift;
    MTLOD_RETURN_IF_ERROR(
        read_at(l.node_triangle_offsets + 4 * n0, {table.data() + kMtBlockEntryBytes * b, 4}));
    MTLOD_RETURN_IF_ERROR(
        read_at(l.node_parent_offsets + 4 * n0, {table.data() + kMtBlockEntryBytes * b + 4, 4}));
  }
  // The offsets are the caller's arrays: a block table out of order would send the slices below
  // outside them.
  MTLOD_RETURN_IF_ERROR(check_table_order(c, table));
  Bounds bounds;
  std::uint32_t input_triangles = 0;
  std::vector<std::uint8_t> buffer;
  for (std::uint32_t b = 0; b < blocks; ++b) {
    const NodeRange r = block_range(c, table, b);
    Slice slices[12];
    const std::size_t k = block_slices(c, l, r, b + 1 == blocks, slices);
    std::uint64_t sum = kFnvSeed;
    for (std::size_t i = 0; i < k; ++i) {
      buffer.resize(slices[i].bytes);
      MTLOD_RETURN_IF_ERROR(read_at(slices[i].offset, buffer));
      sum = mt_checksum(buffer, sum);
      if (i + 1 == k) {  // removers: the triangles of the input
        for (std::size_t t = 0; t + 4 <= buffer.size(); t += 4)
          input_triangles += get32(buffer.data() + t) == kNoNode;
      }
      if (i == 0) {  // positions: the bounds, in vertex order as bounds_of takes them
        for (std::size_t v = 0; v + 12 <= buffer.size(); v += 12) {
          float p[3];
          std::memcpy(p, buffer.data() + v, 12);
          bounds.add(p);
        }
      }
    }
    std::memcpy(table.data() + kMtBlockEntryBytes * b + 8, &sum, 8);
  }

  std::vector<std::uint8_t>& out = seal.header;
  put_counts(out, 2, c);
  put32(out, c.root_vertices);
  put64(out, l.end);
  put64(out, 0);  // checksum, filled last
  put64(out, 0);  // reserved
  for (int k = 0; k < 3; ++k) put_float(out, bounds.lo[k]);
  for (int k = 0; k < 3; ++k) put_float(out, bounds.hi[k]);
  put32(out, input_triangles);
  out.resize(kMtHeaderBytes, 0);
  const std::uint64_t sum = mt_checksum(table, mt_checksum(out));  // the checksum field is still zero
  std::memcpy(out.data() + kChecksumOffset, &sum, 8);
  return seal;
}

namespace {

// Version 1, for MTs whose vertices are not in node order.
void serialize_v1(const MtCounts& c, std::vector<std::uint8_t>& out) {
  const MtLayout l = layout_after(c, kMtHeaderBytesV1);
  const std::uint64_t end = l.triangle_remover + 4 * std::uint64_t{c.triangles};
  out.clear();
  out.reserve(end);
  put_counts(out, 1, c);
  put32(out, 0);  // reserved
  put64(out, end - kMtHeaderBytesV1);
  put64(out, 0);  // checksum, filled last
  put64(out, 0);  // reserved
}

}  // namespace

MtCounts mt_counts(const Mt& mt) {
  MtCounts c;
  c.normals = mt.has_normals();
  c.colors = mt.has_colors();
  c.vertices = std::uint32_t(mt.vertex_count());
  c.nodes = std::uint32_t(mt.node_count());
  c.triangles = std::uint32_t(mt.triangle_count());
  c.root_triangles = std::uint32_t(mt.root_triangle_count());
  c.parents = std::uint32_t(mt.node_parents.size());
  c.root_vertices = mt.node_count() > 1 ? mt.node_vertex[1] : c.vertices;
  return c;
}

void serialize_mt(const Mt& mt, std::vector<std::uint8_t>& out) {
  const bool v2 = mt.vertices_in_node_order();
  const MtCounts c = mt_counts(mt);
  if (v2) {
    out.clear();
    out.reserve(mt_layout(c).end);
    out.resize(kMtHeaderBytes, 0);  // sealed below
  } else {
    serialize_v1(c, out);
  }
  put_array(out, mt.positions);
  if (c.normals) put_array(out, mt.normals);
  if (c.colors) put_array(out, mt.colors);
  put_array(out, mt.node_vertex);
  put_array(out, mt.node_error);
  put_array(out, mt.node_triangle_offsets);
  put_array(out, mt.node_parent_offsets);
  put_array(out, mt.node_parents);
  put_array(out, mt.triangle_corners);
  put_array(out, mt.root_first_corner);
  put_array(out, mt.triangle_remover);
  if (!v2) {
    const std::uint64_t sum = mt_checksum(out);  // the checksum field is still zero here
    std::memcpy(out.data() + kChecksumOffset, &sum, 8);
    return;
  }
  const MtLayout l = mt_layout(c);
  out.resize(l.end, 0);
  auto sealed = seal_mt(c, [&](std::uint64_t offset, std::span<std::uint8_t> to) -> Status {
    std::memcpy(to.data(), out.data() + offset, to.size());
    return Ok{};
  });
  // Reads stay inside the image laid out by the same counts: sealing cannot fail here.
  std::copy(sealed->header.begin(), sealed->header.end(), out.begin());
  std::copy(sealed->block_table.begin(), sealed->block_table.end(),
            out.begin() + std::ptrdiff_t(l.block_table));
}

Result<MtCounts> mt_header_counts(std::span<const std::uint8_t> bytes) {
  MTLOD_TRY(const Header h, parse_header(bytes));
  return h.counts;
}

std::uint32_t mt_file_version(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < 12 || std::memcmp(bytes.data(), kMagic, 8) != 0) return 0;
  return get32(bytes.data() + 8);
}

Result<Mt> view_mt(std::span<const std::uint8_t> bytes, std::shared_ptr<const void> storage) {
  if (reinterpret_cast<std::uintptr_t>(bytes.data()) % 4 != 0)
    return make_error(ErrorCode::kInvalidArgument, "an MT image viewed in place must be 4-byte aligned");
  MTLOD_TRY(Header h, parse_header(bytes));
  if (h.version != 2)
    return make_error(ErrorCode::kUnsupported, "MT file version " + std::to_string(h.version) +
                                                   " cannot be mapped (it is read whole)");
  MTLOD_RETURN_IF_ERROR(check_table(h, bytes));
  Mt mt = view_of(h, bytes);
  auto check = std::make_shared<BlockCheck>(h, mt, bytes);
  MTLOD_RETURN_IF_ERROR(check->check_now(0));
  MTLOD_RETURN_IF_ERROR(check_bounds(h));
  mt.adopt(std::move(storage), std::move(check));
  return mt;
}

Result<Mt> deserialize_mt(std::span<const std::uint8_t> bytes) {
  MTLOD_TRY(Header h, parse_header(bytes));
  std::vector<std::uint8_t> aligned;  // version 2 is checked through views that read u32/f32 in place
  if (h.version == 2 && reinterpret_cast<std::uintptr_t>(bytes.data()) % 4 != 0) {
    aligned.assign(bytes.begin(), bytes.end());
    bytes = aligned;
  }
  if (h.version == 2) {
    MTLOD_RETURN_IF_ERROR(check_table(h, bytes));
    const Mt view = view_of(h, bytes);
    for (std::uint32_t b = 0; b < mt_block_count(h.counts.nodes); ++b)
      MTLOD_RETURN_IF_ERROR(check_block(h, view, bytes, b));
    MTLOD_RETURN_IF_ERROR(check_bounds(h));
    Mt mt(view.arrays());
    // The header's summary, as a mapped view of the same file has it.
    mt.bounds = h.bounds;
    mt.input_triangles = h.input_triangles;
    return mt;
  }
  // Version 1: one checksum over the whole image with its own field read as zero.
  if (checksum_without_field(bytes) != get64(bytes.data() + kChecksumOffset))
    return corrupt("checksum mismatch (the file was altered or damaged)");
  const MtCounts& c = h.counts;
  MtArrays a;
  const std::uint8_t* cursor = bytes.data() + kMtHeaderBytesV1;
  const std::uint64_t v = c.vertices, n = c.nodes;
  take_array(cursor, 3 * v, a.positions);
  if (c.normals) take_array(cursor, 3 * v, a.normals);
  if (c.colors) take_array(cursor, 3 * v, a.colors);
  take_array(cursor, n, a.node_vertex);
  take_array(cursor, n, a.node_error);
  take_array(cursor, n + 1, a.node_triangle_offsets);
  take_array(cursor, n + 1, a.node_parent_offsets);
  take_array(cursor, c.parents, a.node_parents);
  take_array(cursor, 2 * std::uint64_t{c.triangles}, a.triangle_corners);
  take_array(cursor, c.root_triangles, a.root_first_corner);
  take_array(cursor, c.triangles, a.triangle_remover);
  Mt mt(std::move(a));
  const NodeRange whole{0, n, 0, c.triangles, 0, c.parents, 0, v};
  MTLOD_RETURN_IF_ERROR(check_nodes(mt, whole, std::nullopt));
  return mt;
}

}  // namespace mtlod::core::model

// .mt file format (DESIGN.md §2 "Storage"; byte layout in core/FORMAT.md). Untrusted input: every
// size is checked before a read, in 64-bit arithmetic, and every index before it is trusted.
#include "core/mt_format.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <string>

namespace mtlod::core {
namespace {

static_assert(std::endian::native == std::endian::little,
              "the .mt format is little-endian and read by memcpy; add byte swapping for big-endian hosts");

constexpr char kMagic[8] = {'M', 'T', 'L', 'O', 'D', 'M', 'T', '\0'};
constexpr std::uint32_t kFlagNormals = 1u << 0;
constexpr std::uint32_t kFlagColors = 1u << 1;
// The checksum field sits inside the checksummed bytes and is read as zero, so writers fill it last.
constexpr std::uint64_t kChecksumOffset = kMtChecksumOffset;
constexpr std::uint64_t kFnvPrime = 0x100000001b3ull;

// Every array starts 4-byte aligned so a memory map can be read as u32/f32 arrays in place.
std::uint64_t pad4(std::uint64_t n) {
  return (n + 3) & ~std::uint64_t{3};
}

struct Counts {
  std::uint32_t flags = 0;
  std::uint32_t vertices = 0;
  std::uint32_t nodes = 0;
  std::uint32_t triangles = 0;
  std::uint32_t root_triangles = 0;
  std::uint32_t parents = 0;
};

// Payload bytes implied by the counts (each array 4-byte aligned).
std::uint64_t payload_bytes(const Counts& c) {
  const std::uint64_t v = c.vertices, n = c.nodes, t = c.triangles;
  std::uint64_t bytes = 12 * v;                                  // positions
  if (c.flags & kFlagNormals) bytes += 12 * v;                   // normals
  if (c.flags & kFlagColors) bytes += pad4(3 * v);               // colours
  bytes += 4 * n + 4 * n + 4 * (n + 1) + 4 * (n + 1);            // vertex, error, triangle and parent offsets
  bytes += 4 * std::uint64_t{c.parents};                         // parents
  bytes += 8 * t + 4 * std::uint64_t{c.root_triangles} + 4 * t;  // corners, root corners, removers
  return bytes;
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
template <class T>
void put_array(std::vector<std::uint8_t>& out, const std::vector<T>& a) {
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

Error corrupt(std::string message) {
  return make_error(ErrorCode::kCorrupt, "corrupt MT file: " + std::move(message));
}

Status validate(const Mt& mt) {
  const std::uint64_t v = mt.vertex_count(), n = mt.node_count(), t = mt.triangle_count();
  for (std::uint64_t i = 0; i < mt.positions.size(); ++i)
    if (!std::isfinite(mt.positions[i])) return corrupt("positions[" + std::to_string(i) + "] is not finite");
  if (mt.node_vertex[0] != kNoVertex) return corrupt("node_vertex[0] of the root is not the none marker");
  for (std::uint64_t i = 1; i < n; ++i)
    if (mt.node_vertex[i] >= v)
      return corrupt("node_vertex[" + std::to_string(i) + "] = " + std::to_string(mt.node_vertex[i]) +
                     " >= vertex count " + std::to_string(v));
  for (std::uint64_t i = 0; i < n; ++i)
    if (!(mt.node_error[i] >= 0.0f) || !std::isfinite(mt.node_error[i]))
      return corrupt("node_error[" + std::to_string(i) + "] is negative or not finite");
  // Sorted by decreasing error, so with parents before children errors never grow from a node to
  // its children; refinement relies on both.
  for (std::uint64_t i = 2; i < n; ++i)
    if (mt.node_error[i] > mt.node_error[i - 1])
      return corrupt("node_error[" + std::to_string(i) + "] is larger than node_error[" +
                     std::to_string(i - 1) + "] (nodes must be sorted by decreasing error)");

  auto check_offsets = [&](const std::vector<std::uint32_t>& offsets, std::uint64_t total,
                           const char* name) -> Status {
    if (offsets[0] != 0) return corrupt(std::string(name) + "[0] is not 0");
    for (std::uint64_t i = 0; i < n; ++i)
      if (offsets[i + 1] < offsets[i])
        return corrupt(std::string(name) + " decrease at node " + std::to_string(i));
    if (offsets[n] != total)
      return corrupt(std::string(name) + " end at " + std::to_string(offsets[n]) + ", expected " +
                     std::to_string(total));
    return Ok{};
  };
  MTLOD_RETURN_IF_ERROR(check_offsets(mt.node_triangle_offsets, t, "node_triangle_offsets"));
  MTLOD_RETURN_IF_ERROR(check_offsets(mt.node_parent_offsets, mt.node_parents.size(), "node_parent_offsets"));
  // Root triangles keep their first corner apart (they have no split vertex); the counts must agree.
  if (mt.node_triangle_offsets[1] != mt.root_triangle_count())
    return corrupt("root creates " + std::to_string(mt.node_triangle_offsets[1]) + " triangles but " +
                   std::to_string(mt.root_triangle_count()) + " root corners are stored");
  if (mt.node_parent_offsets[1] != 0) return corrupt("the root has parents");

  // DAG order: parents strictly increasing and smaller than their child; every node has one. This
  // also bounds the ancestor walk of refinement (ids only decrease along it).
  for (std::uint64_t i = 1; i < n; ++i) {
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
  for (std::uint64_t i = 0; i < 2 * t; ++i)
    if (mt.triangle_corners[i] >= v)
      return corrupt("triangle_corners[" + std::to_string(i) + "] = " +
                     std::to_string(mt.triangle_corners[i]) + " >= vertex count " + std::to_string(v));
  for (std::uint64_t i = 0; i < mt.root_triangle_count(); ++i)
    if (mt.root_first_corner[i] >= v)
      return corrupt("root_first_corner[" + std::to_string(i) + "] >= vertex count " + std::to_string(v));
  // Each triangle's remover comes after its creator and lists the creator as a parent: refinement
  // adds a node after its parents and then expects everything the node removes to be in the mesh.
  for (std::uint64_t c = 0; c < n; ++c) {
    for (std::uint32_t k = mt.node_triangle_offsets[c]; k < mt.node_triangle_offsets[c + 1]; ++k) {
      const std::uint32_t r = mt.triangle_remover[k];
      if (r == kNoNode) continue;
      if (r >= n || r <= c)
        return corrupt("triangle " + std::to_string(k) + " of node " + std::to_string(c) + " has remover " +
                       std::to_string(r) + " outside (" + std::to_string(c) + ", " + std::to_string(n) + ")");
      const auto* begin = mt.node_parents.data() + mt.node_parent_offsets[r];
      const auto* end = mt.node_parents.data() + mt.node_parent_offsets[r + 1];
      const auto* it = std::lower_bound(begin, end, std::uint32_t(c));
      if (it == end || *it != c)
        return corrupt("node " + std::to_string(r) + " removes triangle " + std::to_string(k) + " of node " +
                       std::to_string(c) + " without listing it as a parent");
    }
  }
  return Ok{};
}

}  // namespace

std::uint64_t mt_checksum(std::span<const std::uint8_t> bytes, std::uint64_t seed) {
  std::uint64_t h = seed;
  std::size_t i = 0;
  for (; i + 8 <= bytes.size(); i += 8) h = (h ^ get64(bytes.data() + i)) * kFnvPrime;
  for (; i < bytes.size(); ++i) h = (h ^ bytes[i]) * kFnvPrime;
  return h;
}

namespace {

Counts counts_of(const MtCounts& m) {
  Counts c;
  c.flags = (m.normals ? kFlagNormals : 0) | (m.colors ? kFlagColors : 0);
  c.vertices = m.vertices;
  c.nodes = m.nodes;
  c.triangles = m.triangles;
  c.root_triangles = m.root_triangles;
  c.parents = m.parents;
  return c;
}

}  // namespace

MtLayout mt_layout(const MtCounts& counts) {
  const Counts c = counts_of(counts);
  const std::uint64_t v = c.vertices, n = c.nodes, t = c.triangles;
  MtLayout l{};
  l.positions = kMtHeaderBytes;
  l.normals = l.positions + 12 * v;
  l.colors = l.normals + (counts.normals ? 12 * v : 0);
  l.node_vertex = l.colors + (counts.colors ? pad4(3 * v) : 0);
  l.node_error = l.node_vertex + 4 * n;
  l.node_triangle_offsets = l.node_error + 4 * n;
  l.node_parent_offsets = l.node_triangle_offsets + 4 * (n + 1);
  l.node_parents = l.node_parent_offsets + 4 * (n + 1);
  l.triangle_corners = l.node_parents + 4 * std::uint64_t{c.parents};
  l.root_first_corner = l.triangle_corners + 8 * t;
  l.triangle_remover = l.root_first_corner + 4 * std::uint64_t{c.root_triangles};
  l.end = l.triangle_remover + 4 * t;
  return l;
}

std::array<std::uint8_t, kMtHeaderBytes> mt_header(const MtCounts& counts) {
  const Counts c = counts_of(counts);
  std::vector<std::uint8_t> out;
  out.resize(8);
  std::memcpy(out.data(), kMagic, 8);
  put32(out, kMtFormatVersion);
  put32(out, c.flags);
  put32(out, c.vertices);
  put32(out, c.nodes);
  put32(out, c.triangles);
  put32(out, c.root_triangles);
  put32(out, c.parents);
  put32(out, 0);  // reserved
  put64(out, payload_bytes(c));
  put64(out, 0);  // checksum, filled last
  put64(out, 0);  // reserved
  std::array<std::uint8_t, kMtHeaderBytes> header;
  std::copy(out.begin(), out.end(), header.begin());
  return header;
}

void serialize_mt(const Mt& mt, std::vector<std::uint8_t>& out) {
  MtCounts counts;
  counts.normals = mt.has_normals();
  counts.colors = mt.has_colors();
  counts.vertices = std::uint32_t(mt.vertex_count());
  counts.nodes = std::uint32_t(mt.node_count());
  counts.triangles = std::uint32_t(mt.triangle_count());
  counts.root_triangles = std::uint32_t(mt.root_triangle_count());
  counts.parents = std::uint32_t(mt.node_parents.size());
  const Counts c = counts_of(counts);
  const auto header = mt_header(counts);
  out.clear();
  out.reserve(kMtHeaderBytes + payload_bytes(c));
  out.assign(header.begin(), header.end());
  put_array(out, mt.positions);
  if (c.flags & kFlagNormals) put_array(out, mt.normals);
  if (c.flags & kFlagColors) put_array(out, mt.colors);
  put_array(out, mt.node_vertex);
  put_array(out, mt.node_error);
  put_array(out, mt.node_triangle_offsets);
  put_array(out, mt.node_parent_offsets);
  put_array(out, mt.node_parents);
  put_array(out, mt.triangle_corners);
  put_array(out, mt.root_first_corner);
  put_array(out, mt.triangle_remover);
  const std::uint64_t sum = mt_checksum(out);  // the checksum field is still zero here
  std::memcpy(out.data() + kChecksumOffset, &sum, 8);
}

Result<Mt> deserialize_mt(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < kMtHeaderBytes)
    return corrupt("file of " + std::to_string(bytes.size()) + " bytes is shorter than the " +
                   std::to_string(kMtHeaderBytes) + "-byte header");
  const std::uint8_t* p = bytes.data();
  if (std::memcmp(p, kMagic, 8) != 0) return corrupt("bad magic (not an mtlod MT file)");
  const std::uint32_t version = get32(p + 8);
  if (version != kMtFormatVersion)
    return make_error(ErrorCode::kUnsupported, "MT file version " + std::to_string(version) +
                                                   " is not supported (this build reads version " +
                                                   std::to_string(kMtFormatVersion) + ")");
  Counts c;
  c.flags = get32(p + 12);
  c.vertices = get32(p + 16);
  c.nodes = get32(p + 20);
  c.triangles = get32(p + 24);
  c.root_triangles = get32(p + 28);
  c.parents = get32(p + 32);
  if (c.flags & ~(kFlagNormals | kFlagColors)) return corrupt("unknown flags " + std::to_string(c.flags));
  if (get32(p + 36) != 0 || get64(p + 56) != 0) return corrupt("reserved header fields are not zero");
  if (c.nodes == 0) return corrupt("node count is 0 (the root is missing)");
  if (c.nodes == kNoNode) return corrupt("node count " + std::to_string(c.nodes) + " exceeds the id range");
  if (c.root_triangles > c.triangles)
    return corrupt("root triangle count " + std::to_string(c.root_triangles) + " > triangle count " +
                   std::to_string(c.triangles));
  const std::uint64_t stated = get64(p + 40);
  const std::uint64_t expected = payload_bytes(c);
  if (stated != expected)
    return corrupt("payload size field " + std::to_string(stated) + " does not match the counts (" +
                   std::to_string(expected) + " bytes)");
  if (bytes.size() - kMtHeaderBytes != expected)
    return corrupt("payload has " + std::to_string(bytes.size() - kMtHeaderBytes) + " bytes, counts need " +
                   std::to_string(expected) +
                   (bytes.size() - kMtHeaderBytes < expected ? " (truncated)" : ""));
  // Checksum over the whole image with its own field read as zero.
  const std::uint64_t stored = get64(p + kChecksumOffset);
  std::uint64_t sum = mt_checksum(bytes.subspan(0, kChecksumOffset));
  const std::uint8_t zeros[8] = {};
  sum = mt_checksum(std::span<const std::uint8_t>(zeros, 8), sum);
  sum = mt_checksum(bytes.subspan(kChecksumOffset + 8), sum);
  if (sum != stored) return corrupt("checksum mismatch (the file was altered or damaged)");

  Mt mt;
  const std::uint8_t* cursor = p + kMtHeaderBytes;
  const std::uint64_t v = c.vertices, n = c.nodes;
  take_array(cursor, 3 * v, mt.positions);
  if (c.flags & kFlagNormals) take_array(cursor, 3 * v, mt.normals);
  if (c.flags & kFlagColors) take_array(cursor, 3 * v, mt.colors);
  take_array(cursor, n, mt.node_vertex);
  take_array(cursor, n, mt.node_error);
  take_array(cursor, n + 1, mt.node_triangle_offsets);
  take_array(cursor, n + 1, mt.node_parent_offsets);
  take_array(cursor, c.parents, mt.node_parents);
  take_array(cursor, 2 * std::uint64_t{c.triangles}, mt.triangle_corners);
  take_array(cursor, c.root_triangles, mt.root_first_corner);
  take_array(cursor, c.triangles, mt.triangle_remover);
  MTLOD_RETURN_IF_ERROR(validate(mt));
  return mt;
}

}  // namespace mtlod::core

// Multi-Tessellation (core/ARCHITECTURE.md §2): nodes in topological order (node 0 = root, which
// creates the coarsest mesh), triangles grouped by creating node, per-triangle remover, DAG arcs in
// CSR. Struct-of-arrays with 32-bit ids, as stored in the .mt file (core/model/FORMAT.md).
//
// Compact storage (≈ 57 bytes per input triangle on real scans, and 12 per vertex, about 6 per
// triangle, for the normals every MT has):
// - every node n ≥ 1 undoes one half-edge collapse u→v, so all triangles it creates contain its split
//   vertex u = node_vertex[n]; a triangle stores only its two other corners, in counter-clockwise
//   order after u. Root triangles keep their first corner in root_first_corner.
// - all triangles a node removes were created by the same collapse and share one error, so errors are
//   per node: error(t) = node_error[triangle_remover[t]], and 0 for triangles of the input (never
//   removed).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include "core/model/bounds.hpp"
#include "core/result.hpp"

namespace mtlod::core::model {

inline constexpr std::uint32_t kNoNode = std::numeric_limits<std::uint32_t>::max();
// "None" for a vertex or a face index (the same value: ids of each kind stay below it).
inline constexpr std::uint32_t kNoVertex = std::numeric_limits<std::uint32_t>::max();
inline constexpr std::uint32_t kNoFace = std::numeric_limits<std::uint32_t>::max();

// Distinct id types where node, triangle and vertex ids meet in one signature.
struct NodeId {
  std::uint32_t value = 0;
};
struct TriangleId {
  std::uint32_t value = 0;
};

// The arrays of an MT, owned: what a builder fills and what tests alter. Mt views them.
struct MtArrays {
  std::vector<float> positions;
  std::vector<float> normals;
  std::vector<std::uint8_t> colors;
  std::vector<std::uint32_t> node_vertex;
  std::vector<float> node_error;
  std::vector<std::uint32_t> node_triangle_offsets;
  std::vector<std::uint32_t> node_parent_offsets;
  std::vector<std::uint32_t> node_parents;
  std::vector<std::uint32_t> triangle_corners;
  std::vector<std::uint32_t> root_first_corner;
  std::vector<std::uint32_t> triangle_remover;
};

// Checks a mapped file's node blocks (nodes [b·kMtBlockNodes, (b+1)·kMtBlockNodes), with their
// triangles, parents and split vertices) the first time a refinement reaches them.
inline constexpr std::uint32_t kMtBlockShift = 12;
inline constexpr std::uint32_t kMtBlockNodes = 1u << kMtBlockShift;
class MtBlockCheck {
 public:
  virtual ~MtBlockCheck() = default;
  // Whether node n's block is valid (checked now if it was not yet). A refinement that meets an
  // invalid block stops adding nodes and fails with check(node)'s error; so does every later one
  // that reaches the block.
  [[nodiscard]] bool require(std::uint32_t node) const {
    const std::uint32_t b = node >> kMtBlockShift;
    return (b < block_count_ && state_[b].load(std::memory_order_acquire) == kValid) || check_block(b).ok();
  }
  // Why node n's block fails its check (kCorrupt), or Ok.
  Status check(std::uint32_t node) const { return check_block(node >> kMtBlockShift); }

 protected:
  static constexpr std::uint8_t kValid = 1;
  explicit MtBlockCheck(std::uint32_t blocks)
      : block_count_(blocks), state_(std::make_unique<std::atomic<std::uint8_t>[]>(blocks)) {}
  // Validates block b (idempotent: two threads may both do it) and stores kValid, or says why not.
  virtual Status check_block(std::uint32_t b) const = 0;
  std::uint32_t block_count_;
  std::unique_ptr<std::atomic<std::uint8_t>[]> state_;
};

// The Multi-Tessellation as read-only arrays: views of MtArrays it owns, or of a memory-mapped file
// (core/io/mt_file.hpp) whose blocks are checked on first use. Copies share the storage.
struct Mt {
  // Vertices: every vertex of the input. build_mt numbers them as the nodes reach them (the root
  // mesh's vertices first, then node n's split vertex as root vertices + n − 1, then any vertex no
  // triangle uses) and reports each input vertex's id. Files of format 1 may number them otherwise.
  std::span<const float> positions;      // x, y, z per vertex
  std::span<const float> normals;        // empty, or x, y, z per vertex
  std::span<const std::uint8_t> colors;  // empty, or r, g, b per vertex

  // Nodes (node_count() of them), topological order: every parent has a smaller id.
  std::span<const std::uint32_t> node_vertex;  // split vertex of node n ≥ 1; kNoVertex for the root
  std::span<const float> node_error;           // error of the triangles node n removes (model units)
  std::span<const std::uint32_t> node_triangle_offsets;  // node_count()+1: node n creates [off[n], off[n+1])
  std::span<const std::uint32_t> node_parent_offsets;    // node_count()+1, CSR into node_parents
  std::span<const std::uint32_t> node_parents;           // distinct creators of the triangles node n removes

  // Triangles (triangle_count() of them), grouped by creating node.
  std::span<const std::uint32_t> triangle_corners;   // 2 per triangle: corners after the first, CCW
  std::span<const std::uint32_t> root_first_corner;  // first corner of each root triangle
  std::span<const std::uint32_t> triangle_remover;   // node that removes it, or kNoNode

  // Summary, stored in the file so that a mapped model is described without reading its arrays.
  Bounds bounds;                      // of every vertex
  std::uint32_t input_triangles = 0;  // triangles no node removes: the full-resolution mesh

  Mt() = default;
  // Owns the arrays.
  explicit Mt(MtArrays arrays);
  // Makes this MT (whose spans and summary the caller set) keep `storage`, which holds the arrays,
  // alive, and have `check` check their blocks on first use.
  void adopt(std::shared_ptr<const void> storage, std::shared_ptr<const MtBlockCheck> check) {
    storage_ = std::move(storage);
    check_ = std::move(check);
  }
  // Gives an MT stored without normals computed ones (core/build/vertex_normals.hpp), which it keeps
  // alive and counts in memory_bytes() even when the rest is mapped.
  void attach_normals(std::shared_ptr<const std::vector<float>> normals) {
    attached_normals_ = std::move(normals);
    this->normals = *attached_normals_;
  }
  // A copy of the arrays, for tests and tools that alter an MT.
  MtArrays arrays() const;

  std::size_t vertex_count() const { return positions.size() / 3; }
  std::size_t node_count() const { return node_vertex.size(); }
  std::size_t triangle_count() const { return triangle_remover.size(); }
  std::size_t root_triangle_count() const { return root_first_corner.size(); }
  bool has_normals() const { return !normals.empty(); }
  bool has_colors() const { return !colors.empty(); }
  // Whether the arrays live in a mapped file (read on demand) rather than in this process's memory.
  bool mapped() const { return check_ != nullptr; }

  // Whether node n's block is valid, checked before a refinement reads its node, triangles and
  // split vertex: always for MTs in memory (validated whole when read); a mapped file's block is
  // checked on first use (MtBlockCheck).
  [[nodiscard]] bool require_node(std::uint32_t n) const { return !check_ || check_->require(n); }
  // Why node n's block is invalid (after require_node said so), or Ok.
  Status check_node(std::uint32_t n) const { return check_ ? check_->check(n) : Status(Ok{}); }

  // Error of triangle t in model units: its remover's error, or 0 for an input triangle.
  float triangle_error(std::uint32_t t) const {
    const std::uint32_t r = triangle_remover[t];
    return r == kNoNode ? 0.0f : node_error[r];
  }
  // First corner of triangle t created by node n (n must be t's creator).
  std::uint32_t first_corner(TriangleId t, NodeId n) const {
    return n.value == 0 ? root_first_corner[t.value] : node_vertex[n.value];
  }
  // Node that creates triangle t (binary search over node_triangle_offsets, O(log nodes)).
  std::uint32_t triangle_creator(std::uint32_t t) const;
  // Writes the three vertex ids of triangle t (counter-clockwise) to out.
  void triangle_vertices(std::uint32_t t, std::uint32_t out[3]) const;

  // Bytes of the arrays (sizes, not capacities): held in memory, or mapped from the file (of which
  // only the pages in use are resident, in the page cache).
  std::size_t array_bytes() const;
  std::size_t memory_bytes() const { return mapped() ? attached_bytes() : array_bytes(); }
  std::size_t mapped_bytes() const { return mapped() ? array_bytes() - attached_bytes() : 0; }
  // Whether the split vertices are numbered in node order (node n + 1's is node n's plus one), as
  // build_mt numbers them; files written before it did are valid but refine more slowly.
  bool vertices_in_node_order() const;

 private:
  std::size_t attached_bytes() const {
    return attached_normals_ ? attached_normals_->size() * sizeof(float) : 0;
  }

  std::shared_ptr<const void> storage_;
  std::shared_ptr<const MtBlockCheck> check_;
  std::shared_ptr<const std::vector<float>> attached_normals_;
};

}  // namespace mtlod::core::model

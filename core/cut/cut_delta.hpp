// What changed between two cuts sent to the same client, by MT triangle id (CutMesh::ids): the
// triangles to add and the ids to remove. A client that keeps its mesh keyed by id applies these
// instead of replacing the whole mesh, so a gaze costs in proportion to the change, not the cut.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/util/zeroed_array.hpp"

namespace mtlod::core::cut {

class CutDelta {
 public:
  // Makes `ids` the cut the client has and writes what changed since the previous call: positions
  // in `ids` of the triangles new to the client, in order, and the ids it must drop, in the order
  // it received them. ids must be distinct and below triangle_count (the MT's). Returns true when
  // the change is relative to an empty mesh: the first call, after reset(), or when
  // triangle_count differs from the previous call's (another model); the client clears its mesh.
  bool update(std::span<const std::uint32_t> ids, std::size_t triangle_count,
              std::vector<std::uint32_t>& added, std::vector<std::uint32_t>& removed);

  // The client starts again from an empty mesh (call it when the client's mesh is replaced).
  void reset();

  std::size_t memory_bytes() const {
    return sent_bits_.resident_bytes() + next_bits_.resident_bytes() +
           sent_.capacity() * sizeof(std::uint32_t);
  }

 private:
  // A moved cut keeps the triangles that stay in their order and appends the others (Refiner's
  // kept mesh: the new ones, and those of nodes dropped and forced back): one pass over both lists
  // in order finds the change, with bit reads for the appended part only. False (added and removed
  // left empty) when more than half of the client's ids are out of order, as after a restart.
  bool diff_in_order(std::span<const std::uint32_t> ids, std::vector<std::uint32_t>& added,
                     std::vector<std::uint32_t>& removed);

  util::ZeroedArray<std::uint64_t> sent_bits_;  // one bit per MT triangle: in the client's mesh
  util::ZeroedArray<std::uint64_t> next_bits_;  // scratch: in the new cut (all clear between calls)
  std::vector<std::uint32_t> sent_;             // the client's ids, in the order received
  std::size_t triangle_count_ = 0;              // of the MT the ids belong to
  bool empty_ = true;                           // the client has no mesh yet
};

// Of a cut (corners and ids as CutMesh holds them), the triangles at `positions` (update's `added`),
// in order: what a delta reply sends. Replaces `triangles` (three corners each) and `gathered_ids`.
void gather_triangles(std::span<const std::uint32_t> corners, std::span<const std::uint32_t> ids,
                      std::span<const std::uint32_t> positions, std::vector<std::uint32_t>& triangles,
                      std::vector<std::uint32_t>& gathered_ids);

}  // namespace mtlod::core::cut

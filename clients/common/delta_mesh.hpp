// A client's copy of its cut, kept across delta replies (PROTOCOL.md, "Delta replies"): triangles
// keyed by their MT triangle id, so a reply that names what was added and removed updates it in
// time proportional to the change. Checked at every step: an id added twice, removed while absent,
// or a count that differs from the server's cut is an error, never a silently wrong mesh.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "clients/common/slot_table.hpp"
#include "core/result.hpp"
#include "protocol/replies.hpp"

namespace mtlod::clients {

class DeltaMesh {
 public:
  // Applies a mesh reply that carries `delta`; its payload as received.
  Status apply(const protocol::MeshReply& reply, std::span<const std::uint8_t> payload);

  std::size_t triangle_count() const { return ids_.size(); }
  std::span<const std::uint32_t> ids() const { return ids_; }
  // Positions of the triangle in slot i (the slot of ids()[i]): 9 floats, as decoded.
  std::span<const float, 9> corners(std::size_t i) const {
    return std::span<const float, 9>(&corners_[9 * i], 9);
  }

 private:
  std::vector<std::uint32_t> ids_;
  std::vector<float> corners_;
  SlotTable slot_;  // id → index into ids_ (flat: a saccade's delta edits tens of thousands)
};

}  // namespace mtlod::clients

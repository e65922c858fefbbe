// Applying delta replies (see delta_mesh.hpp).
#include "clients/common/delta_mesh.hpp"

#include <algorithm>

#include "core/codec/cut_encoder.hpp"
#include "fmt/format.h"

namespace mtlod::clients {

Status DeltaMesh::apply(const protocol::MeshReply& reply, std::span<const std::uint8_t> payload) {
  if (!reply.delta)
    return make_error(ErrorCode::kInvalidArgument, "the reply is not a delta (ask with \"delta\": true)");
  MTLOD_TRY(const protocol::DeltaPayload parts, protocol::split_delta_payload(*reply.delta, payload));
  if (reply.delta->reset || ids_.empty()) {  // a new mesh: the table sized for what arrives
    ids_.clear();
    corners_.clear();
    slot_.reset(parts.added_ids.size());
  }
  // Each edit probes the table at a scattered place: the probes a few edits ahead (and, for a
  // removal, the probe for the triangle that moves into its slot) are fetched while this one waits.
  constexpr std::size_t kAhead = 8;
  for (std::size_t r = 0; r < parts.removed_ids.size(); ++r) {
    const std::uint32_t id = parts.removed_ids[r];
    if (r + kAhead < parts.removed_ids.size()) slot_.prefetch(parts.removed_ids[r + kAhead]);
    if (ids_.size() > kAhead) slot_.prefetch(ids_[ids_.size() - 1 - kAhead]);
    const std::size_t entry = slot_.find(id);
    if (entry == SlotTable::kAbsent) {
      return make_error(ErrorCode::kCorrupt,
                        fmt::format("the delta removes triangle {}, which the mesh does not hold", id));
    }
    // The last triangle moves into the freed slot so the arrays stay dense.
    const auto last = static_cast<std::uint32_t>(ids_.size() - 1);
    const std::uint32_t slot = slot_.erase_moving_last(entry, ids_[last]);
    if (slot != last) {
      ids_[slot] = ids_[last];
      std::copy_n(&corners_[9 * std::size_t{last}], 9, &corners_[9 * std::size_t{slot}]);
    }
    ids_.pop_back();
    corners_.resize(9 * std::size_t{last});
  }
  if (!parts.added_ids.empty()) {
    MTLOD_TRY(const core::model::Mesh m, core::codec::decode_payload(reply.codec, parts.mesh));
    if (m.triangle_count() != parts.added_ids.size()) {
      return make_error(ErrorCode::kCorrupt, fmt::format("the delta's mesh has {} triangles for {} added ids",
                                                         m.triangle_count(), parts.added_ids.size()));
    }
    for (std::size_t f = 0; f < parts.added_ids.size(); ++f) {
      const std::uint32_t id = parts.added_ids[f];
      if (id == SlotTable::kEmpty) {
        return make_error(ErrorCode::kCorrupt,
                          fmt::format("the delta adds triangle {}, not a triangle id", id));
      }
      if (f + kAhead < parts.added_ids.size()) slot_.prefetch(parts.added_ids[f + kAhead]);
      if (!slot_.try_insert(id, static_cast<std::uint32_t>(ids_.size()))) {
        return make_error(ErrorCode::kCorrupt,
                          fmt::format("the delta adds triangle {}, which the mesh already holds", id));
      }
      ids_.push_back(id);
      for (int k = 0; k < 3; ++k) {
        const float* p = &m.positions[3 * std::size_t{m.triangles[3 * f + k]}];
        corners_.insert(corners_.end(), p, p + 3);
      }
    }
  }
  if (ids_.size() != reply.triangles) {
    return make_error(ErrorCode::kCorrupt,
                      fmt::format("the mesh holds {} triangles after the delta, the server's cut {}",
                                  ids_.size(), reply.triangles));
  }
  return Ok{};
}

}  // namespace mtlod::clients

// What a client holds after each mesh reply, whatever the reply: one model's or a scene's, whole
// meshes or deltas (PROTOCOL.md, "Delta replies" and "Scenes"), in either codec. apply() decodes the
// payload as a viewer does before drawing it and checks it against the reply's header: the
// triangles of the model, or of each instance. A whole mesh is decoded and let go (a client that
// draws it would keep it); deltas are applied to the meshes they change.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "clients/common/delta_mesh.hpp"
#include "clients/common/scene_delta_mesh.hpp"
#include "core/result.hpp"
#include "protocol/replies.hpp"

namespace mtlod::clients {

class ReplyMesh {
 public:
  // Decodes `reply`'s payload, as received; an error says what did not decode or add up.
  Status apply(const protocol::MeshReply& reply, std::span<const std::uint8_t> payload);

 private:
  DeltaMesh model_;
  SceneDeltaMesh scene_;
};

}  // namespace mtlod::clients

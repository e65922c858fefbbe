// Applying a scene's delta replies (see scene_delta_mesh.hpp).
#include "clients/common/scene_delta_mesh.hpp"

#include <algorithm>
#include <optional>

#include "fmt/format.h"

namespace mtlod::clients {

bool is_delta_reply(const protocol::MeshReply& reply) {
  return reply.delta || std::any_of(reply.instances.begin(), reply.instances.end(),
                                    [](const protocol::InstanceMesh& m) { return m.delta.has_value(); });
}

Status SceneDeltaMesh::apply(const protocol::MeshReply& reply, std::span<const std::uint8_t> payload) {
  failed_ = 0;
  if (reply.instances.empty()) {
    return make_error(ErrorCode::kInvalidArgument,
                      "the reply is not a scene's (ask with \"scene\" instead of \"model\")");
  }
  auto parts = protocol::split_scene_payload(reply, payload);
  if (!parts) {
    failed_ = reply.instances.size();
    return make_error(ErrorCode::kCorrupt, parts.error().message);
  }
  // A new scene resets every instance's delta; its first replies rebuild the meshes from nothing.
  meshes_.resize(reply.instances.size());
  std::optional<Error> first;
  for (std::size_t i = 0; i < meshes_.size(); ++i) {
    const protocol::InstanceMesh& instance = reply.instances[i];
    // The fields DeltaMesh reads: the codec is the reply's, the rest the instance's.
    part_.model = instance.model;
    part_.triangles = instance.triangles;
    part_.codec = reply.codec;
    part_.delta = instance.delta;
    Status applied = meshes_[i].apply(part_, (*parts)[i]);
    if (applied) continue;
    ++failed_;
    if (!first) {
      first = Error{applied.error().code,
                    fmt::format("instance {} ({}): {}", i, instance.model, applied.error().message)};
    }
  }
  if (!first) return Ok{};
  if (failed_ > 1) first->message += fmt::format(" (and {} more instances failed)", failed_ - 1);
  return *first;
}

std::size_t SceneDeltaMesh::triangle_count() const {
  std::size_t n = 0;
  for (const DeltaMesh& m : meshes_) n += m.triangle_count();
  return n;
}

}  // namespace mtlod::clients

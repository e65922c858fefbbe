// Decoding any mesh reply (see reply_mesh.hpp).
#include "clients/common/reply_mesh.hpp"

#include "core/codec/cut_encoder.hpp"
#include "fmt/format.h"

namespace mtlod::clients {
namespace {

// One whole mesh: it decodes, and holds the triangles the header gives it.
Status decode_whole(core::codec::Codec codec, std::span<const std::uint8_t> payload,
                    std::uint64_t triangles) {
  MTLOD_TRY(const core::model::Mesh mesh, core::codec::decode_payload(codec, payload));
  if (mesh.triangle_count() != triangles) {
    return make_error(ErrorCode::kCorrupt,
                      fmt::format("the payload decodes to {} triangles, the reply says {}",
                                  mesh.triangle_count(), triangles));
  }
  return Ok{};
}

}  // namespace

Status ReplyMesh::apply(const protocol::MeshReply& reply, std::span<const std::uint8_t> payload) {
  if (is_delta_reply(reply))
    return reply.instances.empty() ? model_.apply(reply, payload) : scene_.apply(reply, payload);
  if (reply.instances.empty()) return decode_whole(reply.codec, payload, reply.triangles);
  MTLOD_TRY(const auto parts, protocol::split_scene_payload(reply, payload));
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const protocol::InstanceMesh& instance = reply.instances[i];
    if (Status decoded = decode_whole(reply.codec, parts[i], instance.triangles); !decoded) {
      return make_error(decoded.error().code,
                        fmt::format("instance {} ({}): {}", i, instance.model, decoded.error().message));
    }
  }
  return Ok{};
}

}  // namespace mtlod::clients

// A client's copies of a scene's meshes, kept across delta replies (PROTOCOL.md, "Scenes" and
// "Delta replies"): one DeltaMesh per instance, each given its instance's part of the payload and
// checked as a single model's mesh is (ids added twice or removed while absent, and a triangle count
// that differs from the reply's for that instance).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "clients/common/delta_mesh.hpp"
#include "core/result.hpp"
#include "protocol/replies.hpp"

namespace mtlod::clients {

// True when `reply` carries changes rather than whole meshes: a single model's with `delta`, or a
// scene's whose instances have it.
bool is_delta_reply(const protocol::MeshReply& reply);

class SceneDeltaMesh {
 public:
  // Applies a scene's delta reply (instances, each with `delta`); its payload as received. Instance
  // i's part goes to instance i's mesh; a reply with another number of instances (a new scene, whose
  // deltas reset) resizes the scene first. Every instance is applied even when one fails, so the
  // others stay the server's; the error names the first that failed and failed_instances() says how
  // many did. A payload that does not split into the instances' parts changes nothing and counts
  // every instance as failed.
  Status apply(const protocol::MeshReply& reply, std::span<const std::uint8_t> payload);

  // Instances whose mesh failed in the last apply().
  std::size_t failed_instances() const { return failed_; }
  std::size_t instance_count() const { return meshes_.size(); }
  const DeltaMesh& instance(std::size_t i) const { return meshes_[i]; }
  // The triangles of every instance's mesh together.
  std::size_t triangle_count() const;

 private:
  std::vector<DeltaMesh> meshes_;
  protocol::MeshReply part_;  // one instance's reply, handed to its DeltaMesh (reused)
  std::size_t failed_ = 0;
};

}  // namespace mtlod::clients

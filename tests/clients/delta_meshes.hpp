// What the attribute tests (colours, normals) do with delta replies: a delta extract, then gazes
// across the view; every reply that adds triangles has its Draco part decoded by Google's
// draco_decoder and handed to a check.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <optional>
#include <string>

#include "clients/common/server_connection.hpp"
#include "core/model/mesh.hpp"
#include "protocol/frame.hpp"
#include "tests/core/googles_draco_decoder.hpp"

namespace mtlod::test {

// Sends `first` with delta on, then a gaze at (x, 0.5) for each x; returns how many replies added
// triangles (each decoded and checked as `check(mesh, added, what)`).
inline std::size_t check_delta_meshes(clients::ServerConnection& c, protocol::Extract first,
                                      std::initializer_list<double> gaze_xs, const std::filesystem::path& dir,
                                      const std::function<void(const core::model::Mesh&, std::uint64_t added,
                                                               const std::string& what)>& check) {
  first.delta = true;
  std::uint64_t id = 1;
  auto reply = c.call(first, id);
  std::size_t checked = 0;
  for (auto x = gaze_xs.begin();; ++x) {
    EXPECT_TRUE(reply.ok()) << reply.error().message;
    if (!reply) return checked;
    const auto* mesh = std::get_if<protocol::MeshReply>(&reply->header.reply);
    EXPECT_TRUE(mesh && mesh->delta) << reply->json;
    if (!mesh || !mesh->delta) return checked;
    if (mesh->delta->added > 0) {
      const std::string what = "delta reply " + std::to_string(id);
      auto parts = protocol::split_delta_payload(*mesh->delta, reply->payload);
      EXPECT_TRUE(parts.ok()) << parts.error().message;
      if (!parts) return checked;
      auto loaded = googles_draco_decode(parts->mesh, dir, "delta" + std::to_string(id));
      EXPECT_TRUE(loaded.ok()) << loaded.error().message;
      if (!loaded) return checked;
      check(*loaded, mesh->delta->added, what);
      ++checked;
    }
    if (x == gaze_xs.end()) return checked;
    reply = c.call(protocol::Gaze{*x, 0.5, std::nullopt, std::nullopt}, ++id);
  }
}

}  // namespace mtlod::test

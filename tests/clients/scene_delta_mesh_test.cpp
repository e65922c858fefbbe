// A scene's meshes kept across delta replies (clients/common/scene_delta_mesh.hpp): hand-made replies
// whose parts do or do not hold up, and the real server's replies to a scene extract and its gazes,
// which must rebuild, instance by instance, the very cuts a fresh connection gets for the same view.
#include "clients/common/scene_delta_mesh.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "clients/common/scene_view.hpp"
#include "clients/common/server_connection.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mesh_io.hpp"
#include "tests/clients/served_bunny.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/server/server_process.hpp"

namespace mtlod {
namespace {

// An instance's part of a delta payload holding only ids (nothing added needs no mesh part).
protocol::InstanceMesh ids_only(const std::string& model, std::uint64_t triangles, bool reset,
                                const std::vector<std::uint32_t>& removed,
                                std::vector<std::uint8_t>& payload) {
  protocol::InstanceMesh m;
  m.model = model;
  m.triangles = triangles;
  m.delta = protocol::MeshDelta{reset, 0, 0, removed.size()};
  m.bytes = 4 * removed.size();
  protocol::append_delta_ids({}, removed, payload);
  return m;
}

TEST(SceneDeltaMesh, RefusesWhatIsNotASceneDelta) {
  clients::SceneDeltaMesh kept;
  // A single model's delta is DeltaMesh's, not a scene's.
  protocol::MeshReply single;
  single.delta = protocol::MeshDelta{true, 0, 0, 0};
  EXPECT_FALSE(kept.apply(single, {}).ok());
  EXPECT_TRUE(clients::is_delta_reply(single));

  // A scene's whole meshes (no delta) cannot update a kept mesh: every instance fails.
  protocol::MeshReply whole;
  whole.instances.resize(2);
  whole.instances[0].model = whole.instances[1].model = "a";
  EXPECT_FALSE(clients::is_delta_reply(whole));
  const auto refused = kept.apply(whole, {});
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(kept.failed_instances(), 2u);
  EXPECT_NE(refused.error().message.find("instance 0 (a): the reply is not a delta"), std::string::npos)
      << refused.error().message;
  EXPECT_NE(refused.error().message.find("and 1 more instances failed"), std::string::npos);

  // Parts that do not add up to the payload: nothing applies.
  std::vector<std::uint8_t> payload;
  protocol::MeshReply scene;
  scene.instances = {ids_only("a", 0, true, {}, payload), ids_only("b", 0, true, {}, payload)};
  scene.instances[1].bytes = 4;  // the payload holds no byte for it
  EXPECT_TRUE(clients::is_delta_reply(scene));
  EXPECT_FALSE(kept.apply(scene, payload).ok());
  EXPECT_EQ(kept.failed_instances(), 2u);
}

TEST(SceneDeltaMesh, NamesTheInstanceThatFailsAndKeepsTheOthers) {
  clients::SceneDeltaMesh kept;
  std::vector<std::uint8_t> payload;
  protocol::MeshReply first;
  first.instances = {ids_only("a", 0, true, {}, payload), ids_only("b", 0, true, {}, payload)};
  ASSERT_TRUE(kept.apply(first, payload).ok());
  EXPECT_EQ(kept.instance_count(), 2u);
  EXPECT_EQ(kept.failed_instances(), 0u);

  // Instance 1 drops triangle 7, which it never had; instance 0 is applied all the same.
  payload.clear();
  protocol::MeshReply second;
  second.instances = {ids_only("a", 0, false, {}, payload), ids_only("b", 0, false, {7}, payload)};
  const auto applied = kept.apply(second, payload);
  ASSERT_FALSE(applied.ok());
  EXPECT_EQ(kept.failed_instances(), 1u);
  EXPECT_EQ(applied.error().message,
            "instance 1 (b): the delta removes triangle 7, which the mesh does not hold");

  // A count the kept mesh does not reach is a failure of that instance alone.
  payload.clear();
  protocol::MeshReply third;
  third.instances = {ids_only("a", 3, false, {}, payload), ids_only("b", 0, true, {}, payload)};
  const auto short_count = kept.apply(third, payload);
  ASSERT_FALSE(short_count.ok());
  EXPECT_EQ(kept.failed_instances(), 1u);
  EXPECT_EQ(short_count.error().message,
            "instance 0 (a): the mesh holds 0 triangles after the delta, the server's cut 3");

  // A scene of three instances (a new extract: every delta resets) takes the place of the two.
  payload.clear();
  protocol::MeshReply bigger;
  for (const char* name : {"a", "b", "c"}) bigger.instances.push_back(ids_only(name, 0, true, {}, payload));
  ASSERT_TRUE(kept.apply(bigger, payload).ok());
  EXPECT_EQ(kept.instance_count(), 3u);
}

// The real server serving the bunny (or a stand-in of that name), for the round trips.
class SceneDeltaMeshServerTest : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::filesystem::path(test::scratch_dir("scene-delta-mesh"));
    test::put_bunny(*dir_);
    server_ = new test::ServerProcess({"--mesh", (*dir_ / "bunny.ply").string(), "--cache-dir",
                                       dir_->string(), "--workers", "2", "--log-level", "warn"},
                                      *dir_);
  }
  static void TearDownTestSuite() {
    delete server_;
    delete dir_;
  }

  static clients::ServerConnection connect() {
    auto c = clients::ServerConnection::open("127.0.0.1", server_->port());
    EXPECT_TRUE(c.ok()) << c.error().message;
    return std::move(*c);
  }

  static std::filesystem::path* dir_;
  static test::ServerProcess* server_;
};
std::filesystem::path* SceneDeltaMeshServerTest::dir_ = nullptr;
test::ServerProcess* SceneDeltaMeshServerTest::server_ = nullptr;

TEST_F(SceneDeltaMeshServerTest, GazesRebuildTheCutsAFreshConnectionGets) {
  ASSERT_TRUE(server_->running()) << server_->log();
  // Three bunnies, scaled, turned and moved apart, seen through the default criteria with deltas.
  const std::vector<protocol::Instance> instances = {
      {"bunny", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}},
      {"bunny", {0.5, 0, 0, 0, 0, 0.5, 0, 0, 0, 0, 0.5, 0, 12, 0, -4, 1}},
      {"bunny", {0, 0, -1.5, 0, 0, 1.5, 0, 0, 1.5, 0, 0, 0, -14, 1, 0, 1}},
  };
  clients::ExtractFlags flags;
  flags.budget = 3000;
  flags.delta = true;
  clients::apply_default_criteria(flags);
  clients::ServerConnection c = connect();
  auto view = clients::describe_scene(c, "three bunnies", instances, flags);
  ASSERT_TRUE(view.ok()) << view.error().message;

  const auto as_mesh = [](const auto& reply) {
    return std::get_if<protocol::MeshReply>(&reply->header.reply);
  };
  clients::SceneDeltaMesh kept;
  auto first = c.call(view->extract, 1);
  ASSERT_TRUE(first.ok()) << first.error().message;
  ASSERT_NE(as_mesh(first), nullptr) << first->json;
  ASSERT_TRUE(kept.apply(*as_mesh(first), first->payload).ok());

  // A sweep of gazes across the picture, and back to a point seen before.
  const std::array<std::array<double, 2>, 6> gazes{
      {{0.2, 0.5}, {0.25, 0.55}, {0.8, 0.4}, {0.5, 0.5}, {0.5, 0.5}, {0.2, 0.5}}};
  std::size_t partial = 0;
  for (std::size_t g = 0; g < gazes.size(); ++g) {
    const std::uint64_t id = g + 2;
    auto reply = c.call(protocol::Gaze{gazes[g][0], gazes[g][1], std::nullopt, std::nullopt}, id);
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    const protocol::MeshReply* mesh = as_mesh(reply);
    ASSERT_NE(mesh, nullptr) << reply->json;
    ASSERT_EQ(mesh->instances.size(), 3u);
    const auto applied = kept.apply(*mesh, reply->payload);
    ASSERT_TRUE(applied.ok()) << "gaze " << g << ": " << applied.error().message;
    for (const protocol::InstanceMesh& i : mesh->instances) {
      ASSERT_TRUE(i.delta.has_value());
      EXPECT_FALSE(i.delta->reset) << "gaze " << g;
      partial += i.delta->added < i.triangles;
    }

    // The same view on a fresh connection: its first delta resets, so it holds the whole cuts.
    protocol::Extract fresh = view->extract;
    protocol::gaze_region(fresh.criteria).points.front() = {gazes[g][0], gazes[g][1]};
    clients::ServerConnection other = connect();
    auto whole = other.call(fresh, 1);
    ASSERT_TRUE(whole.ok()) << whole.error().message;
    ASSERT_NE(as_mesh(whole), nullptr) << whole->json;
    clients::SceneDeltaMesh reference;
    ASSERT_TRUE(reference.apply(*as_mesh(whole), whole->payload).ok());
    for (std::size_t i = 0; i < 3; ++i) {
      const clients::DeltaMesh& a = kept.instance(i);
      const clients::DeltaMesh& b = reference.instance(i);
      ASSERT_EQ(a.triangle_count(), mesh->instances[i].triangles) << "gaze " << g << " instance " << i;
      ASSERT_EQ(a.triangle_count(), b.triangle_count()) << "gaze " << g << " instance " << i;
      std::map<std::uint32_t, std::size_t> slot;
      for (std::size_t t = 0; t < b.ids().size(); ++t) slot[b.ids()[t]] = t;
      for (std::size_t t = 0; t < a.ids().size(); ++t) {
        const auto it = slot.find(a.ids()[t]);
        ASSERT_NE(it, slot.end()) << "gaze " << g << " instance " << i << ": triangle " << a.ids()[t];
        // Each model's deltas share its quantization grid: the same floats, not just close ones.
        ASSERT_TRUE(std::equal(a.corners(t).begin(), a.corners(t).end(), b.corners(it->second).begin()))
            << "gaze " << g << " instance " << i << ": triangle " << a.ids()[t];
      }
    }
  }
  EXPECT_GT(partial, 0u);  // some gazes sent an instance less than its whole cut
}

}  // namespace
}  // namespace mtlod

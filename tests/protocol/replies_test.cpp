// Replies: what the server writes, a client reads back field for field; unknown reply fields are
// ignored and broken replies are errors, never exceptions.
#include "protocol/replies.hpp"

#include <gtest/gtest.h>

#include <variant>
#include <vector>

#include "nlohmann/json.hpp"

namespace mtlod::protocol {
namespace {

TEST(Replies, MeshReplyRoundTripsWithTimingsAndFocus) {
  MeshReply m;
  m.model = "dragon";
  m.triangles = 50'000;
  m.vertices = 25'111;
  m.max_error = 0.0125;
  m.bytes = 61'234;
  m.codec = core::codec::Codec::kMeshopt;
  m.focus = std::array<double, 2>{0.25, 0.5};
  m.superseded = 3;
  m.session_bytes = 6'000'000;
  m.scratch_bytes = 4'000'000;
  m.timings = {1, 2, 3, 4, 5, 6, 7, 28};
  auto parsed = parse_reply(to_json(m, 12));
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  EXPECT_EQ(parsed->id, 12u);
  const auto& r = std::get<MeshReply>(parsed->reply);
  EXPECT_EQ(r.model, "dragon");
  EXPECT_EQ(r.triangles, 50'000u);
  EXPECT_EQ(r.max_error, 0.0125);
  EXPECT_EQ(r.codec, core::codec::Codec::kMeshopt);
  EXPECT_EQ(r.focus, m.focus);
  EXPECT_EQ(r.superseded, 3u);
  EXPECT_EQ(r.session_bytes, 6'000'000u);
  EXPECT_EQ(r.scratch_bytes, 4'000'000u);
  EXPECT_EQ(r.timings.refine_us, 6u);
  EXPECT_EQ(r.timings.total_us, 28u);
}

TEST(Replies, DeltaHeaderAndPayloadRoundTrip) {
  MeshReply m;
  m.triangles = 9;
  m.delta = MeshDelta{true, 0, 3, 2};
  const std::vector<std::uint32_t> added{7, 0xDEADBEEF, 42}, removed{1, 65'536};
  std::vector<std::uint8_t> payload{1, 2, 3, 4, 5};  // stands for the mesh part
  m.delta->payload_bytes = payload.size();
  append_delta_ids(added, removed, payload);
  auto parsed = parse_reply(to_json(m, 1));
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  const auto& r = std::get<MeshReply>(parsed->reply);
  ASSERT_TRUE(r.delta);
  EXPECT_TRUE(r.delta->reset);
  auto parts = split_delta_payload(*r.delta, payload);
  ASSERT_TRUE(parts.ok()) << parts.error().message;
  EXPECT_EQ(std::vector<std::uint8_t>(parts->mesh.begin(), parts->mesh.end()),
            (std::vector<std::uint8_t>{1, 2, 3, 4, 5}));
  EXPECT_EQ(parts->added_ids, added);
  EXPECT_EQ(parts->removed_ids, removed);
  EXPECT_FALSE(std::get<MeshReply>(parse_reply(to_json(MeshReply{}, 1))->reply).delta);
}

TEST(Replies, ASceneReplyCarriesItsInstancesAndSplitsItsPayload) {
  MeshReply m;
  m.triangles = 30;
  m.bytes = 9;
  m.within_budget = false;
  m.instances = {{"bunny", 10, 7, 0.5, 4, std::nullopt},
                 {"dragon", 20, 12, 0.25, 5, MeshDelta{true, 1, 1, 0}}};
  auto parsed = parse_reply(to_json(m, 6));
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  const auto& r = std::get<MeshReply>(parsed->reply);
  ASSERT_EQ(r.instances.size(), 2u);
  EXPECT_EQ(r.instances[0].model, "bunny");
  EXPECT_EQ(r.instances[1].triangles, 20u);
  EXPECT_EQ(r.instances[1].max_error, 0.25);
  EXPECT_FALSE(r.instances[0].delta);
  ASSERT_TRUE(r.instances[1].delta);
  EXPECT_EQ(r.instances[1].delta->added, 1u);
  EXPECT_FALSE(r.within_budget);
  const std::vector<std::uint8_t> payload{1, 2, 3, 4, 5, 6, 7, 8, 9};
  auto parts = split_scene_payload(r, payload);
  ASSERT_TRUE(parts.ok()) << parts.error().message;
  ASSERT_EQ(parts->size(), 2u);
  EXPECT_EQ(std::vector<std::uint8_t>((*parts)[1].begin(), (*parts)[1].end()),
            (std::vector<std::uint8_t>{5, 6, 7, 8, 9}));
  // Sizes that do not add up to the payload's are refused, one byte either way.
  for (const std::size_t size : {8u, 10u}) {
    const std::vector<std::uint8_t> wrong(size);
    EXPECT_FALSE(split_scene_payload(r, wrong).ok()) << size;
  }
  MeshReply huge = r;
  huge.instances[0].bytes = UINT64_MAX;
  EXPECT_FALSE(split_scene_payload(huge, payload).ok());
  EXPECT_TRUE(std::get<MeshReply>(parse_reply(to_json(MeshReply{}, 1))->reply).instances.empty());
}

TEST(Replies, ADeltaFromAServerThatNamedItsMeshDracoBytesStillReads) {
  auto parsed = parse_reply(
      R"({"type":"mesh","id":2,"triangles":4,"delta":{"reset":false,"draco_bytes":17,"added":2,"removed":1}})");
  ASSERT_TRUE(parsed.ok()) << parsed.error().message;
  const auto& delta = std::get<MeshReply>(parsed->reply).delta;
  ASSERT_TRUE(delta);
  EXPECT_EQ(delta->payload_bytes, 17u);
  EXPECT_EQ(delta->added, 2u);
  // And a reply of this server names it both ways, for those clients.
  MeshReply m;
  m.delta = MeshDelta{false, 23, 1, 0};
  const auto json = nlohmann::json::parse(to_json(m, 3));
  EXPECT_EQ(json["delta"]["payload_bytes"], 23);
  EXPECT_EQ(json["delta"]["draco_bytes"], 23);
}

TEST(Replies, DeltaPayloadWhoseSizesDoNotAddUpIsRejected) {
  std::vector<std::uint8_t> payload(5 + 4 * 5);
  EXPECT_TRUE(split_delta_payload({false, 5, 3, 2}, payload).ok());
  EXPECT_FALSE(split_delta_payload({false, 5, 3, 3}, payload).ok());               // one id short
  EXPECT_FALSE(split_delta_payload({false, 6, 3, 2}, payload).ok());               // one byte short
  EXPECT_FALSE(split_delta_payload({false, 0, 0, 0}, payload).ok());               // bytes left over
  EXPECT_FALSE(split_delta_payload({false, 5, UINT64_MAX / 2, 2}, payload).ok());  // would overflow
  EXPECT_FALSE(split_delta_payload({false, 25, 0, 0}, payload).ok());              // a mesh, no ids
  EXPECT_TRUE(split_delta_payload({false, 0, 0, 0}, {}).ok());                     // nothing changed
}

TEST(Replies, EveryReplyTypeKeepsItsType) {
  Limits limits;
  limits.max_grid = 1024;
  const std::vector<Reply> replies = {
      HelloReply{1, "mtlod/test", limits, "replica-1@00c0ffee", true, core::codec::Codec::kMeshopt},
      ModelsReply{{ModelSummary{"bunny", 1839, 3674, 12, 900, 4096, 0.5}}},
      ModelInfoReply{},
      MeshReply{},
      ErrorReply{ErrorKind::kNoView, "gaze needs an earlier extract"},
      CancelReply{4, true},
      StatsReply{{{"requests", 10}, {"errors", 1}}},
      Pong{},
      ReloadReply{{ModelReload{"bunny", "replaced", 2, ""}}}};
  std::vector<bool> seen(std::variant_size_v<Reply>);
  for (const Reply& reply : replies) {
    auto parsed = parse_reply(to_json(reply, 1));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(parsed->reply.index(), reply.index()) << reply_type_name(reply);
    seen[reply.index()] = true;
  }
  for (std::size_t i = 0; i < seen.size(); ++i) EXPECT_TRUE(seen[i]) << kReplyTypeNames[i] << " not tried";
  auto reload = parse_reply(to_json(replies[8], 1));
  EXPECT_EQ(std::get<ReloadReply>(reload->reply).models.at(0).version, 2u);
  auto hello = parse_reply(to_json(replies[0], 1));
  EXPECT_EQ(std::get<HelloReply>(hello->reply).limits.max_grid, 1024u);
  EXPECT_EQ(std::get<HelloReply>(hello->reply).instance, "replica-1@00c0ffee");
  EXPECT_TRUE(std::get<HelloReply>(hello->reply).auth_required);
  EXPECT_EQ(std::get<HelloReply>(hello->reply).codec, core::codec::Codec::kMeshopt);
  auto models = parse_reply(to_json(replies[1], 1));
  EXPECT_EQ(std::get<ModelsReply>(models->reply).models.at(0).root_triangles, 12u);
  auto error = parse_reply(to_json(replies[4], 1));
  EXPECT_EQ(std::get<ErrorReply>(error->reply).code, ErrorKind::kNoView);
  auto stats = parse_reply(to_json(replies[6], 1));
  EXPECT_EQ(std::get<StatsReply>(stats->reply).counters.size(), 2u);
}

TEST(Replies, ClientsIgnoreUnknownFieldsAndRejectBrokenReplies) {
  auto parsed = parse_reply(R"({"type":"pong","id":3,"added_in_a_later_version":true})");
  ASSERT_TRUE(parsed.ok());
  EXPECT_EQ(parsed->id, 3u);
  EXPECT_FALSE(parse_reply(R"({"type":"pong")").ok());
  EXPECT_FALSE(parse_reply(R"({"type":"warp"})").ok());
  EXPECT_FALSE(parse_reply(R"({"type":"mesh","triangles":"many"})").ok());
}

}  // namespace
}  // namespace mtlod::protocol

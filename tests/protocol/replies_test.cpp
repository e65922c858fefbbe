// Replies: what the server writes, a client reads back field for field; unknown reply fields are
// ignored and broken replies are errors, never exceptions.
#include "protocol/replies.hpp"

#include <gtest/gtest.h>

namespace mtlod::protocol {
namespace {

TEST(Replies, MeshReplyRoundTripsWithTimingsAndFocus) {
  MeshReply m;
  m.model = "dragon";
  m.triangles = 50'000;
  m.vertices = 25'111;
  m.max_error = 0.0125;
  m.bytes = 61'234;
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
  EXPECT_EQ(r.focus, m.focus);
  EXPECT_EQ(r.superseded, 3u);
  EXPECT_EQ(r.session_bytes, 6'000'000u);
  EXPECT_EQ(r.scratch_bytes, 4'000'000u);
  EXPECT_EQ(r.timings.refine_us, 6u);
  EXPECT_EQ(r.timings.total_us, 28u);
}

TEST(Replies, EveryReplyTypeKeepsItsType) {
  Limits limits;
  limits.max_grid = 1024;
  const std::vector<Reply> replies = {HelloReply{1, "mtlod/test", limits, "replica-1@00c0ffee"},
                                      ModelsReply{{ModelSummary{"bunny", 1839, 3674, 12, 900, 4096, 0.5}}},
                                      ModelInfoReply{},
                                      MeshReply{},
                                      ErrorReply{ErrorKind::kNoView, "gaze needs an earlier extract"},
                                      CancelReply{4, true},
                                      StatsReply{{{"requests", 10}, {"errors", 1}}},
                                      Pong{}};
  for (const Reply& reply : replies) {
    auto parsed = parse_reply(to_json(reply, 1));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(parsed->reply.index(), reply.index()) << reply_type_name(reply);
  }
  auto hello = parse_reply(to_json(replies[0], 1));
  EXPECT_EQ(std::get<HelloReply>(hello->reply).limits.max_grid, 1024u);
  EXPECT_EQ(std::get<HelloReply>(hello->reply).instance, "replica-1@00c0ffee");
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

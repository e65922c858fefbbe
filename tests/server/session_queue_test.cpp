// The per-connection policy without sockets: reply order, coalescing, cancel.
#include "server/session_queue.hpp"

#include <gtest/gtest.h>

namespace mtlod::server {
namespace {

std::vector<std::uint8_t> bytes(std::uint8_t b) {
  return {b};
}

TEST(ReplyOrder, HoldsLaterRepliesUntilEarlierOnesArrive) {
  ReplyOrder order;
  const auto a = order.open(), b = order.open(), c = order.open();
  order.fill(c, bytes(3));
  order.fill(b, bytes(2), /*mesh=*/true);
  EXPECT_FALSE(order.pop().has_value());  // a is still missing
  EXPECT_EQ(order.outstanding(), 3u);
  order.fill(a, bytes(1));
  EXPECT_EQ(order.pop()->frame, bytes(1));
  const auto second = order.pop();
  EXPECT_EQ(second->frame, bytes(2));
  EXPECT_TRUE(second->mesh) << "the mark that counts a mesh as sent travels with its frame";
  const auto third = order.pop();
  EXPECT_EQ(third->frame, bytes(3));
  EXPECT_FALSE(third->mesh);
  EXPECT_FALSE(order.pop().has_value());
  EXPECT_EQ(order.outstanding(), 0u);
}

Job job(std::uint64_t id, bool gaze) {
  Job j;
  j.seq = id;
  j.id = id;
  j.gaze = gaze;
  return j;
}

TEST(JobQueue, ANewerGazeReplacesTheQueuedGazeAndCountsIt) {
  JobQueue q;
  EXPECT_FALSE(q.push(job(1, false)));
  EXPECT_FALSE(q.push(job(2, true)));
  auto replaced = q.push(job(3, true));
  ASSERT_TRUE(replaced);
  EXPECT_EQ(replaced->id, 2u);
  replaced = q.push(job(4, true));
  ASSERT_TRUE(replaced);
  EXPECT_EQ(replaced->id, 3u);
  EXPECT_EQ(q.queued(), 2u);
  EXPECT_EQ(q.start_next()->id, 1u);
  EXPECT_FALSE(q.start_next()) << "one job at a time";
  q.finish();
  const auto last = q.start_next();
  EXPECT_EQ(last->id, 4u);
  EXPECT_EQ(last->superseded, 2u);
}

TEST(JobQueue, AGazeBehindAnExtractIsNotReplacedByTheExtract) {
  JobQueue q;
  q.push(job(1, true));
  EXPECT_FALSE(q.push(job(2, false)));
  EXPECT_FALSE(q.push(job(3, true))) << "the gaze after the extract refers to the new view";
  EXPECT_EQ(q.queued(), 3u);
}

TEST(JobQueue, CancelRemovesOnlyQueuedJobs) {
  JobQueue q;
  q.push(job(1, false));
  q.push(job(2, false));
  ASSERT_TRUE(q.start_next());
  EXPECT_FALSE(q.cancel(1)) << "running";
  EXPECT_EQ(q.cancel(2)->id, 2u);
  EXPECT_FALSE(q.cancel(2));
  EXPECT_EQ(q.drain().size(), 0u);
}

}  // namespace
}  // namespace mtlod::server

// The load tester's latency histogram against exact percentiles of the sorted values.
#include "clients/load/histogram.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

namespace mtlod::clients {
namespace {

// The exact percentile by the histogram's definition (smallest value with at least p % of the
// values at or below it), in integer arithmetic: p is given in tenths of a percent.
std::uint64_t exact_percentile(const std::vector<std::uint64_t>& sorted, std::uint64_t p_tenths) {
  const std::uint64_t n = sorted.size();
  const std::uint64_t rank = std::max<std::uint64_t>(1, (p_tenths * n + 999) / 1000);  // ceil(p/100 · n)
  return sorted[rank - 1];
}

// A bucket spans at most 1/2^kSubBits of its values: the reported value may exceed the exact one
// by that fraction, and never falls below it.
void expect_close(std::uint64_t reported, std::uint64_t exact) {
  EXPECT_GE(reported, exact);
  EXPECT_LE(reported, exact + exact / (1u << LatencyHistogram::kSubBits)) << "exact " << exact;
}

TEST(LatencyHistogram, SmallValuesAreExact) {
  // Below 2^kSubBits every value has its own bucket: 1..100 gives p50 = 50, p90 = 90, p99 = 99.
  LatencyHistogram h;
  for (std::uint64_t v = 100; v >= 1; --v) h.record(v);
  EXPECT_EQ(h.count(), 100u);
  EXPECT_EQ(h.value_at_percentile(50), 50u);
  EXPECT_EQ(h.value_at_percentile(90), 90u);
  EXPECT_EQ(h.value_at_percentile(99), 99u);
  EXPECT_EQ(h.value_at_percentile(100), 100u);
  EXPECT_EQ(h.value_at_percentile(0), 1u);
  EXPECT_EQ(h.min(), 1u);
  EXPECT_EQ(h.max(), 100u);
  EXPECT_DOUBLE_EQ(h.mean(), 50.5);
}

TEST(LatencyHistogram, EmptyReportsZero) {
  LatencyHistogram h;
  EXPECT_EQ(h.value_at_percentile(99), 0u);
  EXPECT_EQ(h.max(), 0u);
  EXPECT_EQ(h.min(), 0u);
}

TEST(LatencyHistogram, BucketsTileTheRangeWithBoundedWidth) {
  // Consecutive buckets meet without gaps, and each bucket's width is at most its lowest value
  // divided by 2^kSubBits.
  std::uint64_t next_lowest = 0;
  for (std::size_t b = 0; b < 3000; ++b) {
    const std::uint64_t highest = LatencyHistogram::highest_in_bucket(b);
    ASSERT_EQ(LatencyHistogram::bucket_of(next_lowest), b);
    ASSERT_EQ(LatencyHistogram::bucket_of(highest), b);
    if (next_lowest >= (1u << LatencyHistogram::kSubBits)) {
      ASSERT_LE(highest - next_lowest + 1, next_lowest >> LatencyHistogram::kSubBits);
    }
    next_lowest = highest + 1;
  }
  EXPECT_EQ(LatencyHistogram::bucket_of(UINT64_MAX), LatencyHistogram::bucket_of(UINT64_MAX - 1));
}

TEST(LatencyHistogram, PercentilesMatchSortedValuesOnRandomData) {
  // Log-normal latencies (µs) around 5 ms with a heavy tail, and uniform ones over a wide range.
  std::mt19937_64 rng(42);
  for (int trial = 0; trial < 6; ++trial) {
    std::vector<std::uint64_t> values(1000 + 7919 * trial);
    if (trial % 2 == 0) {
      std::lognormal_distribution<double> latency(std::log(5000.0), 0.8);
      for (auto& v : values) v = static_cast<std::uint64_t>(latency(rng));
    } else {
      std::uniform_int_distribution<std::uint64_t> wide(0, 50'000'000);
      for (auto& v : values) v = wide(rng);
    }
    LatencyHistogram h;
    for (std::uint64_t v : values) h.record(v);
    std::sort(values.begin(), values.end());
    for (std::uint64_t p_tenths : {1u, 500u, 900u, 990u, 999u, 1000u}) {
      SCOPED_TRACE(testing::Message() << "trial " << trial << " p " << p_tenths / 10.0);
      expect_close(h.value_at_percentile(p_tenths / 10.0), exact_percentile(values, p_tenths));
    }
    EXPECT_EQ(h.max(), values.back());
    EXPECT_EQ(h.min(), values.front());
    EXPECT_EQ(h.count(), values.size());
  }
}

TEST(LatencyHistogram, MergeEqualsRecordingEverything) {
  std::mt19937_64 rng(7);
  std::exponential_distribution<double> latency(1.0 / 3000);
  LatencyHistogram all, a, b;
  for (int i = 0; i < 20000; ++i) {
    const auto v = static_cast<std::uint64_t>(latency(rng));
    all.record(v);
    (i % 3 ? a : b).record(v);
  }
  a.merge(b);
  EXPECT_EQ(a.count(), all.count());
  EXPECT_EQ(a.max(), all.max());
  EXPECT_EQ(a.min(), all.min());
  for (double p : {50.0, 90.0, 99.0, 99.9}) EXPECT_EQ(a.value_at_percentile(p), all.value_at_percentile(p));
}

}  // namespace
}  // namespace mtlod::clients

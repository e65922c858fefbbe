// The open-loop arrival schedule: due times independent of the server, bounded by duration and
// count, spread round robin over connections.
#include "clients/load/schedule.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

namespace mtlod::clients {
namespace {

TEST(ArrivalSchedule, UniformIsExactlyOneOverRateApart) {
  // 400 requests/s: 2.5 ms apart, from time 0.
  ArrivalSchedule s(400, Arrivals::kUniform);
  for (std::int64_t i = 0; i < 10000; ++i) ASSERT_EQ(s.next_ns(), i * 2'500'000);
}

TEST(ArrivalSchedule, UniformDoesNotDriftWithAnInexactGap) {
  // 3 requests/s: a gap of 333333333.33 ns. Request 3000 is due at exactly 1000 s.
  ArrivalSchedule s(3, Arrivals::kUniform);
  std::int64_t last = 0;
  for (int i = 0; i <= 3000; ++i) last = s.next_ns();
  EXPECT_EQ(last, 1'000'000'000'000);
}

TEST(ArrivalSchedule, PoissonGapsHaveTheRequestedMean) {
  // 20000 exponential gaps of mean 1 ms: the sample mean's standard deviation is 1/√20000 ≈ 0.7 %,
  // so 4 % is more than five standard deviations. Gaps must never be negative.
  ArrivalSchedule s(1000, Arrivals::kPoisson, 123);
  std::int64_t previous = s.next_ns();
  EXPECT_EQ(previous, 0);
  double sum = 0, sum_sq = 0;
  const int n = 20000;
  for (int i = 0; i < n; ++i) {
    const std::int64_t t = s.next_ns();
    ASSERT_GE(t, previous);
    const double gap = static_cast<double>(t - previous);
    sum += gap, sum_sq += gap * gap;
    previous = t;
  }
  const double mean = sum / n;
  EXPECT_NEAR(mean, 1e6, 0.04e6);
  // Exponential: standard deviation equals the mean (within 6 % at this sample size).
  EXPECT_NEAR(std::sqrt(sum_sq / n - mean * mean), 1e6, 0.06e6);
}

TEST(ArrivalSchedule, SameSeedSameSchedule) {
  ArrivalSchedule a(250, Arrivals::kPoisson, 9), b(250, Arrivals::kPoisson, 9);
  for (int i = 0; i < 1000; ++i) ASSERT_EQ(a.next_ns(), b.next_ns());
}

TEST(PlanArrivals, BoundedByDurationAndSpreadRoundRobin) {
  // 100/s for 1 s: due at 0, 10, ..., 990 ms (100 requests; 1000 ms itself is excluded), over 3
  // connections: 34, 33, 33, and connection 1 gets requests 1, 4, 7, ...
  const auto plan = plan_arrivals(ArrivalSchedule(100, Arrivals::kUniform), 1'000'000'000, 0, 3);
  ASSERT_EQ(plan.size(), 3u);
  EXPECT_EQ(plan[0].size(), 34u);
  EXPECT_EQ(plan[1].size(), 33u);
  EXPECT_EQ(plan[2].size(), 33u);
  EXPECT_EQ(plan[1][0], 10'000'000);
  EXPECT_EQ(plan[1][1], 40'000'000);
  EXPECT_EQ(plan[0].back(), 990'000'000);
}

TEST(PlanArrivals, CountBoundStopsFirst) {
  // 1000/s for 10 s would be 10000 requests; the count bound keeps 25.
  const auto plan = plan_arrivals(ArrivalSchedule(1000, Arrivals::kUniform), 10'000'000'000, 25, 4);
  std::size_t total = 0;
  for (const auto& c : plan) total += c.size();
  EXPECT_EQ(total, 25u);
  EXPECT_EQ(plan[0].back(), 24'000'000);  // request 24 → connection 0, due at 24 ms
}

TEST(PlanArrivals, ZeroDurationPlansNothing) {
  const auto plan = plan_arrivals(ArrivalSchedule(1000, Arrivals::kUniform), 0, 0, 2);
  EXPECT_TRUE(plan[0].empty());
  EXPECT_TRUE(plan[1].empty());
}

}  // namespace
}  // namespace mtlod::clients

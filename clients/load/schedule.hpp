// The arrival schedule of an open-loop load test: when each request is due, independent of when
// earlier replies come back, so a slow server cannot slow the offered load down and hide its
// queueing ("coordinated omission"). Latency is measured from the due time, not the send time.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

namespace mtlod::clients {

enum class Arrivals : std::uint8_t {
  kUniform,  // exactly 1/rate apart
  kPoisson,  // exponentially distributed gaps with mean 1/rate
};

class ArrivalSchedule {
 public:
  // `rate_per_s` > 0 requests per second over all connections.
  ArrivalSchedule(double rate_per_s, Arrivals arrivals, std::uint64_t seed = 1);

  // Due time of the next request, in nanoseconds after the start of the test.
  std::int64_t next_ns();

 private:
  double gap_ns_;
  Arrivals arrivals_;
  std::uint64_t issued_ = 0;
  double poisson_ns_ = 0;
  std::mt19937_64 rng_;
};

// The requests of a test bounded by `duration_ns` and `max_requests` (0: no count bound): request
// i is due at the schedule's i-th time and goes to connection i mod `connections`. Returns each
// connection's due times, in order.
std::vector<std::vector<std::int64_t>> plan_arrivals(ArrivalSchedule schedule, std::int64_t duration_ns,
                                                     std::uint64_t max_requests, std::size_t connections);

}  // namespace mtlod::clients

// Open-loop arrival schedule (see schedule.hpp).
#include "clients/load/schedule.hpp"

#include <cassert>
#include <cmath>

namespace mtlod::clients {

ArrivalSchedule::ArrivalSchedule(double rate_per_s, Arrivals arrivals, std::uint64_t seed)
    : gap_ns_(1e9 / rate_per_s), arrivals_(arrivals), rng_(seed) {
  assert(rate_per_s > 0);
}

std::int64_t ArrivalSchedule::next_ns() {
  if (arrivals_ == Arrivals::kUniform) {
    // From the index, not by accumulation, so rounding never drifts over a long test.
    return static_cast<std::int64_t>(std::llround(static_cast<double>(issued_++) * gap_ns_));
  }
  const double due = poisson_ns_;
  poisson_ns_ += std::exponential_distribution<double>(1.0 / gap_ns_)(rng_);
  ++issued_;
  return static_cast<std::int64_t>(std::llround(due));
}

std::vector<std::vector<std::int64_t>> plan_arrivals(ArrivalSchedule schedule, std::int64_t duration_ns,
                                                     std::uint64_t max_requests, std::size_t connections) {
  assert(connections > 0);
  std::vector<std::vector<std::int64_t>> plan(connections);
  for (std::uint64_t i = 0; max_requests == 0 || i < max_requests; ++i) {
    const std::int64_t due = schedule.next_ns();
    if (due >= duration_ns) break;
    plan[i % connections].push_back(due);
  }
  return plan;
}

}  // namespace mtlod::clients

// What the benchmarks share.
#pragma once

#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <utility>
#include <vector>

#include "core/result.hpp"

namespace mtlod::bench {

// The benchmarks refine MTs built in memory, whose refinements cannot fail: a failure is a bug and
// stops the run.
inline void refined(const Status& status) {
  if (status) return;
  std::fprintf(stderr, "refinement failed: %s\n", status.error().message.c_str());
  std::abort();
}
// The same for a refinement that returns its cut: the cut.
template <class T>
T refined(Result<T> result) {
  if (!result) {
    std::fprintf(stderr, "refinement failed: %s\n", result.error().message.c_str());
    std::abort();
  }
  return std::move(*result);
}

// The value at quantile q (0..1) of values sorted ascending, the nearest rank below; not empty.
inline double quantile(const std::vector<double>& sorted, double q) {
  return sorted[static_cast<std::size_t>(q * static_cast<double>(sorted.size() - 1))];
}

}  // namespace mtlod::bench

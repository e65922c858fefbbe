// What the benchmarks share.
#pragma once

#include <cstdio>
#include <cstdlib>

#include "core/result.hpp"

namespace mtlod::bench {

// The benchmarks refine MTs built in memory, whose refinements cannot fail: a failure is a bug and
// stops the run.
inline void refined(const Status& status) {
  if (status) return;
  std::fprintf(stderr, "refinement failed: %s\n", status.error().message.c_str());
  std::abort();
}

}  // namespace mtlod::bench

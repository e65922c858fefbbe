// A ParallelForFn (core/mt_builder.hpp) on std::thread for the offline tools and benchmarks: one
// thread per hardware core takes task indices from a shared counter until none are left.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <thread>
#include <vector>

namespace mtlod::tools {

inline void thread_parallel_for(void* /*user*/, std::size_t count, void (*task)(void* context, std::size_t i),
                                void* context) {
  const std::size_t workers =
      std::min<std::size_t>(count, std::max(1u, std::thread::hardware_concurrency()));
  std::atomic<std::size_t> next{0};
  auto work = [&] {
    for (std::size_t i = next++; i < count; i = next++) task(context, i);
  };
  std::vector<std::thread> threads;
  threads.reserve(workers > 0 ? workers - 1 : 0);
  for (std::size_t w = 1; w < workers; ++w) threads.emplace_back(work);
  work();  // the calling thread is one of the workers
  for (std::thread& t : threads) t.join();
}

}  // namespace mtlod::tools

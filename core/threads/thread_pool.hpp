// A ParallelForFn (core/build/mt_builder.hpp) for the offline tools, the benchmarks and the server's
// start-up builds. core/threads/ is the only part of core that starts threads; the algorithms take
// a ParallelForFn and never start one themselves. A pool of threads, one per hardware core with
// the caller as one of them, that take task indices from a shared counter until none are left. The
// threads are started once: a build calls parallel_for a few hundred times, each too short to pay
// for starting threads.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <thread>
#include <vector>

#include "core/build/mt_builder.hpp"

namespace mtlod::core::threads {

class ThreadPool {
 public:
  // threads: all threads taking part, the caller included (at least 1).
  explicit ThreadPool(unsigned threads = std::max(1u, std::thread::hardware_concurrency())) {
    for (unsigned w = 1; w < threads; ++w) workers_.emplace_back([this] { work_loop(); });
  }
  ~ThreadPool() {
    stop_.store(true);
    generation_.fetch_add(1);
    generation_.notify_all();
    for (std::thread& t : workers_) t.join();
  }
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  // A ParallelForFn: pass the pool as its user pointer. One call at a time per pool.
  static void parallel_for(void* pool, std::size_t count, void (*task)(void* context, std::size_t i),
                           void* context) {
    static_cast<ThreadPool*>(pool)->run(count, task, context);
  }
  // Makes a build with these options run its concurrent phases on this pool.
  void attach(core::build::BuildOptions& options) {
    options.parallel_for = parallel_for;
    options.parallel_user = this;
  }

 private:
  // Idle workers spin this many rounds before they sleep: the gaps between one build phase and the
  // next are usually shorter than a sleep and wake-up.
  static constexpr int kSpinRounds = 1 << 14;

  void run(std::size_t count, void (*task)(void*, std::size_t), void* context) {
    if (workers_.empty() || count <= 1) {
      for (std::size_t i = 0; i < count; ++i) task(context, i);
      return;
    }
    task_ = task;
    context_ = context;
    count_ = count;
    next_.store(0, std::memory_order_relaxed);
    busy_.store(unsigned(workers_.size()), std::memory_order_relaxed);
    generation_.fetch_add(1, std::memory_order_release);
    generation_.notify_all();
    take_tasks();
    // The job lives in the caller's frame: wait until every worker has left it.
    for (unsigned busy = busy_.load(std::memory_order_acquire); busy != 0;
         busy = busy_.load(std::memory_order_acquire))
      busy_.wait(busy, std::memory_order_acquire);
  }

  void take_tasks() {
    for (std::size_t i = next_.fetch_add(1, std::memory_order_relaxed); i < count_;
         i = next_.fetch_add(1, std::memory_order_relaxed))
      task_(context_, i);
  }

  void work_loop() {
    std::uint64_t seen = 0;
    for (;;) {
      std::uint64_t now = generation_.load(std::memory_order_acquire);
      for (int round = 0; now == seen && round < kSpinRounds; ++round) {
        std::this_thread::yield();
        now = generation_.load(std::memory_order_acquire);
      }
      if (now == seen) {
        generation_.wait(seen, std::memory_order_acquire);
        continue;
      }
      seen = now;
      if (stop_.load()) return;
      take_tasks();
      if (busy_.fetch_sub(1, std::memory_order_acq_rel) == 1) busy_.notify_one();
    }
  }

  std::vector<std::thread> workers_;
  std::atomic<std::uint64_t> generation_{0};
  std::atomic<unsigned> busy_{0};
  std::atomic<bool> stop_{false};
  std::atomic<std::size_t> next_{0};
  void (*task_)(void*, std::size_t) = nullptr;
  void* context_ = nullptr;
  std::size_t count_ = 0;
};

}  // namespace mtlod::core::threads

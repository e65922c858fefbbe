// AddressTable, FairScheduler and MemoryCeiling against hand-worked expectations: slots per
// address, the order in which jobs of several keys run, reservations at the limit.
#include "server/admission.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <condition_variable>
#include <thread>

#include "core/io/memory_limit.hpp"

namespace mtlod::server {
namespace {

TEST(AddressTable, CapsEachAddressAndReleasesOnDestruction) {
  AddressTable table(2);
  AddressTable::Slot a1 = table.acquire("10.0.0.1"), a2 = table.acquire("10.0.0.1");
  EXPECT_TRUE(a1 && a2);
  EXPECT_FALSE(table.acquire("10.0.0.1"));
  EXPECT_TRUE(table.acquire("10.0.0.2"));  // another address has its own slots (released at once)
  EXPECT_EQ(table.held("10.0.0.2"), 0u);
  {
    AddressTable::Slot moved = std::move(a1);  // a move does not release
    EXPECT_EQ(table.held("10.0.0.1"), 2u);
  }
  EXPECT_EQ(table.held("10.0.0.1"), 1u);
  AddressTable::Slot a3 = table.acquire("10.0.0.1");
  EXPECT_TRUE(a3);
  a3.reset();
  a3.reset();  // twice is once
  EXPECT_EQ(table.held("10.0.0.1"), 1u);
}

TEST(AddressTable, ZeroMeansNoCap) {
  AddressTable table(0);
  std::vector<AddressTable::Slot> slots;
  for (int i = 0; i < 1000; ++i) slots.push_back(table.acquire("::1"));
  for (const auto& s : slots) EXPECT_TRUE(s);
  EXPECT_EQ(table.held("::1"), 1000u);
}

// Runs jobs on a one-thread pool; the first job blocks until released, so the order of the rest
// is decided while they all wait.
TEST(FairScheduler, KeysTakeTurnsAndEachKeysJobsKeepTheirOrder) {
  boost::asio::thread_pool pool(1);
  FairScheduler scheduler(pool, 1);
  std::mutex mutex;
  std::condition_variable cv;
  bool release = false;
  std::vector<std::string> order;
  auto record = [&](std::string name) {
    return [&, name] {
      std::lock_guard lock(mutex);
      order.push_back(name);
    };
  };
  scheduler.submit("flood", [&] {
    std::unique_lock lock(mutex);
    cv.wait(lock, [&] { return release; });
    order.push_back("flood0");
  });
  for (int i = 1; i <= 4; ++i) scheduler.submit("flood", record("flood" + std::to_string(i)));
  scheduler.submit("b", record("b1"));
  scheduler.submit("c", record("c1"));
  scheduler.submit("b", record("b2"));
  EXPECT_EQ(scheduler.waiting(), 7u);
  {
    std::lock_guard lock(mutex);
    release = true;
  }
  cv.notify_all();
  pool.join();
  const std::vector<std::string> expected = {"flood0", "flood1", "b1",     "c1",
                                             "flood2", "b2",     "flood3", "flood4"};
  EXPECT_EQ(order, expected);
  EXPECT_EQ(scheduler.waiting(), 0u);
}

TEST(FairScheduler, RunsAsManyJobsAtOnceAsItHasSlots) {
  boost::asio::thread_pool pool(4);
  FairScheduler scheduler(pool, 2);
  std::atomic<int> running{0}, most{0}, done{0};
  for (int i = 0; i < 40; ++i) {
    scheduler.submit(std::to_string(i % 3), [&] {
      const int now = ++running;
      int seen = most.load();
      while (now > seen && !most.compare_exchange_weak(seen, now)) {
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
      --running;
      ++done;
    });
  }
  pool.join();
  EXPECT_EQ(done.load(), 40);
  EXPECT_LE(most.load(), 2);
}

TEST(MemoryCeiling, ReservesUpToTheLimitAndNoFurther) {
  MemoryCeiling memory(100);
  EXPECT_TRUE(memory.reserve(60));
  EXPECT_FALSE(memory.reserve(41));
  EXPECT_TRUE(memory.reserve(40));
  EXPECT_EQ(memory.held(), 100u);
  EXPECT_FALSE(memory.reserve(1));
  memory.release(60);
  memory.adjust(-10);
  EXPECT_EQ(memory.held(), 30u);
  memory.adjust(25);
  EXPECT_EQ(memory.held(), 55u);
  EXPECT_FALSE(memory.reserve(UINT64_MAX));  // no wrap-around
  EXPECT_EQ(memory.held(), 55u);
}

TEST(MemoryCeiling, DefaultIsHalfOfWhatTheProcessMayUse) {
  const std::uint64_t limit = core::io::default_memory_limit();
  EXPECT_GT(limit, std::uint64_t{64} << 20);
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  EXPECT_LE(limit, std::uint64_t(pages) * std::uint64_t(page) / 2);
}

}  // namespace
}  // namespace mtlod::server

// Who gets in and whose work runs next, so that no client can lock the others out: a cap on the
// connections one client address holds (AddressTable), and a scheduler that lets client addresses
// take turns at the workers instead of serving extractions first come, first served
// (FairScheduler). Idle sockets are handled by the transports' first-frame deadline.
#pragma once

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/thread_pool.hpp>

#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>

namespace mtlod::server {

// The client's address as text ("127.0.0.1", "::1"); empty when the socket has none.
std::string remote_address(const boost::asio::ip::tcp::socket& socket);

// Writes `bytes` (a refusal the client can read) and closes the socket, without waiting for it.
void refuse_socket(boost::asio::ip::tcp::socket socket, std::string bytes);

class AddressTable {
 public:
  // cap 0: no per-address limit.
  explicit AddressTable(std::uint32_t cap) : cap_(cap) {}

  // A connection's hold on its address: released when destroyed or reset.
  class Slot {
   public:
    Slot() = default;
    Slot(Slot&& other) noexcept { *this = std::move(other); }
    Slot& operator=(Slot&& other) noexcept;
    ~Slot() { reset(); }
    // Gives the slot back; address() still names it.
    void reset();
    const std::string& address() const { return address_; }
    explicit operator bool() const { return table_ != nullptr; }

   private:
    friend class AddressTable;
    AddressTable* table_ = nullptr;
    std::string address_;
  };

  // A slot for one more connection from `address`, or an empty one when it holds `cap` already.
  Slot acquire(const std::string& address);
  std::uint32_t cap() const { return cap_; }
  std::uint32_t held(const std::string& address) const;

 private:
  void release(const std::string& address);

  const std::uint32_t cap_;
  mutable std::mutex mutex_;
  std::unordered_map<std::string, std::uint32_t> held_;
};

// The memory the server's work may hold: worker scratch plus every connection's session. Work
// reserves its estimated need before it runs and is refused when that would pass the limit; when it
// has run, the reservation is replaced by what it really left behind.
class MemoryCeiling {
 public:
  explicit MemoryCeiling(std::uint64_t limit) : limit_(limit) {}

  // Reserves `bytes`; false, reserving nothing, when that would pass the limit.
  bool reserve(std::uint64_t bytes);
  // Adds (or with a negative change, frees) memory already in use.
  void adjust(std::int64_t change) {
    held_.fetch_add(static_cast<std::uint64_t>(change), std::memory_order_relaxed);
  }
  void release(std::uint64_t bytes) { held_.fetch_sub(bytes, std::memory_order_relaxed); }

  std::uint64_t held() const { return held_.load(std::memory_order_relaxed); }
  std::uint64_t limit() const { return limit_; }

 private:
  const std::uint64_t limit_;
  std::atomic<std::uint64_t> held_{0};
};

class FairScheduler {
 public:
  // Runs at most `slots` jobs at once on `pool`.
  FairScheduler(boost::asio::thread_pool& pool, unsigned slots) : pool_(pool), slots_(slots ? slots : 1) {}

  // Runs `job` on the pool when its turn comes. Keys (client addresses) with waiting work take
  // turns, one job each; a key's jobs run in the order submitted. `job` must not throw.
  void submit(const std::string& key, std::function<void()> job);

  // Jobs submitted and not yet started.
  std::size_t waiting() const;

 private:
  void dispatch(std::unique_lock<std::mutex>& lock);
  void finished();

  boost::asio::thread_pool& pool_;
  const unsigned slots_;
  mutable std::mutex mutex_;
  unsigned running_ = 0;
  std::size_t waiting_count_ = 0;
  std::unordered_map<std::string, std::deque<std::function<void()>>> waiting_;
  std::deque<std::string> turns_;  // keys with waiting work, in the order their turns come
};

}  // namespace mtlod::server

// Server counters (requests by type, errors by code, bytes, connections, stage times). Lock-free:
// relaxed atomics are enough for monotonically growing statistics read by `stats` and the logs.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "protocol/errors.hpp"
#include "protocol/replies.hpp"

namespace mtlod::server {

class Metrics {
 public:
  static constexpr std::size_t kRequestTypes = std::variant_size_v<protocol::Request>;
  static constexpr std::size_t kErrorKinds = static_cast<std::size_t>(protocol::ErrorKind::kInternal) + 1;

  void connection_opened() { add(connections_total_), add(connections_open_); }
  void connection_closed() { connections_open_.fetch_sub(1, std::memory_order_relaxed); }
  void connection_refused() { add(connections_refused_); }
  void request(std::size_t type_index) { add(requests_[type_index]); }
  void error(protocol::ErrorKind kind) { add(errors_[static_cast<std::size_t>(kind)]); }
  void bytes_in(std::uint64_t n) { add(bytes_in_, n); }
  void bytes_out(std::uint64_t n) { add(bytes_out_, n); }
  void extraction(const protocol::StageTimings& t, std::uint64_t triangles);

  std::uint64_t open_connections() const { return connections_open_.load(std::memory_order_relaxed); }
  // Named values, for the `stats` reply.
  std::vector<std::pair<std::string, double>> snapshot() const;

 private:
  using Counter = std::atomic<std::uint64_t>;
  static void add(Counter& c, std::uint64_t n = 1) { c.fetch_add(n, std::memory_order_relaxed); }

  Counter connections_total_{0}, connections_open_{0}, connections_refused_{0};
  std::array<Counter, kRequestTypes> requests_{};
  std::array<Counter, kErrorKinds> errors_{};
  Counter bytes_in_{0}, bytes_out_{0};
  Counter extractions_{0}, triangles_out_{0};
  Counter queue_us_{0}, map_us_{0}, occupancy_us_{0}, dt_us_{0}, labels_us_{0}, refine_us_{0}, encode_us_{0},
      total_us_{0};
};

}  // namespace mtlod::server

// Server counters (requests by type, errors by code, bytes, connections, stage times) and latency
// histograms, read by the `stats` reply and by `GET /metrics` in Prometheus' text format. Lock-free:
// relaxed atomics are enough for monotonically growing statistics read while they change.
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

// Durations in fixed buckets, as a Prometheus histogram (cumulative when rendered).
class PrometheusHistogram {
 public:
  // Upper bounds in microseconds: finer around a 60–120 Hz frame (8–16 ms), where gaze latency is
  // judged, and up to a few seconds for huge grids and budgets.
  static constexpr std::array<std::uint64_t, 14> kBoundsUs{
      250, 500, 1000, 2000, 4000, 8000, 12000, 16000, 25000, 50000, 100000, 250000, 1000000, 2500000};

  void observe(std::uint64_t us);
  // Observations at or below each bound, then the count of all (the +Inf bucket).
  std::array<std::uint64_t, kBoundsUs.size() + 1> cumulative() const;
  std::uint64_t sum_us() const { return sum_us_.load(std::memory_order_relaxed); }

 private:
  std::array<std::atomic<std::uint64_t>, kBoundsUs.size() + 1> buckets_{};  // the last: above every bound
  std::atomic<std::uint64_t> sum_us_{0};
};

// Values the server holds elsewhere, sampled when /metrics is scraped.
struct MetricsGauges {
  std::uint64_t memory_held_bytes = 0;   // sessions plus running extractions' reservations
  std::uint64_t memory_limit_bytes = 0;  // --max-memory
  std::uint64_t models = 0;
  std::uint64_t model_bytes = 0;         // held in memory by every model
  std::uint64_t model_mapped_bytes = 0;  // of the model files mapped in place
  std::uint64_t model_reloads = 0;       // new versions loaded since start-up
  // The version each model serves, by name; left empty where model names are not public (with
  // access tokens, whose grants name the models a client may see).
  std::vector<std::pair<std::string, std::uint64_t>> model_versions;
};

class Metrics {
 public:
  static constexpr std::size_t kRequestTypes = std::variant_size_v<protocol::Request>;
  static constexpr std::size_t kErrorKinds = static_cast<std::size_t>(protocol::ErrorKind::kInternal) + 1;
  // The stages of an extraction as StageTimings reports them; "total" runs from the request's
  // arrival to its reply.
  static constexpr std::array<const char*, 8> kStages{"queue",  "map",    "occupancy", "dt",
                                                      "labels", "refine", "encode",    "total"};

  void connection_opened() { add(connections_total_), add(connections_open_); }
  void connection_closed() { connections_open_.fetch_sub(1, std::memory_order_relaxed); }
  void connection_refused() { add(connections_refused_); }
  void request(std::size_t type_index) { add(requests_[type_index]); }
  void error(protocol::ErrorKind kind) { add(errors_[static_cast<std::size_t>(kind)]); }
  void bytes_in(std::uint64_t n) { add(bytes_in_, n); }
  void bytes_out(std::uint64_t n) { add(bytes_out_, n); }
  // A mesh reply (extract or gaze) has been written whole to its connection.
  void mesh_sent() { add(meshes_sent_); }
  std::uint64_t meshes_sent() const { return meshes_sent_.load(std::memory_order_relaxed); }
  // gaze: the extraction answered a gaze (else an extract).
  void extraction(const protocol::StageTimings& t, std::uint64_t triangles, bool gaze);
  // A connection's session now holds `delta` bytes more (or fewer).
  void session_bytes(std::int64_t delta) { session_bytes_.fetch_add(static_cast<std::uint64_t>(delta)); }
  // The workers' scratch kept between extractions now holds `delta` bytes more (or fewer).
  void scratch_bytes(std::int64_t delta) { scratch_bytes_.fetch_add(static_cast<std::uint64_t>(delta)); }

  std::uint64_t open_connections() const { return connections_open_.load(std::memory_order_relaxed); }
  std::uint64_t connections_accepted() const { return connections_total_.load(std::memory_order_relaxed); }
  // Named values, for the `stats` reply.
  std::vector<std::pair<std::string, double>> snapshot() const;
  // Everything, in Prometheus' text exposition format (version 0.0.4).
  std::string prometheus_text(const MetricsGauges& gauges) const;

 private:
  using Counter = std::atomic<std::uint64_t>;
  static void add(Counter& c, std::uint64_t n = 1) { c.fetch_add(n, std::memory_order_relaxed); }
  // prometheus_text's sections: traffic counters, extraction durations, memory and model gauges.
  void append_traffic(std::string& out) const;
  void append_durations(std::string& out) const;
  void append_memory(std::string& out, const MetricsGauges& gauges) const;

  Counter connections_total_{0}, connections_open_{0}, connections_refused_{0};
  std::array<Counter, kRequestTypes> requests_{};
  std::array<Counter, kErrorKinds> errors_{};
  Counter bytes_in_{0}, bytes_out_{0};
  Counter meshes_sent_{0};
  Counter triangles_out_{0};
  Counter session_bytes_{0};  // wraps through negative deltas; the sum is what sessions hold
  Counter scratch_bytes_{0};  // likewise, what the workers keep
  // [extract, gaze][stage]
  std::array<std::array<PrometheusHistogram, kStages.size()>, 2> stage_histograms_{};
};

}  // namespace mtlod::server

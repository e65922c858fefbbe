// Server counters (see metrics.hpp).
#include "server/metrics.hpp"

namespace mtlod::server {

void Metrics::extraction(const protocol::StageTimings& t, std::uint64_t triangles) {
  add(extractions_);
  add(triangles_out_, triangles);
  add(queue_us_, t.queue_us);
  add(map_us_, t.map_us);
  add(occupancy_us_, t.occupancy_us);
  add(dt_us_, t.dt_us);
  add(labels_us_, t.labels_us);
  add(refine_us_, t.refine_us);
  add(encode_us_, t.encode_us);
  add(total_us_, t.total_us);
}

std::vector<std::pair<std::string, double>> Metrics::snapshot() const {
  auto get = [](const Counter& c) { return static_cast<double>(c.load(std::memory_order_relaxed)); };
  std::vector<std::pair<std::string, double>> out = {{"connections_total", get(connections_total_)},
                                                     {"connections_open", get(connections_open_)},
                                                     {"connections_refused", get(connections_refused_)},
                                                     {"bytes_in", get(bytes_in_)},
                                                     {"bytes_out", get(bytes_out_)},
                                                     {"extractions", get(extractions_)},
                                                     {"triangles_out", get(triangles_out_)},
                                                     {"queue_us_total", get(queue_us_)},
                                                     {"map_us_total", get(map_us_)},
                                                     {"occupancy_us_total", get(occupancy_us_)},
                                                     {"dt_us_total", get(dt_us_)},
                                                     {"labels_us_total", get(labels_us_)},
                                                     {"refine_us_total", get(refine_us_)},
                                                     {"encode_us_total", get(encode_us_)},
                                                     {"extract_us_total", get(total_us_)}};
  for (std::size_t i = 0; i < kRequestTypes; ++i)
    out.emplace_back(std::string("requests_") + protocol::kRequestTypeNames[i], get(requests_[i]));
  for (std::size_t i = 0; i < kErrorKinds; ++i) {
    out.emplace_back(std::string("errors_") + protocol::to_string(static_cast<protocol::ErrorKind>(i)),
                     get(errors_[i]));
  }
  return out;
}

}  // namespace mtlod::server

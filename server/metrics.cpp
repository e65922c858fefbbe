// Server counters and their Prometheus rendering (see metrics.hpp).
#include "server/metrics.hpp"

#include <algorithm>
#include <iterator>

#include "fmt/format.h"
#include "protocol/text.hpp"

namespace mtlod::server {
namespace {

// A Prometheus label value: valid text with its backslashes, quotes and newlines escaped.
std::string label_value(const std::string& text) {
  std::string out;
  for (const char c : protocol::printable(text)) {
    if (c == '\\' || c == '"') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out;
}

// A metric family's HELP and TYPE lines.
void family(std::string& out, const char* name, const char* type, const char* help) {
  fmt::format_to(std::back_inserter(out), "# HELP {} {}\n# TYPE {} {}\n", name, help, name, type);
}
// One sample line, with its labels when there are any.
void sample(std::string& out, const char* name, std::uint64_t value, const std::string& labels = {}) {
  if (labels.empty()) {
    fmt::format_to(std::back_inserter(out), "{} {}\n", name, value);
  } else {
    fmt::format_to(std::back_inserter(out), "{}{{{}}} {}\n", name, labels, value);
  }
}
// A family of one unlabelled sample.
void single(std::string& out, const char* name, const char* type, const char* help, std::uint64_t value) {
  family(out, name, type, help);
  sample(out, name, value);
}
std::uint64_t get(const std::atomic<std::uint64_t>& c) {
  return c.load(std::memory_order_relaxed);
}

}  // namespace

void PrometheusHistogram::observe(std::uint64_t us) {
  const auto bound = std::lower_bound(kBoundsUs.begin(), kBoundsUs.end(), us);
  buckets_[static_cast<std::size_t>(bound - kBoundsUs.begin())].fetch_add(1, std::memory_order_relaxed);
  sum_us_.fetch_add(us, std::memory_order_relaxed);
}

std::array<std::uint64_t, PrometheusHistogram::kBoundsUs.size() + 1> PrometheusHistogram::cumulative() const {
  std::array<std::uint64_t, kBoundsUs.size() + 1> out{};
  std::uint64_t running = 0;
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] = running += buckets_[i].load(std::memory_order_relaxed);
  return out;
}

void Metrics::extraction(const protocol::StageTimings& t, std::uint64_t triangles, bool gaze) {
  add(triangles_out_, triangles);
  const std::array<std::uint64_t, kStages.size()> stages{
      t.queue_us, t.map_us, t.occupancy_us, t.dt_us, t.labels_us, t.refine_us, t.encode_us, t.total_us};
  auto& histograms = stage_histograms_[gaze ? 1 : 0];
  for (std::size_t s = 0; s < stages.size(); ++s) histograms[s].observe(stages[s]);
}

std::vector<std::pair<std::string, double>> Metrics::snapshot() const {
  // Extraction counts and stage sums come from the histograms, extract and gaze together.
  std::uint64_t extractions = 0;
  for (const auto& histograms : stage_histograms_) extractions += histograms.back().cumulative().back();
  std::vector<std::pair<std::string, double>> out = {{"connections_total", get(connections_total_)},
                                                     {"connections_open", get(connections_open_)},
                                                     {"connections_refused", get(connections_refused_)},
                                                     {"bytes_in", get(bytes_in_)},
                                                     {"bytes_out", get(bytes_out_)},
                                                     {"extractions", static_cast<double>(extractions)},
                                                     {"meshes_sent", get(meshes_sent_)},
                                                     {"triangles_out", get(triangles_out_)},
                                                     {"worker_scratch_bytes", get(scratch_bytes_)}};
  for (std::size_t s = 0; s < kStages.size(); ++s) {
    std::uint64_t sum_us = 0;
    for (const auto& histograms : stage_histograms_) sum_us += histograms[s].sum_us();
    const std::string stage = s + 1 == kStages.size() ? "extract" : kStages[s];  // the stats name of "total"
    out.emplace_back(stage + "_us_total", static_cast<double>(sum_us));
  }
  for (std::size_t i = 0; i < kRequestTypes; ++i)
    out.emplace_back(std::string("requests_") + protocol::kRequestTypeNames[i], get(requests_[i]));
  for (std::size_t i = 0; i < kErrorKinds; ++i) {
    out.emplace_back(std::string("errors_") + protocol::to_string(static_cast<protocol::ErrorKind>(i)),
                     get(errors_[i]));
  }
  return out;
}

std::string Metrics::prometheus_text(const MetricsGauges& gauges) const {
  // Names and units after https://prometheus.io/docs/practices/naming/: a mtlod_ prefix, base
  // units (seconds, bytes), _total on counters.
  std::string out;
  append_traffic(out);
  append_durations(out);
  append_memory(out, gauges);
  return out;
}

void Metrics::append_traffic(std::string& out) const {
  single(out, "mtlod_connections_accepted_total", "counter", "Connections accepted on both ports.",
         get(connections_total_));
  single(out, "mtlod_connections_refused_total", "counter", "Connections refused by the connection limits.",
         get(connections_refused_));
  single(out, "mtlod_connections_open", "gauge", "Connections open now (protocol and WebSocket).",
         get(connections_open_));
  family(out, "mtlod_requests_total", "counter", "Requests that parsed, by type.");
  for (std::size_t i = 0; i < kRequestTypes; ++i)
    sample(out, "mtlod_requests_total", get(requests_[i]),
           fmt::format("type=\"{}\"", protocol::kRequestTypeNames[i]));
  family(out, "mtlod_errors_total", "counter", "Error replies, by code.");
  for (std::size_t i = 0; i < kErrorKinds; ++i) {
    sample(out, "mtlod_errors_total", get(errors_[i]),
           fmt::format("code=\"{}\"", protocol::to_string(static_cast<protocol::ErrorKind>(i))));
  }
  single(out, "mtlod_received_bytes_total", "counter", "Bytes of request frames received.", get(bytes_in_));
  single(out, "mtlod_sent_bytes_total", "counter", "Bytes of reply frames sent.", get(bytes_out_));
  single(out, "mtlod_sent_triangles_total", "counter", "Triangles of the cuts sent.", get(triangles_out_));
  single(out, "mtlod_sent_meshes_total", "counter",
         "Mesh replies (extract and gaze) written whole to their connections.", get(meshes_sent_));
}

void Metrics::append_durations(std::string& out) const {
  family(out, "mtlod_extraction_duration_seconds", "histogram",
         "Extractions by request type and stage; stage total runs from the request's arrival to its reply.");
  for (std::size_t type = 0; type < stage_histograms_.size(); ++type) {
    for (std::size_t s = 0; s < kStages.size(); ++s) {
      const PrometheusHistogram& h = stage_histograms_[type][s];
      const std::string labels =
          fmt::format("type=\"{}\",stage=\"{}\"", type ? "gaze" : "extract", kStages[s]);
      const auto counts = h.cumulative();
      for (std::size_t b = 0; b < counts.size(); ++b) {
        const std::string le = b < PrometheusHistogram::kBoundsUs.size()
                                   ? fmt::format("{}", PrometheusHistogram::kBoundsUs[b] / 1e6)
                                   : std::string("+Inf");
        sample(out, "mtlod_extraction_duration_seconds_bucket", counts[b],
               fmt::format("{},le=\"{}\"", labels, le));
      }
      fmt::format_to(std::back_inserter(out), "mtlod_extraction_duration_seconds_sum{{{}}} {}\n", labels,
                     static_cast<double>(h.sum_us()) / 1e6);
      sample(out, "mtlod_extraction_duration_seconds_count", counts.back(), labels);
    }
  }
}

void Metrics::append_memory(std::string& out, const MetricsGauges& gauges) const {
  single(out, "mtlod_session_memory_bytes", "gauge",
         "Bytes the connections' sessions hold (cuts, views, deltas).", get(session_bytes_));
  single(out, "mtlod_worker_scratch_bytes", "gauge",
         "Bytes the workers keep between extractions (grids, per model; at most 64 MiB each).",
         get(scratch_bytes_));
  single(out, "mtlod_memory_held_bytes", "gauge",
         "Sessions plus the running extractions' reservations, as the memory ceiling counts them.",
         gauges.memory_held_bytes);
  single(out, "mtlod_memory_limit_bytes", "gauge", "The memory ceiling (--max-memory).",
         gauges.memory_limit_bytes);
  single(out, "mtlod_models", "gauge", "Models served.", gauges.models);
  single(out, "mtlod_model_memory_bytes", "gauge", "Bytes every model holds in memory.", gauges.model_bytes);
  single(out, "mtlod_model_mapped_bytes", "gauge",
         "Bytes of the model files mapped in place (resident only as far as requests read them).",
         gauges.model_mapped_bytes);
  single(out, "mtlod_model_reloads_total", "counter",
         "New model versions loaded from changed files since start-up (SIGHUP, reload, file watch).",
         gauges.model_reloads);
  if (!gauges.model_versions.empty()) {
    family(out, "mtlod_model_version", "gauge", "The version of each model served (1 at start-up).");
    for (const auto& [name, version] : gauges.model_versions)
      sample(out, "mtlod_model_version", version, fmt::format("model=\"{}\"", label_value(name)));
  }
}

}  // namespace mtlod::server

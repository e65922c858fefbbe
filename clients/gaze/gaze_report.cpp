// mtlod-gaze's report (see gaze_report.hpp).
#include "clients/gaze/gaze_report.hpp"

#include <fstream>
#include <string>

#include "fmt/format.h"
#include "nlohmann/json.hpp"

namespace mtlod::clients {
namespace {

nlohmann::ordered_json percentiles_ms(const LatencyHistogram& h) {
  auto ms = [](std::uint64_t us) { return us / 1000.0; };
  return {{"p50", ms(h.value_at_percentile(50))},
          {"p90", ms(h.value_at_percentile(90))},
          {"p99", ms(h.value_at_percentile(99))},
          {"p999", ms(h.value_at_percentile(99.9))},
          {"max", ms(h.max())},
          {"mean", h.mean() / 1000.0},
          {"count", h.count()}};
}

nlohmann::ordered_json report_json(const GazeOptions& o, const clients::ExtractFlags& flags,
                                   const GazeTotals& r, const GazeReplayEnd& end) {
  const double per_mesh = std::max<double>(1, static_cast<double>(r.meshes));
  return {
      {"model", o.scene_file.empty() ? nlohmann::json(o.model) : nlohmann::json(nullptr)},
      {"scene", o.scene_file.empty() ? nlohmann::json(nullptr) : nlohmann::json(o.scene_file)},
      {"instances", o.scene_file.empty() ? nlohmann::json(nullptr) : nlohmann::json(o.scene.size())},
      {"streams", o.streams},
      {"trace", describe_traces(o)},
      {"budget", flags.budget ? nlohmann::json(*flags.budget) : nlohmann::json(nullptr)},
      {"elapsed_s", end.elapsed_s},
      {"samples", r.sent},
      {"tracker_lost_samples", r.tracker_lost},
      {"blinks", r.blinks},
      {"requests", r.meshes + r.superseded + r.errors},
      {"meshes", r.meshes},
      {"superseded", r.superseded},
      {"superseded_counted_by_server", r.superseded_counted},
      {"errors", r.errors},
      {"errors_by_code", r.errors_by_code},
      {"lost", end.lost},
      {"reconnects", end.reconnects},
      {"resent", end.resent},
      {"focus_mismatches", r.focus_mismatches},
      {"delta", flags.delta},
      {"delta_errors", r.delta_errors},
      {"throughput_rps", r.meshes / std::max(end.elapsed_s, 1e-9)},
      {"latency_ms", percentiles_ms(r.mesh_latency_us)},
      {"sample_latency_ms", percentiles_ms(r.sample_latency_us)},
      {"applied_latency_ms",
       flags.delta ? percentiles_ms(r.applied_latency_us) : nlohmann::ordered_json(nullptr)},
      {"mean_triangles", r.triangles / per_mesh},
      {"bytes", r.bytes},
      {"server_total_us_mean", r.server_total_us / per_mesh},
  };
}

void print_report(const GazeOptions& o, const clients::ExtractFlags& flags, const GazeTotals& r,
                  const GazeReplayEnd& end) {
  const double per_mesh = std::max<double>(1, static_cast<double>(r.meshes));
  fmt::print(
      "{} stream(s) on {}: {} samples, {} meshes, {} superseded (server counted {}), {} errors, {} lost\n",
      o.streams, describe_view(o), r.sent, r.meshes, r.superseded, r.superseded_counted, r.errors, end.lost);
  fmt::print("  tracker lost the eye: {} samples in {} blinks (not sent; the server kept the last gaze)\n",
             r.tracker_lost, r.blinks);
  const auto& h = r.mesh_latency_us;
  fmt::print("  gaze-to-mesh ms  p50 {:.2f}  p90 {:.2f}  p99 {:.2f}  p99.9 {:.2f}  max {:.2f}\n",
             h.value_at_percentile(50) / 1e3, h.value_at_percentile(90) / 1e3,
             h.value_at_percentile(99) / 1e3, h.value_at_percentile(99.9) / 1e3, h.max() / 1e3);
  const auto& q = r.sample_latency_us;
  fmt::print("  every sample until a mesh shows it or a newer one, ms  p50 {:.2f}  p99 {:.2f}  max {:.2f}\n",
             q.value_at_percentile(50) / 1e3, q.value_at_percentile(99) / 1e3, q.max() / 1e3);
  if (flags.delta) {
    const auto& a = r.applied_latency_us;
    fmt::print(
        "  gaze-to-applied (delta decoded into the client's mesh) ms  p50 {:.2f}  p99 {:.2f}  max {:.2f}\n",
        a.value_at_percentile(50) / 1e3, a.value_at_percentile(99) / 1e3, a.max() / 1e3);
  }
  fmt::print(
      "  {:.0f} triangles per mesh, {:.0f} bytes per mesh, server total {:.0f} µs mean, focus mismatches "
      "{}{}\n",
      r.triangles / per_mesh, static_cast<double>(r.bytes) / per_mesh, r.server_total_us / per_mesh,
      r.focus_mismatches, flags.delta ? fmt::format(", delta errors {}", r.delta_errors) : std::string());
}

}  // namespace

Status report_gaze(const GazeOptions& options, const clients::ExtractFlags& flags, const GazeTotals& totals,
                   const GazeReplayEnd& end) {
  const nlohmann::ordered_json report = report_json(options, flags, totals, end);
  print_report(options, flags, totals, end);
  if (options.json_file.empty()) return Ok{};
  std::ofstream out(options.json_file);
  out << report.dump(2) << "\n";
  if (!out) return make_error(ErrorCode::kIoError, fmt::format("{}: write failed", options.json_file));
  return Ok{};
}

}  // namespace mtlod::clients

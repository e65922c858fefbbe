// mtlod-gaze: replays eye-tracker gaze against mtlod-server (issue 6) and measures gaze-to-mesh
// latency: from a sample's timestamp (its due time in the replay, so a late send counts) to the
// arrival of the mesh reply that reflects it. Gaze updates the server coalesced away are counted;
// each sample's wait for a mesh showing it or a newer sample is reported too. With --delta each
// stream applies its replies on a thread of its own, so decoding one reply never delays the arrival
// time taken for the next; gaze-to-applied (the mesh decoded into the client's copy) is reported
// too. A dropped connection is reopened with backoff; the view's extract and the newest unanswered
// sample are sent again (older samples are stale: the newest one supersedes them, as the server's
// coalescing would).
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>

#include "CLI/CLI.hpp"
#include "clients/common/delta_mesh.hpp"
#include "clients/common/extract_flags.hpp"
#include "clients/common/retry.hpp"
#include "clients/gaze/trace.hpp"
#include "clients/load/histogram.hpp"
#include "fmt/format.h"
#include "nlohmann/json.hpp"

namespace {

using namespace mtlod;
using Clock = std::chrono::steady_clock;

int fail(const std::string& message) {
  fmt::print(stderr, "mtlod-gaze: {}\n", message);
  return 1;
}

std::int64_t since(Clock::time_point start) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - start).count();
}

struct Totals {
  std::mutex mutex;
  clients::LatencyHistogram mesh_latency_us;     // per mesh reply: its sample's time → arrival
  clients::LatencyHistogram sample_latency_us;   // per sample: its time → a mesh showing it or a newer one
  clients::LatencyHistogram applied_latency_us;  // per delta mesh reply: its sample's time → applied
  std::uint64_t sent = 0, meshes = 0, superseded = 0, superseded_counted = 0, errors = 0,
                focus_mismatches = 0;
  std::uint64_t bytes = 0, triangles = 0, server_total_us = 0;
  std::map<std::string, std::uint64_t> errors_by_code;
  std::uint64_t reconnects = 0, resent = 0;
  std::uint64_t delta_errors = 0;  // delta replies that did not apply cleanly to the kept mesh
};

struct Stream {
  std::vector<clients::GazeSample> trace;
  protocol::Extract view;  // the extract that opened the stream's view
  std::mutex send_mutex;   // held while sending and while the connection is replaced (before `mutex`)
  std::mutex mutex;        // guards what follows
  std::condition_variable changed;
  std::shared_ptr<clients::Connection> connection;
  std::uint64_t generation = 0;
  bool reconnecting = false;
  std::size_t sent = 0;       // samples sent; sample i has request id i + 1
  std::size_t answered = 0;   // samples answered (mesh or error)
  std::size_t reflected = 0;  // samples [0, reflected) have a mesh showing them or a newer sample
  bool broken = false;
  std::mt19937_64 rng;      // backoff jitter
  clients::DeltaMesh mesh;  // with --delta: the mesh the replies build (apply thread only)
  // Delta replies received and not yet applied, in arrival order, with their sample's time (ns;
  // -1 for the view's extract); the apply thread takes them.
  struct Received {
    clients::ReplyFrame frame;
    std::int64_t sample_ns;
  };
  std::deque<Received> to_apply;
  bool receiving_done = false;
  std::condition_variable to_apply_changed;
};

struct Link {
  const clients::Endpoint& endpoint;
  const clients::RetryPolicy& retry;
  Totals& totals;
  std::atomic<bool>& finished;
};

// Reopens a dropped connection (unless the other thread already did): the view's extract (id 0,
// focused on the newest sample sent) and then the newest unanswered sample again. False: gave up.
bool reconnect(Stream& stream, const Link& link, std::uint64_t failed) {
  std::lock_guard send_lock(stream.send_mutex);
  {
    std::lock_guard lock(stream.mutex);
    if (stream.generation != failed || stream.broken) return !stream.broken;
    stream.reconnecting = true;
  }
  auto session =
      clients::open_session(link.endpoint, "mtlod-gaze/0.1", link.retry, stream.rng, nullptr, &link.finished);
  auto connection = session ? std::make_shared<clients::Connection>(std::move(session->connection)) : nullptr;
  std::size_t sent = 0, answered = 0;
  {
    std::lock_guard lock(stream.mutex);
    stream.reconnecting = false;
    if (connection) {
      stream.connection = connection;
      ++stream.generation;
    } else {
      stream.broken = true;
    }
    sent = stream.sent;
    answered = stream.answered;
  }
  stream.changed.notify_all();
  if (!connection) return false;
  protocol::Extract view = stream.view;
  if (sent > 0) {
    view.criteria.focus.front().x = stream.trace[sent - 1].x;
    view.criteria.focus.front().y = stream.trace[sent - 1].y;
  }
  (void)connection->send(view, 0);
  const bool resend = sent > answered;
  if (resend) {
    const clients::GazeSample& newest = stream.trace[sent - 1];
    (void)connection->send(protocol::Gaze{newest.x, newest.y, std::nullopt, std::nullopt}, sent);
  }
  std::lock_guard lock(link.totals.mutex);
  ++link.totals.reconnects;
  link.totals.resent += resend ? 1 : 0;
  return true;
}

void receive_loop(Stream& stream, const Link& link, Clock::time_point start) {
  Totals& totals = link.totals;
  for (;;) {
    std::shared_ptr<clients::Connection> connection;
    std::uint64_t generation = 0;
    {
      std::unique_lock lock(stream.mutex);
      stream.changed.wait(lock, [&] { return !stream.reconnecting; });
      if (stream.broken) break;
      connection = stream.connection;
      generation = stream.generation;
    }
    auto frame = connection->receive(std::chrono::hours(1));
    const std::int64_t now = since(start);
    if (!frame || clients::asks_for_retry(*frame)) {
      if (link.finished || !reconnect(stream, link, generation)) break;
      continue;
    }
    const std::uint64_t id = frame->header.id.value_or(0);
    const std::size_t payload_bytes = frame->payload.size();
    const bool known_sample = id != 0 && id <= stream.trace.size();
    if (const auto* mesh = std::get_if<protocol::MeshReply>(&frame->header.reply); mesh && mesh->delta) {
      // Every delta in arrival order, the view's re-extract after a reconnect (id 0) included.
      const std::int64_t sample_ns =
          known_sample ? static_cast<std::int64_t>(stream.trace[id - 1].time_ms * 1e6) : -1;
      clients::ReplyFrame copy;
      copy.header = frame->header;
      copy.payload = std::move(frame->payload);
      {
        std::lock_guard lock(stream.mutex);
        stream.to_apply.push_back({std::move(copy), sample_ns});
      }
      stream.to_apply_changed.notify_one();
    }
    if (!known_sample) continue;
    const std::size_t index = id - 1;
    const clients::GazeSample& sample = stream.trace[index];
    const auto sample_ns = static_cast<std::int64_t>(sample.time_ms * 1e6);
    std::size_t newly_from = 0, newly_to = 0;
    {
      std::lock_guard lock(stream.mutex);
      stream.answered = std::max(stream.answered, index + 1);
      if (std::holds_alternative<protocol::MeshReply>(frame->header.reply) && stream.reflected <= index) {
        newly_from = stream.reflected;
        newly_to = index + 1;
        stream.reflected = index + 1;
      }
    }
    std::lock_guard lock(totals.mutex);
    if (const auto* mesh = std::get_if<protocol::MeshReply>(&frame->header.reply)) {
      ++totals.meshes;
      totals.mesh_latency_us.record(
          static_cast<std::uint64_t>(std::max<std::int64_t>(0, now - sample_ns) / 1000));
      for (std::size_t i = newly_from; i < newly_to; ++i) {
        const auto t = static_cast<std::int64_t>(stream.trace[i].time_ms * 1e6);
        totals.sample_latency_us.record(
            static_cast<std::uint64_t>(std::max<std::int64_t>(0, now - t) / 1000));
      }
      // The reply must say it reflects this sample (JSON carries doubles exactly).
      if (!mesh->focus || (*mesh->focus)[0] != sample.x || (*mesh->focus)[1] != sample.y)
        ++totals.focus_mismatches;
      totals.superseded_counted += mesh->superseded;
      totals.bytes += payload_bytes;
      totals.triangles += mesh->triangles;
      totals.server_total_us += mesh->timings.total_us;
    } else if (const auto* error = std::get_if<protocol::ErrorReply>(&frame->header.reply)) {
      ++totals.errors_by_code[protocol::to_string(error->code)];
      if (error->code == protocol::ErrorKind::kSuperseded)
        ++totals.superseded;
      else
        ++totals.errors;
    }
  }
  {
    std::lock_guard lock(stream.mutex);
    stream.broken = true;
  }
  stream.changed.notify_all();
}

// Applies a stream's delta replies in arrival order until the receive loop is done and none is left.
void apply_loop(Stream& stream, Totals& totals, Clock::time_point start) {
  for (;;) {
    Stream::Received received;
    {
      std::unique_lock lock(stream.mutex);
      stream.to_apply_changed.wait(lock, [&] { return !stream.to_apply.empty() || stream.receiving_done; });
      if (stream.to_apply.empty()) return;
      received = std::move(stream.to_apply.front());
      stream.to_apply.pop_front();
    }
    const auto& mesh = std::get<protocol::MeshReply>(received.frame.header.reply);
    auto applied = stream.mesh.apply(mesh, received.frame.payload);
    const std::int64_t now = since(start);
    std::lock_guard lock(totals.mutex);
    if (!applied) {
      if (totals.delta_errors++ == 0) fmt::print(stderr, "mtlod-gaze: {}\n", applied.error().message);
    } else if (received.sample_ns >= 0) {
      totals.applied_latency_us.record(
          static_cast<std::uint64_t>(std::max<std::int64_t>(0, now - received.sample_ns) / 1000));
    }
  }
}

nlohmann::ordered_json percentiles_ms(const clients::LatencyHistogram& h) {
  auto ms = [](std::uint64_t us) { return us / 1000.0; };
  return {{"p50", ms(h.value_at_percentile(50))},
          {"p90", ms(h.value_at_percentile(90))},
          {"p99", ms(h.value_at_percentile(99))},
          {"p999", ms(h.value_at_percentile(99.9))},
          {"max", ms(h.max())},
          {"mean", h.mean() / 1000.0},
          {"count", h.count()}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "mtlod-gaze: replay a gaze trace (CSV time_ms,x,y) or a synthetic one against mtlod-server and "
      "measure gaze-to-mesh latency."};
  std::string model = "bunny", trace_file, json_file;
  clients::Endpoint endpoint;
  unsigned streams_count = 1;
  double drain_timeout_s = 10;
  bool quiet = false;
  clients::SynthesisOptions synthesis;
  clients::add_endpoint_flags(app, endpoint);
  app.add_option("--model", model, "model name")->capture_default_str();
  app.add_option("--trace", trace_file,
                 "CSV trace: time_ms,x,y per line (x, y normalised, 0,0 top left); "
                 "without it a trace is synthesised");
  app.add_option("--hz", synthesis.rate_hz, "synthesised trace: samples per second")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 10000.0));
  app.add_option("-d,--duration", synthesis.duration_ms, "synthesised trace: length in ms")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 86400e3));
  app.add_option("--seed", synthesis.seed, "synthesised trace: random seed (stream k uses seed + k)")
      ->capture_default_str();
  app.add_option("--streams", streams_count, "concurrent gaze streams, one connection each")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1024u));
  app.add_option("--drain-timeout", drain_timeout_s, "seconds to wait for outstanding replies at the end")
      ->capture_default_str();
  clients::RetryPolicy retry;
  app.add_option(
         "--attempts", retry.attempts,
         "connection attempts, with exponential backoff, when a connection drops (1: give up at once)")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1000u));
  app.add_option("--json", json_file, "write the report as JSON to this file");
  app.add_flag("-q,--quiet", quiet, "no progress line");
  std::string write_trace;
  app.add_option("--write-trace", write_trace,
                 "write the (first stream's) trace as CSV to this file and exit");
  protocol::ExtractFlags flags;
  protocol::add_extract_flags(app, flags);
  CLI11_PARSE(app, argc, argv);
  if (!flags.error && !flags.error_px) flags.error_px = 1;
  if (flags.silhouette.empty()) flags.silhouette = "2,0";
  if (flags.focus.empty()) flags.focus.push_back("0.5,0.5,20,0.1");

  std::vector<clients::GazeSample> file_trace;
  if (!trace_file.empty()) {
    std::ifstream in(trace_file);
    if (!in) return fail(fmt::format("{}: cannot read", trace_file));
    std::stringstream text;
    text << in.rdbuf();
    auto parsed = clients::parse_gaze_trace(text.str());
    if (!parsed) return fail(fmt::format("{}: {}", trace_file, parsed.error().message));
    file_trace = std::move(*parsed);
  }

  if (!write_trace.empty()) {
    const auto trace = file_trace.empty() ? clients::synthesize_gaze_trace(synthesis) : file_trace;
    std::ofstream out(write_trace);
    out << "time_ms,x,y\n";
    for (const auto& s : trace) out << fmt::format("{:.3f},{:.5f},{:.5f}\n", s.time_ms, s.x, s.y);
    if (!out) return fail(fmt::format("{}: write failed", write_trace));
    fmt::print("wrote {} samples to {}\n", trace.size(), write_trace);
    return 0;
  }

  // Every stream opens its view with one extract first; that set-up is not measured.
  std::vector<std::unique_ptr<Stream>> streams;
  for (unsigned k = 0; k < streams_count; ++k) {
    auto stream = std::make_unique<Stream>();
    if (file_trace.empty()) {
      clients::SynthesisOptions o = synthesis;
      o.seed = synthesis.seed + k;
      stream->trace = clients::synthesize_gaze_trace(o);
    } else {
      stream->trace = file_trace;
    }
    stream->rng.seed(synthesis.seed * 7919 + k);
    auto session = clients::open_session(endpoint, "mtlod-gaze/0.1", retry, stream->rng);
    if (!session) return fail(session.error().message);
    auto connection = std::make_shared<clients::Connection>(std::move(session->connection));
    auto info = connection->call(protocol::ModelInfo{model}, 0);
    if (!info) return fail(info.error().message);
    const auto* m = std::get_if<protocol::ModelInfoReply>(&info->header.reply);
    if (!m) return fail(fmt::format("model '{}' is not served", model));
    auto request = protocol::make_extract(flags, model, m->bounds_min, m->bounds_max);
    if (!request) return fail(request.error().message);
    request->criteria.focus.front().x = stream->trace.front().x;
    request->criteria.focus.front().y = stream->trace.front().y;
    auto first = connection->call(*request, 0, std::chrono::seconds(120));
    if (!first) return fail(first.error().message);
    if (const auto* e = std::get_if<protocol::ErrorReply>(&first->header.reply))
      return fail("extract: " + e->message);
    if (const auto* mesh = std::get_if<protocol::MeshReply>(&first->header.reply); mesh && mesh->delta) {
      if (auto applied = stream->mesh.apply(*mesh, first->payload); !applied)
        return fail(applied.error().message);
    }
    stream->view = std::move(*request);
    stream->connection = std::move(connection);
    streams.push_back(std::move(stream));
  }

  Totals totals;
  std::atomic<bool> finished{false};
  const Link link{endpoint, retry, totals, finished};
  std::atomic<unsigned> senders_done{0};
  const Clock::time_point start = Clock::now();
  std::vector<std::thread> threads;
  for (auto& s : streams) {
    Stream& stream = *s;
    threads.emplace_back([&stream, &link, start] {
      receive_loop(stream, link, start);
      {
        std::lock_guard lock(stream.mutex);
        stream.receiving_done = true;
      }
      stream.to_apply_changed.notify_all();
    });
    if (flags.delta) threads.emplace_back([&stream, &totals, start] { apply_loop(stream, totals, start); });
    threads.emplace_back([&stream, &totals, &senders_done, start] {
      for (std::size_t i = 0; i < stream.trace.size(); ++i) {
        const clients::GazeSample& sample = stream.trace[i];
        std::this_thread::sleep_until(
            start + std::chrono::nanoseconds(static_cast<std::int64_t>(sample.time_ms * 1e6)));
        std::lock_guard send_lock(stream.send_mutex);
        std::shared_ptr<clients::Connection> connection;
        {
          std::lock_guard lock(stream.mutex);
          if (stream.broken) break;
          stream.sent = i + 1;
          connection = stream.connection;
        }
        // A failed send is the receiver's to handle: it reconnects and sends the newest sample again.
        (void)connection->send(protocol::Gaze{sample.x, sample.y, std::nullopt, std::nullopt}, i + 1);
        std::lock_guard lock(totals.mutex);
        ++totals.sent;
      }
      ++senders_done;
    });
  }

  double trace_ms = 0;
  for (auto& s : streams) trace_ms = std::max(trace_ms, s->trace.back().time_ms);
  const auto drain_deadline =
      start + std::chrono::milliseconds(static_cast<std::int64_t>(trace_ms + drain_timeout_s * 1000));
  const bool progress = !quiet && ::isatty(STDERR_FILENO);
  auto outstanding = [&] {
    std::size_t n = 0;
    for (auto& s : streams) {
      std::lock_guard lock(s->mutex);
      if (!s->broken) n += s->sent - s->answered;
    }
    return n;
  };
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (progress) {
      std::lock_guard lock(totals.mutex);
      fmt::print(stderr, "\r{:6.1f} s  samples {:>7}  meshes {:>7}  superseded {:>7}  p99 {:>7.2f} ms   ",
                 since(start) / 1e9, totals.sent, totals.meshes, totals.superseded,
                 totals.mesh_latency_us.value_at_percentile(99) / 1e3);
    }
    if (senders_done == streams.size() && outstanding() == 0) break;
    if (Clock::now() >= drain_deadline) break;
  }
  if (progress) fmt::print(stderr, "\n");
  const std::size_t lost = outstanding();
  finished = true;
  for (auto& s : streams) {
    std::lock_guard lock(s->mutex);
    if (s->connection) s->connection->interrupt();
  }
  for (auto& t : threads) t.join();

  const Totals& r = totals;
  const double elapsed_s = since(start) / 1e9;
  const double per_mesh = std::max<double>(1, static_cast<double>(r.meshes));
  nlohmann::ordered_json report = {
      {"model", model},
      {"streams", streams_count},
      {"trace", trace_file.empty()
                    ? fmt::format("synthetic {} Hz, {} ms", synthesis.rate_hz, synthesis.duration_ms)
                    : trace_file},
      {"budget", flags.budget ? nlohmann::json(*flags.budget) : nlohmann::json(nullptr)},
      {"elapsed_s", elapsed_s},
      {"samples", r.sent},
      {"requests", r.meshes + r.superseded + r.errors},
      {"meshes", r.meshes},
      {"superseded", r.superseded},
      {"superseded_counted_by_server", r.superseded_counted},
      {"errors", r.errors},
      {"errors_by_code", r.errors_by_code},
      {"lost", lost},
      {"reconnects", r.reconnects},
      {"resent", r.resent},
      {"focus_mismatches", r.focus_mismatches},
      {"delta", flags.delta},
      {"delta_errors", r.delta_errors},
      {"throughput_rps", r.meshes / std::max(elapsed_s, 1e-9)},
      {"latency_ms", percentiles_ms(r.mesh_latency_us)},
      {"sample_latency_ms", percentiles_ms(r.sample_latency_us)},
      {"applied_latency_ms",
       flags.delta ? percentiles_ms(r.applied_latency_us) : nlohmann::ordered_json(nullptr)},
      {"mean_triangles", r.triangles / per_mesh},
      {"bytes", r.bytes},
      {"server_total_us_mean", r.server_total_us / per_mesh},
  };
  const auto& h = r.mesh_latency_us;
  fmt::print(
      "{} stream(s) on {}: {} samples, {} meshes, {} superseded (server counted {}), {} errors, {} lost\n",
      streams_count, model, r.sent, r.meshes, r.superseded, r.superseded_counted, r.errors, lost);
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
  if (!json_file.empty()) {
    std::ofstream out(json_file);
    out << report.dump(2) << "\n";
    if (!out) return fail(fmt::format("{}: write failed", json_file));
  }
  return r.meshes > 0 ? 0 : 1;
}

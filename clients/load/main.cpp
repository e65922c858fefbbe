// mtlod-load: a load tester for mtlod-server (issue 6). Closed loop: N connections, each sends its
// next request when the previous reply is in. Open loop (--rate): requests are due on a fixed
// schedule whatever the server does, and latency counts from the due time, so queueing shows.
// Each connection has a sending and a receiving thread; replies come back in request order.
// When a connection drops or its server drains (`shutting_down`), the stream reconnects with
// backoff and sends its unanswered requests again, so a failover shows as latency and retries,
// not as lost requests; --reconnect-after recycles connections so a load balancer can rebalance.
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
#include <string>
#include <thread>
#include <vector>

#include "CLI/CLI.hpp"
#include "clients/common/extract_flags.hpp"
#include "clients/common/retry.hpp"
#include "clients/load/histogram.hpp"
#include "clients/load/schedule.hpp"
#include "clients/load/workload.hpp"
#include "fmt/format.h"
#include "nlohmann/json.hpp"
#include "protocol/camera.hpp"

namespace {

using namespace mtlod;
using Clock = std::chrono::steady_clock;

struct Options {
  clients::Endpoint endpoint;
  std::vector<std::string> models{"bunny"};
  unsigned connections = 1;
  double duration_s = 10;
  std::uint64_t max_requests = 0;  // 0: bounded by duration only
  double rate = 0;                 // open loop: requests per second over all connections; 0: closed loop
  std::string arrivals = "uniform";
  unsigned window = 0;  // open loop: unanswered requests per connection; 0: the server's max_in_flight
  std::string cameras = "random";  // random, fixed or a script file
  bool random_focus = true;
  std::string mix = "extract=1";
  double gaze_hz = 0;
  double drain_timeout_s = 10;
  std::uint64_t seed = 1;
  clients::RetryPolicy retry;
  std::uint64_t reconnect_after = 0;  // requests per connection before it is replaced; 0: never
  std::string json_file;
  bool quiet = false;
};

struct ModelView {
  std::string name;
  std::array<double, 3> bounds_min{}, bounds_max{};
  protocol::Extract base;  // the flags' request for this model
};

// Everything the receivers record, under one mutex (a few thousand replies per second at most).
struct Totals {
  std::mutex mutex;
  clients::LatencyHistogram latency_us;       // mesh replies, from the due (open) or send (closed) time
  clients::LatencyHistogram server_total_us;  // the server's own total per mesh reply
  std::uint64_t sent = 0, ok = 0, superseded = 0, errors = 0, bytes = 0, triangles = 0;
  std::map<std::string, std::uint64_t> errors_by_code;
  protocol::StageTimings stage_sums;
  std::int64_t last_reply_ns = 0;
  std::uint64_t reconnects = 0, retried = 0, gave_up = 0;
  struct Instance {
    std::uint64_t ok = 0;
    std::int64_t first_ns = -1, last_ns = 0;
  };
  std::map<std::string, Instance> instances;  // mesh replies by the server process that sent them
};

struct Pending {
  std::uint64_t id;
  std::int64_t intended_ns;   // latency starts here
  protocol::Request request;  // kept to send again after a reconnect
  bool setup = false;         // an extract re-sent to restore the view for gazes: not counted
};

// One logical connection: the sender thread fills `pending`, the receiver thread empties it. The
// socket under it may be replaced (a drop, a draining server, --reconnect-after).
struct Stream {
  std::mutex send_mutex;  // held while sending and while the connection is replaced (before `mutex`)
  std::mutex mutex;       // guards what follows
  std::condition_variable changed;
  std::shared_ptr<clients::Connection> connection;
  std::uint64_t generation = 0;  // bumped at every new connection
  bool reconnecting = false;
  bool broken = false;   // no connection and no attempts left
  std::string instance;  // the server process on the current connection
  std::deque<Pending> pending;
  std::optional<protocol::Extract> view;  // the last extract sent: restores the view for gazes
  std::uint64_t next_id = 1;
  std::uint64_t sent_on_connection = 0;
  std::uint64_t unsent = 0;  // due requests the window held back past the end of the test
  std::mt19937_64 rng;       // backoff jitter
};

// What reconnecting needs from the run.
struct Link {
  const Options& options;
  Totals& totals;
  std::atomic<bool>& finished;  // the run is over: no more reconnecting
};

std::int64_t since(Clock::time_point start) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - start).count();
}

int fail(const std::string& message) {
  fmt::print(stderr, "mtlod-load: {}\n", message);
  return 1;
}

// Replaces the stream's connection, unless another thread already replaced generation `failed`:
// closes it, reconnects with backoff, and sends every unanswered request again in order (an
// extract first when gazes need their view back). Returns false when the stream gave up.
bool reconnect(Stream& stream, const Link& link, std::uint64_t failed) {
  std::lock_guard send_lock(stream.send_mutex);
  std::shared_ptr<clients::Connection> old;
  {
    std::lock_guard lock(stream.mutex);
    if (stream.generation != failed || stream.broken) return !stream.broken;
    stream.reconnecting = true;
    old = stream.connection;
  }
  if (old) old->interrupt();
  auto session = clients::open_session(link.options.endpoint, "mtlod-load/0.1", link.options.retry,
                                       stream.rng, nullptr, &link.finished);
  std::vector<Pending> resend;
  auto connection = session ? std::make_shared<clients::Connection>(std::move(session->connection)) : nullptr;
  {
    std::lock_guard lock(stream.mutex);
    stream.reconnecting = false;
    if (!connection) {
      stream.broken = true;
    } else {
      stream.connection = connection;
      ++stream.generation;
      stream.instance = session->hello.instance;
      stream.sent_on_connection = 0;
      // A gaze before any extract in the queue needs the view back first.
      for (const Pending& p : stream.pending) {
        if (std::holds_alternative<protocol::Extract>(p.request)) break;
        if (std::holds_alternative<protocol::Gaze>(p.request) && stream.view) {
          stream.pending.push_front(Pending{stream.next_id++, 0, *stream.view, true});
          break;
        }
      }
      resend.assign(stream.pending.begin(), stream.pending.end());
    }
  }
  stream.changed.notify_all();
  {
    std::lock_guard lock(link.totals.mutex);
    if (!connection) {
      ++link.totals.gave_up;
    } else {
      ++link.totals.reconnects;
      for (const Pending& p : resend) link.totals.retried += p.setup ? 0 : 1;
    }
  }
  if (!connection) return false;
  // A send that fails here shows up as a failed receive on the new connection.
  for (const Pending& p : resend) {
    if (!connection->send(p.request, p.id)) break;
  }
  return true;
}

void receive_loop(Stream& stream, const Link& link, Clock::time_point start) {
  Totals& totals = link.totals;
  for (;;) {
    std::shared_ptr<clients::Connection> connection;
    std::uint64_t generation = 0;
    std::string instance;
    {
      std::unique_lock lock(stream.mutex);
      stream.changed.wait(lock, [&] { return !stream.reconnecting; });
      if (stream.broken) break;
      connection = stream.connection;
      generation = stream.generation;
      instance = stream.instance;
    }
    auto frame = connection->receive(std::chrono::hours(1));
    const std::int64_t now = since(start);
    if (!frame || clients::asks_for_retry(*frame)) {
      if (link.finished) break;
      {
        // Replaced on purpose (--reconnect-after) or by the other thread: carry on with the new one.
        std::lock_guard lock(stream.mutex);
        if (stream.reconnecting || stream.generation != generation) continue;
      }
      if (!reconnect(stream, link, generation)) break;
      continue;
    }
    Pending pending{0, now, protocol::Ping{}};
    {
      std::lock_guard lock(stream.mutex);
      // Replies come in request order; an unmatched id (a refusal without id) takes no request.
      if (!stream.pending.empty() && frame->header.id == stream.pending.front().id) {
        pending = std::move(stream.pending.front());
        stream.pending.pop_front();
      }
    }
    stream.changed.notify_all();
    std::lock_guard lock(totals.mutex);
    totals.last_reply_ns = std::max(totals.last_reply_ns, now);
    if (pending.setup && std::holds_alternative<protocol::MeshReply>(frame->header.reply)) continue;
    if (const auto* mesh = std::get_if<protocol::MeshReply>(&frame->header.reply)) {
      ++totals.ok;
      auto& server = totals.instances[instance];
      ++server.ok;
      if (server.first_ns < 0) server.first_ns = now;
      server.last_ns = now;
      totals.latency_us.record(
          static_cast<std::uint64_t>(std::max<std::int64_t>(0, now - pending.intended_ns) / 1000));
      totals.server_total_us.record(mesh->timings.total_us);
      totals.bytes += frame->payload.size();
      totals.triangles += mesh->triangles;
      auto& s = totals.stage_sums;
      const auto& t = mesh->timings;
      s.queue_us += t.queue_us, s.map_us += t.map_us, s.occupancy_us += t.occupancy_us, s.dt_us += t.dt_us;
      s.labels_us += t.labels_us, s.refine_us += t.refine_us, s.encode_us += t.encode_us,
          s.total_us += t.total_us;
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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "mtlod-load: load test for mtlod-server: closed loop (N connections, each waits for its reply) "
      "or open loop (--rate: a fixed arrival schedule, latency from each request's due time)."};
  Options o;
  clients::add_endpoint_flags(app, o.endpoint);
  app.add_option("--model", o.models, "model name; repeat to spread connections over several models")
      ->capture_default_str()
      ->take_all();
  app.add_option("-c,--connections", o.connections, "connections")
      ->capture_default_str()
      ->check(CLI::Range(1u, 4096u));
  app.add_option("-d,--duration", o.duration_s, "seconds of sending (replies are awaited after)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
  app.add_option("-n,--requests", o.max_requests, "stop after this many requests (0: duration only)")
      ->capture_default_str();
  app.add_option("--rate", o.rate, "open loop: requests per second over all connections (0: closed loop)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e6));
  app.add_option("--arrivals", o.arrivals, "open loop schedule: uniform or poisson")->capture_default_str();
  app.add_option(
         "--window", o.window,
         "open loop: unanswered requests per connection before sending waits (0: the server's max_in_flight)")
      ->capture_default_str();
  app.add_option("--cameras", o.cameras,
                 "random (orbits around the model), fixed (the camera flags) or a script file of "
                 "ex,ey,ez,tx,ty,tz[,fx,fy] lines, cycled")
      ->capture_default_str();
  app.add_option("--random-focus", o.random_focus, "each extract gets a random focus point (true/false)")
      ->capture_default_str();
  app.add_option("--mix", o.mix,
                 "request kinds by weight: extract=W,gaze=W (a gaze moves the focus of the "
                 "connection's last extract)")
      ->capture_default_str();
  app.add_option(
         "--gaze-hz", o.gaze_hz,
         "gaze streams: every connection sends one extract, then gaze updates at this rate (sets --mix "
         "gaze=1 and --rate to connections × Hz)")
      ->check(CLI::Range(0.0, 10000.0));
  app.add_option("--drain-timeout", o.drain_timeout_s, "seconds to wait for outstanding replies at the end")
      ->capture_default_str();
  app.add_option("--seed", o.seed, "random seed for cameras, foci, mix and Poisson arrivals")
      ->capture_default_str();
  app.add_option(
         "--attempts", o.retry.attempts,
         "connection attempts when a connection drops or its server drains, with exponential backoff; the "
         "unanswered requests are then sent again (1: give up at once)")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1000u));
  app.add_option(
         "--reconnect-after", o.reconnect_after,
         "requests per connection: then it waits for its replies and reconnects, so a load balancer can "
         "move it (0: never)")
      ->capture_default_str();
  app.add_option("--json", o.json_file, "write the report as JSON to this file");
  app.add_flag("-q,--quiet", o.quiet, "no progress line");
  protocol::ExtractFlags flags;
  protocol::add_extract_flags(app, flags);
  CLI11_PARSE(app, argc, argv);

  if (!flags.error && !flags.error_px) flags.error_px = 1;
  if (flags.silhouette.empty()) flags.silhouette = "2,0";
  if (o.gaze_hz > 0) {
    o.mix = "gaze=1";
    o.rate = o.gaze_hz * o.connections;
  }
  auto mix = clients::parse_mix(o.mix);
  if (!mix) return fail(mix.error().message);
  if (o.arrivals != "uniform" && o.arrivals != "poisson")
    return fail("--arrivals must be uniform or poisson");
  std::vector<clients::ScriptedCamera> script;
  if (o.cameras != "random" && o.cameras != "fixed") {
    std::ifstream in(o.cameras);
    if (!in) return fail(fmt::format("{}: cannot read the camera script", o.cameras));
    std::stringstream text;
    text << in.rdbuf();
    auto parsed = clients::parse_camera_script(text.str());
    if (!parsed) return fail(fmt::format("{}: {}", o.cameras, parsed.error().message));
    script = std::move(*parsed);
  }
  const bool open_loop = o.rate > 0;

  // Connect everything first: connection set-up is not part of the measurement.
  std::vector<std::unique_ptr<Stream>> streams;
  std::uint32_t server_window = 8;
  for (unsigned c = 0; c < o.connections; ++c) {
    auto stream = std::make_unique<Stream>();
    stream->rng.seed(o.seed * 7919 + c);
    auto session = clients::open_session(o.endpoint, "mtlod-load/0.1", o.retry, stream->rng);
    if (!session) return fail(session.error().message);
    server_window = session->hello.limits.max_in_flight;
    stream->instance = session->hello.instance;
    stream->connection = std::make_shared<clients::Connection>(std::move(session->connection));
    streams.push_back(std::move(stream));
  }
  std::vector<ModelView> models;
  for (const std::string& name : o.models) {
    auto info = streams.front()->connection->call(protocol::ModelInfo{name}, 0);
    if (!info) return fail(info.error().message);
    const auto* m = std::get_if<protocol::ModelInfoReply>(&info->header.reply);
    if (!m)
      return fail(
          fmt::format("model '{}': {}", name, std::get<protocol::ErrorReply>(info->header.reply).message));
    auto base = protocol::make_extract(flags, name, m->bounds_min, m->bounds_max);
    if (!base) return fail(base.error().message);
    models.push_back(ModelView{name, m->bounds_min, m->bounds_max, std::move(*base)});
  }
  const unsigned window = open_loop ? (o.window ? o.window : server_window) : 1;

  const auto duration_ns = static_cast<std::int64_t>(o.duration_s * 1e9);
  std::vector<std::vector<std::int64_t>> plan;
  if (open_loop) {
    plan = clients::plan_arrivals(
        clients::ArrivalSchedule(
            o.rate, o.arrivals == "poisson" ? clients::Arrivals::kPoisson : clients::Arrivals::kUniform,
            o.seed),
        duration_ns, o.max_requests, o.connections);
  }

  Totals totals;
  std::atomic<bool> finished{false};
  const Link link{o, totals, finished};
  std::atomic<std::uint64_t> issued{0};  // closed loop: requests taken from --requests
  std::atomic<unsigned> senders_done{0};
  const Clock::time_point start = Clock::now();
  std::vector<std::thread> threads;
  for (unsigned c = 0; c < o.connections; ++c) {
    Stream& stream = *streams[c];
    threads.emplace_back([&stream, &link, start] { receive_loop(stream, link, start); });
    threads.emplace_back([&, c] {
      std::mt19937_64 rng(o.seed * 1000003 + c);
      const ModelView& model = models[c % models.size()];
      std::uniform_real_distribution<double> unit(0.1, 0.9);
      std::uniform_real_distribution<double> pick(0, mix->extract + mix->gaze);
      std::size_t script_index = c;
      bool has_view = false;
      for (std::size_t i = 0;; ++i) {
        std::int64_t intended = 0;
        if (open_loop) {
          if (i >= plan[c].size()) break;
          intended = plan[c][i];
          std::this_thread::sleep_until(start + std::chrono::nanoseconds(intended));
        } else {
          if (since(start) >= duration_ns) break;
          if (o.max_requests && issued.fetch_add(1) >= o.max_requests) break;
        }
        if (o.reconnect_after) {
          // Recycle the connection once its replies are in, so a load balancer can place it anew.
          std::unique_lock lock(stream.mutex);
          if (stream.sent_on_connection >= o.reconnect_after) {
            const bool idle =
                stream.changed.wait_until(lock, start + std::chrono::nanoseconds(duration_ns),
                                          [&] { return stream.broken || stream.pending.empty(); });
            const std::uint64_t generation = stream.generation;
            lock.unlock();
            if (idle && !reconnect(stream, link, generation)) break;
          }
        }
        {
          // Wait for room in the window; past the end of the test, give up on the rest.
          std::unique_lock lock(stream.mutex);
          const bool room =
              stream.changed.wait_until(lock, start + std::chrono::nanoseconds(duration_ns),
                                        [&] { return stream.broken || stream.pending.size() < window; });
          if (stream.broken) break;
          if (!room) {
            stream.unsent += open_loop ? plan[c].size() - i : 0;
            break;
          }
        }
        protocol::Request request;
        if (has_view && pick(rng) >= mix->extract) {
          request = protocol::Gaze{unit(rng), unit(rng), std::nullopt, std::nullopt};
        } else {
          protocol::Extract e = model.base;
          if (o.cameras == "random") {
            clients::random_orbit_camera(model.bounds_min, model.bounds_max, flags.fov_deg, rng, e);
          } else if (!script.empty()) {
            const clients::ScriptedCamera& s = script[script_index++ % script.size()];
            protocol::LookAt look{s.eye, s.target, {0, 1, 0}, flags.fov_deg};
            protocol::look_at_camera(look, static_cast<double>(e.viewport[0]) / e.viewport[1], e.view,
                                     e.projection);
            if (s.has_focus) {
              if (e.criteria.focus.empty()) e.criteria.focus.emplace_back();
              e.criteria.focus.front().x = s.focus[0];
              e.criteria.focus.front().y = s.focus[1];
            }
          }
          if (o.random_focus && script.empty()) {
            if (e.criteria.focus.empty()) e.criteria.focus.emplace_back();
            e.criteria.focus.front().x = unit(rng);
            e.criteria.focus.front().y = unit(rng);
          }
          request = std::move(e);
          has_view = true;
        }
        std::shared_ptr<clients::Connection> connection;
        std::uint64_t this_id = 0;
        std::lock_guard send_lock(stream.send_mutex);
        {
          std::lock_guard lock(stream.mutex);
          if (stream.broken) break;
          if (!open_loop) intended = since(start);
          this_id = stream.next_id++;
          if (const auto* e = std::get_if<protocol::Extract>(&request)) stream.view = *e;
          stream.pending.push_back(Pending{this_id, intended, request});
          ++stream.sent_on_connection;
          connection = stream.connection;
        }
        // A failed send is the receiver's to handle: it reconnects and sends `pending` again.
        (void)connection->send(request, this_id);
        std::lock_guard lock(totals.mutex);
        ++totals.sent;
      }
      ++senders_done;
    });
  }

  // Progress on a terminal, until every sender has finished and the replies are in (or the drain
  // timeout passes).
  const bool progress = !o.quiet && ::isatty(STDERR_FILENO);
  const auto drain_deadline = start + std::chrono::nanoseconds(duration_ns) +
                              std::chrono::milliseconds(static_cast<std::int64_t>(o.drain_timeout_s * 1000));
  auto outstanding = [&] {
    std::size_t n = 0;
    for (auto& s : streams) {
      std::lock_guard lock(s->mutex);
      for (const Pending& p : s->pending) n += p.setup ? 0 : 1;
    }
    return n;
  };
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (progress) {
      const double t = since(start) / 1e9;
      std::lock_guard lock(totals.mutex);
      fmt::print(
          stderr,
          "\r{:6.1f} s  sent {:>8}  mesh {:>8}  {:>8.1f}/s  p50 {:>7.2f} ms  p99 {:>7.2f} ms  errors {}  "
          "reconnects {}   ",
          t, totals.sent, totals.ok, totals.ok / std::max(t, 1e-3),
          totals.latency_us.value_at_percentile(50) / 1e3, totals.latency_us.value_at_percentile(99) / 1e3,
          totals.errors, totals.reconnects);
    }
    if (senders_done == o.connections && outstanding() == 0) break;
    if (Clock::now() >= drain_deadline) break;
  }
  if (progress) fmt::print(stderr, "\n");
  finished = true;
  // Senders may still wait on a window or a reconnect: end every receive, then wake them.
  for (auto& s : streams) {
    std::lock_guard lock(s->mutex);
    s->broken = true;
    if (s->connection) s->connection->interrupt();
  }
  for (auto& s : streams) s->changed.notify_all();
  for (auto& t : threads) t.join();
  const std::uint64_t lost = outstanding();
  std::uint64_t unsent = 0;
  for (auto& s : streams) unsent += s->unsent;

  // The report.
  const Totals& r = totals;
  const double elapsed_s =
      std::max<double>(std::min(o.duration_s, since(start) / 1e9), r.last_reply_ns / 1e9);
  const double throughput = r.ok / std::max(elapsed_s, 1e-9);
  auto ms = [](std::uint64_t us) { return us / 1000.0; };
  const auto& h = r.latency_us;
  const double mean_div = std::max<double>(1, static_cast<double>(r.ok));
  const auto& s = r.stage_sums;
  nlohmann::ordered_json report = {
      {"mode", open_loop ? "open" : "closed"},
      {"models", o.models},
      {"connections", o.connections},
      {"rate_rps", o.rate},
      {"mix", o.mix},
      {"budget", flags.budget ? nlohmann::json(*flags.budget) : nlohmann::json(nullptr)},
      {"duration_s", o.duration_s},
      {"elapsed_s", elapsed_s},
      {"sent", r.sent},
      {"requests", r.ok + r.errors + r.superseded},
      {"ok", r.ok},
      {"errors", r.errors},
      {"superseded", r.superseded},
      {"errors_by_code", r.errors_by_code},
      {"unsent", unsent},
      {"lost", lost},
      {"reconnects", r.reconnects},
      {"retried", r.retried},
      {"gave_up", r.gave_up},
      {"throughput_rps", throughput},
      {"latency_ms",
       {{"p50", ms(h.value_at_percentile(50))},
        {"p90", ms(h.value_at_percentile(90))},
        {"p99", ms(h.value_at_percentile(99))},
        {"p999", ms(h.value_at_percentile(99.9))},
        {"max", ms(h.max())},
        {"mean", h.mean() / 1000.0},
        {"min", ms(h.min())}}},
      {"bytes", r.bytes},
      {"bytes_per_s", r.bytes / std::max(elapsed_s, 1e-9)},
      {"mean_triangles", r.triangles / mean_div},
      {"server_us",
       {{"queue", s.queue_us / mean_div},
        {"map", s.map_us / mean_div},
        {"occupancy", s.occupancy_us / mean_div},
        {"dt", s.dt_us / mean_div},
        {"labels", s.labels_us / mean_div},
        {"refine", s.refine_us / mean_div},
        {"encode", s.encode_us / mean_div},
        {"total", s.total_us / mean_div},
        {"total_p50", r.server_total_us.value_at_percentile(50)},
        {"total_p99", r.server_total_us.value_at_percentile(99)}}},
  };
  nlohmann::ordered_json instances = nlohmann::ordered_json::object();
  for (const auto& [name, i] : r.instances) {
    instances[name] = {{"ok", i.ok}, {"first_reply_s", i.first_ns / 1e9}, {"last_reply_s", i.last_ns / 1e9}};
  }
  report["instances"] = std::move(instances);
  fmt::print("{} loop, {} connection(s), models {}, {:.1f} s{}\n", open_loop ? "open" : "closed",
             o.connections, fmt::join(o.models, ","), elapsed_s,
             open_loop ? fmt::format(", {:.0f} requests/s offered", o.rate) : "");
  fmt::print("  requests  sent {}  mesh {}  errors {}  superseded {}  unsent {}  lost {}\n", r.sent, r.ok,
             r.errors, r.superseded, unsent, lost);
  for (const auto& [code, n] : r.errors_by_code) fmt::print("    {:<20} {}\n", code, n);
  if (r.reconnects || r.gave_up) {
    fmt::print("  reconnects {}, requests sent again {}, streams that gave up {}\n", r.reconnects, r.retried,
               r.gave_up);
  }
  if (r.instances.size() > 1) {
    for (const auto& [name, i] : r.instances) {
      fmt::print("    {:<28} {:>8} meshes  {:.1f}..{:.1f} s\n", name, i.ok, i.first_ns / 1e9,
                 i.last_ns / 1e9);
    }
  }
  fmt::print("  throughput {:.1f} meshes/s, {:.2f} MB/s, {:.0f} triangles and {:.0f} bytes per mesh\n",
             throughput, r.bytes / std::max(elapsed_s, 1e-9) / 1e6, r.triangles / mean_div,
             r.bytes / mean_div);
  fmt::print("  latency ms  p50 {:.2f}  p90 {:.2f}  p99 {:.2f}  p99.9 {:.2f}  max {:.2f}  mean {:.2f}\n",
             ms(h.value_at_percentile(50)), ms(h.value_at_percentile(90)), ms(h.value_at_percentile(99)),
             ms(h.value_at_percentile(99.9)), ms(h.max()), h.mean() / 1000.0);
  fmt::print(
      "  server µs (mean)  queue {:.0f}  map {:.0f}  occupancy {:.0f}  dt {:.0f}  labels {:.0f}  refine "
      "{:.0f}  "
      "encode {:.0f}  total {:.0f}\n",
      s.queue_us / mean_div, s.map_us / mean_div, s.occupancy_us / mean_div, s.dt_us / mean_div,
      s.labels_us / mean_div, s.refine_us / mean_div, s.encode_us / mean_div, s.total_us / mean_div);
  if (!o.json_file.empty()) {
    std::ofstream out(o.json_file);
    out << report.dump(2) << "\n";
    if (!out) return fail(fmt::format("{}: write failed", o.json_file));
  }
  return r.ok > 0 ? 0 : 1;
}

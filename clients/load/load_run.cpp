// A run of mtlod-load (see load_run.hpp).
#include "clients/load/load_run.hpp"

#include <unistd.h>

#include <cstdio>
#include <memory>
#include <thread>

#include "clients/common/scene_view.hpp"
#include "clients/load/schedule.hpp"
#include "fmt/format.h"

namespace mtlod::clients {
namespace {

using Streams = std::vector<std::unique_ptr<LoadStream>>;

// Connects every stream first: connection set-up is not part of the measurement. Returns the
// server's max_in_flight (the open loop's default window).
Result<std::uint32_t> connect_streams(LoadRun& run, Streams& streams) {
  std::uint32_t server_window = 8;
  for (unsigned c = 0; c < run.options.connections; ++c) {
    streams.push_back(std::make_unique<LoadStream>(run, c));
    MTLOD_TRY(const protocol::HelloReply hello, streams.back()->session().connect());
    server_window = hello.limits.max_in_flight;
  }
  return server_window;
}

// Each model's bounds and each scene's, and the extract the flags make for it: the models first,
// then the scenes.
Result<std::vector<ModelView>> describe_views(ServerConnection& connection, const LoadOptions& options,
                                              const clients::ExtractFlags& flags) {
  std::vector<ModelView> models;
  for (const std::string& name : options.models) {
    MTLOD_TRY(const ReplyFrame info, connection.call(protocol::ModelInfo{name}, 0));
    const auto* m = std::get_if<protocol::ModelInfoReply>(&info.header.reply);
    if (!m) {
      return make_error(
          ErrorCode::kNotFound,
          fmt::format("model '{}': {}", name, std::get<protocol::ErrorReply>(info.header.reply).message));
    }
    MTLOD_TRY(protocol::Extract base, clients::make_extract(flags, name, m->bounds_min, m->bounds_max));
    models.push_back(ModelView{name, m->bounds_min, m->bounds_max, std::move(base)});
  }
  for (std::size_t i = 0; i < options.scene_files.size(); ++i) {
    const std::string& file = options.scene_files[i];
    MTLOD_TRY(SceneView scene, describe_scene(connection, file, options.scenes[i], flags));
    models.push_back(ModelView{"scene " + file, scene.box.min, scene.box.max, std::move(scene.extract)});
  }
  return models;
}

std::size_t outstanding(Streams& streams) {
  std::size_t n = 0;
  for (auto& s : streams) n += s->outstanding();
  return n;
}

void print_progress(LoadRun& run, Streams& streams) {
  std::uint64_t reconnects = 0;
  for (auto& s : streams) reconnects += s->session().reconnects();
  const double t = nanoseconds_between(run.start, Clock::now()) / 1e9;
  LoadTotals& totals = run.totals;
  std::lock_guard lock(totals.mutex);
  fmt::print(stderr,
             "\r{:6.1f} s  sent {:>8}  mesh {:>8}  {:>8.1f}/s  p50 {:>7.2f} ms  p99 {:>7.2f} ms  errors {}  "
             "reconnects {}   ",
             t, totals.sent, totals.ok, totals.ok / std::max(t, 1e-3),
             totals.latency_us.value_at_percentile(50) / 1e3, totals.latency_us.value_at_percentile(99) / 1e3,
             totals.errors, reconnects);
}

// Shows progress on a terminal until every sender has finished and the replies are in, or the
// drain timeout passes.
void wait_for_replies(LoadRun& run, Streams& streams) {
  const bool progress = !run.options.quiet && ::isatty(STDERR_FILENO);
  const auto drain_deadline =
      run.end_of_sending() +
      std::chrono::milliseconds(static_cast<std::int64_t>(run.options.drain_timeout_s * 1000));
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (progress) print_progress(run, streams);
    if (run.senders_done == run.options.connections && outstanding(streams) == 0) break;
    if (Clock::now() >= drain_deadline) break;
  }
  if (progress) fmt::print(stderr, "\n");
}

}  // namespace

Result<LoadRunEnd> run_load(const LoadOptions& options, const RequestSettings& requests,
                            const clients::ExtractFlags& flags, LoadTotals& totals) {
  LoadRun run(options, requests, totals);
  Streams streams;
  MTLOD_TRY(const std::uint32_t server_window, connect_streams(run, streams));
  MTLOD_TRY(run.models, describe_views(streams.front()->session().connection(), options, flags));
  run.window = options.open_loop() ? (options.window ? options.window : server_window) : 1;
  run.duration_ns = static_cast<std::int64_t>(options.duration_s * 1e9);
  if (options.open_loop()) {
    const Arrivals arrivals = options.arrivals == "poisson" ? Arrivals::kPoisson : Arrivals::kUniform;
    run.plan = plan_arrivals(ArrivalSchedule(options.rate, arrivals, options.seed), run.duration_ns,
                             options.max_requests, options.connections);
  }

  run.start = Clock::now();
  std::vector<std::thread> threads;
  for (auto& s : streams) {
    LoadStream& stream = *s;
    threads.emplace_back([&stream] { stream.session().receive_replies(); });
    threads.emplace_back([&stream] { stream.send_requests(); });
  }
  wait_for_replies(run, streams);
  run.finished = true;
  // Senders may still wait on a window or a reconnect: end every receive, then wake them.
  for (auto& s : streams) s->session().close();
  for (auto& t : threads) t.join();

  LoadRunEnd end;
  end.elapsed_s =
      std::max<double>(std::min(options.duration_s, nanoseconds_between(run.start, Clock::now()) / 1e9),
                       totals.last_reply_ns / 1e9);
  end.lost = outstanding(streams);
  for (auto& s : streams) {
    end.unsent += s->unsent();
    end.reconnects += s->session().reconnects();
    end.retried += s->session().resent();
    end.gave_up += s->session().gave_up();
  }
  return end;
}

}  // namespace mtlod::clients

// mtlod-server's network shell. One strand per connection (the socket's executor) orders
// everything a session does; extractions run on a separate thread pool and post their result back
// to the session's strand, so a slow request never stalls a socket. Shape after Beast's async
// server examples: listener → session with do_read/on_read, do_write/on_write; every error returns.
#include "server/server.hpp"

#include <boost/asio.hpp>

#include <atomic>
#include <chrono>
#include <list>
#include <mutex>
#include <thread>

#include "protocol/frame.hpp"
#include "protocol/parse.hpp"
#include "protocol/replies.hpp"
#include "server/session_queue.hpp"
#include "spdlog/spdlog.h"

namespace mtlod::server {
namespace {

namespace net = boost::asio;
using tcp = net::ip::tcp;
using boost::system::error_code;
using Clock = std::chrono::steady_clock;

std::int64_t now_ns() { return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count(); }

std::vector<std::uint8_t> make_frame(const protocol::Reply& reply, std::optional<std::uint64_t> id,
                                     std::span<const std::uint8_t> payload = {}) {
  std::vector<std::uint8_t> frame;
  const std::string json = protocol::to_json(reply, id);
  frame.reserve(protocol::kFrameHeaderBytes + json.size() + payload.size());
  protocol::append_frame(json, payload, frame);
  return frame;
}

std::vector<std::uint8_t> error_frame(protocol::ErrorKind code, std::string message, std::optional<std::uint64_t> id) {
  return make_frame(protocol::ErrorReply{code, std::move(message)}, id);
}

}  // namespace

struct Server::Impl {
  class Session;

  ServerConfig config;
  const ModelRegistry& models;
  Engine engine;
  Metrics metrics;
  net::io_context ioc;
  // Listener, signals and shutdown run on one strand, whatever the number of I/O threads.
  net::strand<net::io_context::executor_type> control{net::make_strand(ioc)};
  tcp::acceptor acceptor{control};
  std::unique_ptr<net::thread_pool> workers;
  net::signal_set signals{control, SIGINT, SIGTERM};
  net::steady_timer drain_timer{control};
  std::atomic<bool> stopping{false};
  std::atomic<std::uint64_t> next_connection{1};
  std::mutex sessions_mutex;
  std::list<std::weak_ptr<Session>> sessions;

  Impl(ServerConfig c, const ModelRegistry& m) : config(std::move(c)), models(m), engine(m) {}

  void accept();
  void begin_stop();
  // Called by each session as it closes: the last one during a shutdown ends the drain early.
  void on_session_closed() {
    net::post(control, [this] {
      if (stopping && metrics.open_connections() == 0) drain_timer.cancel();
    });
  }
};

class Server::Impl::Session : public std::enable_shared_from_this<Session> {
 public:
  Session(Impl& server, tcp::socket socket, std::uint64_t number)
      : server_(server), socket_(std::move(socket)), deadline_(socket_.get_executor()), number_(number) {}

  void start() {
    server_.metrics.connection_opened();
    net::dispatch(socket_.get_executor(), [self = shared_from_this()] { self->do_read_header(); });
  }

  // Graceful end: no more reading; queued jobs are answered `shutting_down`; the running one
  // finishes; the socket closes once every reply is written.
  void shutdown() {
    net::dispatch(socket_.get_executor(), [self = shared_from_this()] {
      if (self->stopping_) return;
      self->stopping_ = true;
      for (Job& job : self->jobs_.drain()) {
        self->replies_.fill(job.seq, error_frame(protocol::ErrorKind::kShuttingDown, "the server is shutting down", job.id));
      }
      error_code ignored;
      self->socket_.shutdown(tcp::socket::shutdown_receive, ignored);  // ends the pending read
      self->flush();
    });
  }

  void force_close() {
    net::dispatch(socket_.get_executor(), [self = shared_from_this()] { self->close(); });
  }

 private:
  void do_read_header() {
    if (stopping_ || closed_) return;
    if (paused()) {
      read_paused_ = true;
      return;
    }
    reading_ = true;
    arm_deadline(server_.config.limits.idle_timeout_ms, /*idle=*/true);
    net::async_read(socket_, net::buffer(header_),
                    [self = shared_from_this()](error_code ec, std::size_t n) { self->on_header(ec, n); });
  }

  void on_header(error_code ec, std::size_t) {
    reading_ = false;
    if (ec) return end_reading(ec, "read header");
    server_.metrics.bytes_in(header_.size());
    auto header = protocol::decode_frame_header(header_, server_.config.limits.max_frame_bytes);
    if (!header) {
      // The stream cannot be resynchronised: answer, then close once the answer is written.
      server_.metrics.error(protocol::ErrorKind::kBadFrame);
      spdlog::warn("conn={} bad frame: {}", number_, header.error().message);
      replies_.fill(replies_.open(), error_frame(protocol::ErrorKind::kBadFrame, header.error().message, std::nullopt));
      stopping_ = true;
      for (Job& job : jobs_.drain()) {
        replies_.fill(job.seq, error_frame(protocol::ErrorKind::kShuttingDown, "connection closing after a bad frame", job.id));
      }
      return flush();
    }
    body_.resize(header->body_bytes());
    json_bytes_ = header->json_bytes;
    reading_ = true;
    arm_deadline(server_.config.limits.read_timeout_ms, /*idle=*/false);
    net::async_read(socket_, net::buffer(body_),
                    [self = shared_from_this()](error_code ec, std::size_t n) { self->on_body(ec, n); });
  }

  void on_body(error_code ec, std::size_t n) {
    reading_ = false;
    if (ec) return end_reading(ec, "read body");
    server_.metrics.bytes_in(n);
    received_ns_ = now_ns();
    handle(std::string_view(reinterpret_cast<const char*>(body_.data()), json_bytes_));
    flush();
    do_read_header();
  }

  void handle(std::string_view json) {
    const protocol::ParsedRequest parsed = protocol::parse_request(json, server_.config.limits);
    const std::uint64_t seq = replies_.open();
    if (!parsed.ok()) return reply_error(seq, parsed.error.code, parsed.error.message, parsed.id);
    const std::uint64_t id = *parsed.id;
    server_.metrics.request(parsed.request->index());
    std::visit([&](const auto& request) { on_request(seq, id, request); }, *parsed.request);
  }

  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::Hello&) {
    replies_.fill(seq, make_frame(protocol::HelloReply{protocol::kProtocolVersion, "mtlod/0.1", server_.config.limits}, id));
  }
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::ListModels&) {
    protocol::ModelsReply reply;
    for (const auto& model : server_.models.models()) reply.models.push_back(model->summary());
    replies_.fill(seq, make_frame(reply, id));
  }
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::ModelInfo& request) {
    const Model* model = server_.models.find(request.model);
    if (!model) return reply_unknown_model(seq, id, request.model);
    replies_.fill(seq, make_frame(model->info(), id));
  }
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::Stats&) {
    replies_.fill(seq, make_frame(protocol::StatsReply{server_.metrics.snapshot()}, id));
  }
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::Ping&) {
    replies_.fill(seq, make_frame(protocol::Pong{}, id));
  }
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::Cancel& request) {
    std::optional<Job> job = jobs_.cancel(request.target);
    if (job) replies_.fill(job->seq, error_frame(protocol::ErrorKind::kCancelled, "cancelled by the client", job->id));
    replies_.fill(seq, make_frame(protocol::CancelReply{request.target, job.has_value()}, id));
  }
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::Extract& request) {
    if (!server_.models.find(request.model)) return reply_unknown_model(seq, id, request.model);
    last_extract_ = request;
    enqueue(Job{seq, id, false, request, 0, received_ns_});
  }
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::Gaze& gaze) {
    if (!last_extract_) {
      return reply_error(seq, protocol::ErrorKind::kNoView,
                         "gaze needs an earlier extract on this connection to know the view", id);
    }
    protocol::Extract request = *last_extract_;
    if (request.criteria.focus.empty()) request.criteria.focus.emplace_back();
    protocol::Focus& focus = request.criteria.focus.front();
    focus.x = gaze.x;
    focus.y = gaze.y;
    if (gaze.distance) focus.distance = *gaze.distance;
    if (gaze.factor) focus.factor = *gaze.factor;
    last_extract_ = request;  // later gazes and extracts start from here
    enqueue(Job{seq, id, true, std::move(request), 0, received_ns_});
  }

  void enqueue(Job job) {
    // In flight: extractions queued or running. A gaze that replaces a queued gaze adds none.
    const bool coalesces = job.gaze && jobs_.last_is_gaze();
    const std::size_t in_flight = jobs_.queued() + (jobs_.running() ? 1 : 0);
    if (!coalesces && in_flight >= server_.config.limits.max_in_flight) {
      return reply_error(job.seq, protocol::ErrorKind::kLimitExceeded,
                         fmt::format("{} extractions are in flight on this connection; the limit is {}", in_flight,
                                     server_.config.limits.max_in_flight),
                         job.id);
    }
    if (std::optional<Job> replaced = jobs_.push(std::move(job))) {
      server_.metrics.error(protocol::ErrorKind::kSuperseded);
      replies_.fill(replaced->seq,
                    error_frame(protocol::ErrorKind::kSuperseded, "a newer gaze replaced this one", replaced->id));
    }
    start_next_job();
  }

  void start_next_job() {
    std::optional<Job> job = jobs_.start_next();
    if (!job) return;
    net::post(*server_.workers, [self = shared_from_this(), job = std::move(*job)]() mutable {
      const std::int64_t started = now_ns();
      auto outcome = self->server_.engine.extract(job.extract, self->cut_);
      net::post(self->socket_.get_executor(), [self, job = std::move(job), started, outcome = std::move(outcome)]() mutable {
        self->finish_job(job, started, outcome);
      });
    });
  }

  void finish_job(const Job& job, std::int64_t started_ns, std::variant<ExtractOutcome, protocol::ProtocolError>& outcome) {
    jobs_.finish();
    if (auto* error = std::get_if<protocol::ProtocolError>(&outcome)) {
      reply_error(job.seq, error->code, error->message, job.id);
    } else {
      ExtractOutcome& result = std::get<ExtractOutcome>(outcome);
      protocol::MeshReply& reply = result.reply;
      reply.timings.queue_us = static_cast<std::uint64_t>(std::max<std::int64_t>(0, started_ns - job.received_ns) / 1000);
      reply.timings.total_us = static_cast<std::uint64_t>((now_ns() - job.received_ns) / 1000);
      reply.superseded = job.superseded;
      if (job.gaze && !job.extract.criteria.focus.empty()) {
        reply.focus = std::array<double, 2>{job.extract.criteria.focus.front().x, job.extract.criteria.focus.front().y};
      }
      const auto& t = reply.timings;
      spdlog::info("conn={} id={} {} model={} triangles={} bytes={} max_error={:.4g} us: queue={} map={} occupancy={} "
                   "dt={} labels={} refine={} encode={} total={}",
                   number_, job.id, job.gaze ? "gaze" : "extract", reply.model, reply.triangles, reply.bytes,
                   reply.max_error, t.queue_us, t.map_us, t.occupancy_us, t.dt_us, t.labels_us, t.refine_us,
                   t.encode_us, t.total_us);
      server_.metrics.extraction(t, reply.triangles);
      replies_.fill(job.seq, make_frame(reply, job.id, result.payload));
    }
    start_next_job();
    flush();
  }

  void reply_unknown_model(std::uint64_t seq, std::uint64_t id, const std::string& name) {
    std::string known;
    for (const auto& m : server_.models.models()) known += (known.empty() ? "" : ", ") + m->name;
    reply_error(seq, protocol::ErrorKind::kUnknownModel, fmt::format("no model named '{}'; loaded: {}", name, known), id);
  }

  void reply_error(std::uint64_t seq, protocol::ErrorKind code, const std::string& message, std::optional<std::uint64_t> id) {
    server_.metrics.error(code);
    spdlog::debug("conn={} id={} error {}: {}", number_, id.value_or(0), protocol::to_string(code), message);
    replies_.fill(seq, error_frame(code, message, id));
  }

  // Writes every reply whose turn has come, one async_write at a time.
  void flush() {
    if (writing_ || closed_) return;
    std::optional<std::vector<std::uint8_t>> frame = replies_.pop();
    if (!frame) {
      if (stopping_ && replies_.outstanding() == 0 && !jobs_.running()) close();
      return;
    }
    writing_ = true;
    outgoing_ = std::move(*frame);
    net::async_write(socket_, net::buffer(outgoing_),
                     [self = shared_from_this()](error_code ec, std::size_t n) { self->on_write(ec, n); });
  }

  void on_write(error_code ec, std::size_t n) {
    writing_ = false;
    if (ec) {
      spdlog::debug("conn={} write failed: {}", number_, ec.message());
      return close();
    }
    server_.metrics.bytes_out(n);
    flush();
    if (read_paused_ && !paused()) {
      read_paused_ = false;
      do_read_header();
    }
  }

  // A client that sends faster than it reads gets no more reads until it catches up.
  bool paused() const { return replies_.outstanding() > 2 * std::size_t{server_.config.limits.max_in_flight} + 32; }

  void arm_deadline(std::uint32_t timeout_ms, bool idle) {
    deadline_.expires_after(std::chrono::milliseconds(timeout_ms));
    deadline_.async_wait([self = shared_from_this(), idle](error_code ec) {
      if (ec || !self->reading_) return;  // cancelled or re-armed
      if (idle && self->replies_.outstanding() > 0) {
        return self->arm_deadline(self->server_.config.limits.idle_timeout_ms, true);  // waiting on us, not idle
      }
      spdlog::info("conn={} closed: {} timeout", self->number_, idle ? "idle" : "read");
      self->close();
    });
  }

  void end_reading(error_code ec, const char* what) {
    if (ec != net::error::eof && ec != net::error::operation_aborted && ec != net::error::connection_reset) {
      spdlog::debug("conn={} {} failed: {}", number_, what, ec.message());
    }
    // The client closed or the read was ended: answer what is still pending if the socket can, then close.
    stopping_ = true;
    for (Job& job : jobs_.drain()) {
      replies_.fill(job.seq, error_frame(protocol::ErrorKind::kCancelled, "connection closed", job.id));
    }
    flush();
  }

  void close() {
    if (closed_) return;
    closed_ = true;
    error_code ignored;
    deadline_.cancel();
    socket_.shutdown(tcp::socket::shutdown_both, ignored);
    socket_.close(ignored);
    server_.metrics.connection_closed();
    server_.on_session_closed();
  }

  Impl& server_;
  tcp::socket socket_;
  net::steady_timer deadline_;
  std::uint64_t number_;
  std::array<std::uint8_t, protocol::kFrameHeaderBytes> header_{};
  std::vector<std::uint8_t> body_;
  std::uint32_t json_bytes_ = 0;
  std::int64_t received_ns_ = 0;
  std::vector<std::uint8_t> outgoing_;
  ReplyOrder replies_;
  JobQueue jobs_;
  SessionCut cut_;
  std::optional<protocol::Extract> last_extract_;
  bool reading_ = false;
  bool writing_ = false;
  bool read_paused_ = false;
  bool stopping_ = false;
  bool closed_ = false;
};

void Server::Impl::accept() {
  acceptor.async_accept(net::make_strand(ioc), [this](error_code ec, tcp::socket socket) {
    if (ec) {
      if (ec != net::error::operation_aborted) spdlog::warn("accept failed: {}", ec.message());
      if (!stopping && acceptor.is_open()) accept();
      return;
    }
    if (stopping) return;
    const std::uint64_t number = next_connection++;
    if (metrics.open_connections() >= config.limits.max_connections) {
      metrics.connection_refused();
      spdlog::warn("conn={} refused: {} connections open, the limit", number, config.limits.max_connections);
      auto frame = std::make_shared<std::vector<std::uint8_t>>(error_frame(
          protocol::ErrorKind::kLimitExceeded,
          fmt::format("the server has {} connections, its limit", config.limits.max_connections), std::nullopt));
      auto refused = std::make_shared<tcp::socket>(std::move(socket));
      net::async_write(*refused, net::buffer(*frame), [frame, refused](error_code, std::size_t) {
        error_code ignored;
        refused->shutdown(tcp::socket::shutdown_both, ignored);
        refused->close(ignored);
      });
    } else {
      auto session = std::make_shared<Session>(*this, std::move(socket), number);
      {
        std::lock_guard lock(sessions_mutex);
        sessions.remove_if([](const std::weak_ptr<Session>& s) { return s.expired(); });
        sessions.push_back(session);
      }
      session->start();
    }
    accept();
  });
}

void Server::Impl::begin_stop() {
  if (stopping.exchange(true)) return;
  spdlog::info("shutting down: no new connections, finishing in-flight work (at most {} ms)", config.drain_timeout_ms);
  error_code ignored;
  acceptor.close(ignored);
  signals.cancel(ignored);
  std::vector<std::shared_ptr<Session>> live;
  {
    std::lock_guard lock(sessions_mutex);
    for (auto& weak : sessions) {
      if (auto s = weak.lock()) live.push_back(std::move(s));
    }
  }
  for (auto& s : live) s->shutdown();
  if (live.empty()) return;
  drain_timer.expires_after(std::chrono::milliseconds(config.drain_timeout_ms));
  drain_timer.async_wait([this](error_code ec) {
    if (ec) return;
    spdlog::warn("drain timeout: closing the remaining connections");
    std::lock_guard lock(sessions_mutex);
    for (auto& weak : sessions) {
      if (auto s = weak.lock()) s->force_close();
    }
  });
}

Server::Server(ServerConfig config, const ModelRegistry& models) : impl_(std::make_unique<Impl>(std::move(config), models)) {}

Server::~Server() {
  if (impl_->workers) impl_->workers->join();
}

Status Server::listen() {
  error_code ec;
  const auto address = net::ip::make_address(impl_->config.host, ec);
  if (ec) return make_error(ErrorCode::kInvalidArgument, fmt::format("bad host '{}': {}", impl_->config.host, ec.message()));
  const tcp::endpoint endpoint(address, impl_->config.port);
  auto& acceptor = impl_->acceptor;
  acceptor.open(endpoint.protocol(), ec);
  if (!ec) acceptor.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) acceptor.bind(endpoint, ec);
  if (!ec) acceptor.listen(net::socket_base::max_listen_connections, ec);
  if (ec) {
    return make_error(ErrorCode::kIoError,
                      fmt::format("cannot listen on {}:{}: {}", impl_->config.host, impl_->config.port, ec.message()));
  }
  return Ok{};
}

std::uint16_t Server::port() const {
  error_code ec;
  return impl_->acceptor.local_endpoint(ec).port();
}

void Server::run() {
  Impl& s = *impl_;
  const unsigned workers = s.config.workers ? s.config.workers : std::max(1u, std::thread::hardware_concurrency());
  s.workers = std::make_unique<net::thread_pool>(workers);
  s.signals.async_wait([&s](error_code ec, int signal) {
    if (ec) return;
    spdlog::info("received signal {}", signal);
    s.begin_stop();
  });
  s.accept();
  std::vector<std::thread> extra;
  for (unsigned i = 1; i < std::max(1u, s.config.io_threads); ++i) extra.emplace_back([&s] { s.ioc.run(); });
  s.ioc.run();
  for (auto& t : extra) t.join();
  s.workers->join();
}

void Server::stop() {
  net::post(impl_->control, [this] { impl_->begin_stop(); });
}

const Metrics& Server::metrics() const { return impl_->metrics; }

}  // namespace mtlod::server

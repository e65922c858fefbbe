// A connection's request logic (see connection.hpp). Everything runs on the connection's strand;
// extractions run on the worker pool and post their result back to it.
#include "server/connection.hpp"

#include <boost/asio/dispatch.hpp>
#include <boost/asio/post.hpp>

#include <chrono>
#include <utility>

#include "fmt/format.h"
#include "protocol/frame.hpp"
#include "protocol/parse.hpp"
#include "protocol/replies.hpp"
#include "protocol/text.hpp"
#include "server/log.hpp"
#include "spdlog/spdlog.h"

namespace mtlod::server {
namespace net = boost::asio;

namespace {

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::vector<std::uint8_t> make_frame(const protocol::Reply& reply, std::optional<std::uint64_t> id,
                                     std::span<const std::uint8_t> payload = {}) {
  std::vector<std::uint8_t> frame;
  const std::string json = protocol::to_json(reply, id);
  frame.reserve(protocol::kFrameHeaderBytes + json.size() + payload.size());
  protocol::append_frame(json, payload, frame);
  return frame;
}

std::vector<std::uint8_t> error_frame(protocol::ErrorKind code, std::string message,
                                      std::optional<std::uint64_t> id) {
  return make_frame(protocol::ErrorReply{code, std::move(message)}, id);
}

}  // namespace

Connection::Connection(ServerContext& server, net::any_io_executor strand, std::uint64_t number,
                       AddressTable::Slot slot)
    : server_(server), strand_(std::move(strand)), number_(number), slot_(std::move(slot)) {}

void Connection::opened() {
  server_.metrics.connection_opened();
}

void Connection::shutdown() {
  net::dispatch(strand_, [self = shared_from_this()] {
    if (self->stopping_) return;
    self->stopping_ = true;
    self->drain_jobs(protocol::ErrorKind::kShuttingDown, "the server is shutting down");
    self->stop_reading();
    self->flush();
  });
}

void Connection::force_close() {
  net::dispatch(strand_, [self = shared_from_this()] { self->close(); });
}

void Connection::handle_frame(std::string_view json, std::int64_t received_ns) {
  got_request_ = true;
  const std::uint64_t seq = replies_.open();
  std::optional<std::uint64_t> id;
  try {
    const auto parsed = protocol::parse_request(json, server_.config.limits);
    id = parsed ? parsed->id : parsed.error().request_id;
    if (parsed) server_.metrics.request(parsed->request.index());
    if (!authorised() && !(parsed && std::holds_alternative<protocol::Hello>(parsed->request))) {
      // Until a token is shown, nothing is served nor even checked beyond being a hello: a client
      // without one learns no more than that it needs one.
      reply_error(seq, protocol::ErrorKind::kUnauthorized,
                  "this server needs an access token: send a hello with a valid 'token' first", id);
    } else if (!parsed) {
      reply_error(seq, parsed.error().code, parsed.error().message, id);
    } else {
      received_ns_ = received_ns;
      std::visit([&](const auto& request) { on_request(seq, parsed->id, request); }, parsed->request);
    }
  } catch (const std::exception& e) {
    // This request fails; the connection and every other one carry on.
    spdlog::error("conn={} id={} request failed: {}", number_, id.value_or(0), protocol::printable(e.what()));
    if (!replies_.filled(seq))
      reply_error(seq, protocol::ErrorKind::kInternal, "the server failed on this request", id);
  }
  flush();
}

std::optional<protocol::FrameHeader> Connection::frame_header(
    std::span<const std::uint8_t, protocol::kFrameHeaderBytes> bytes) {
  server_.metrics.bytes_in(bytes.size());
  auto header = protocol::decode_frame_header(bytes, server_.config.limits.max_frame_bytes);
  if (!header) {
    bad_frame(header.error().message);
    return std::nullopt;
  }
  return *header;
}

bool Connection::handle_message(bool text, std::string_view message, std::int64_t received_ns) {
  if (text) {
    handle_frame(message, received_ns);
    return true;
  }
  // A binary message is a whole frame: its header must announce exactly the bytes that follow.
  if (message.size() < protocol::kFrameHeaderBytes) {
    bad_frame(fmt::format("a binary message of {} bytes is shorter than the {}-byte frame header",
                          message.size(), protocol::kFrameHeaderBytes));
    return false;
  }
  const auto* bytes = reinterpret_cast<const std::uint8_t*>(message.data());
  auto header = protocol::decode_frame_header(
      std::span<const std::uint8_t, protocol::kFrameHeaderBytes>(bytes, protocol::kFrameHeaderBytes),
      server_.config.limits.max_frame_bytes);
  const std::size_t body_bytes = message.size() - protocol::kFrameHeaderBytes;
  if (!header || header->body_bytes() != body_bytes) {
    bad_frame(header ? fmt::format("the frame header announces {} bytes but the message holds {} after it",
                                   header->body_bytes(), body_bytes)
                     : header.error().message);
    return false;
  }
  handle_frame(message.substr(protocol::kFrameHeaderBytes, header->json_bytes), received_ns);
  return true;
}

void Connection::bad_frame(const std::string& message) {
  // The stream cannot be resynchronised: answer, then close once the answer is written.
  server_.metrics.error(protocol::ErrorKind::kBadFrame);
  const std::string text = protocol::printable(message);
  spdlog::warn("conn={} bad frame: {}", number_, text);
  replies_.fill(replies_.open(), error_frame(protocol::ErrorKind::kBadFrame, text, std::nullopt));
  stopping_ = true;
  drain_jobs(protocol::ErrorKind::kShuttingDown, "connection closing after a bad frame");
  flush();
}

void Connection::on_read_end() {
  // The client closed its side or the read failed: nothing more will come. Queued work is
  // answered if the socket still takes it; the connection closes once the replies are out.
  stopping_ = true;
  drain_jobs(protocol::ErrorKind::kCancelled, "connection closed");
  flush();
}

void Connection::authorise(const Grant* grant) {
  grant_ = grant;
  if (grant)
    spdlog::debug("conn={} authorised by the token on line {} of the tokens file", number_, grant->line);
}

ModelPtr Connection::visible_model(std::string_view name) const {
  if (grant_ && !grant_->sees(name)) return nullptr;
  return server_.models.find(name);
}

const std::string* Connection::unseen_model(const protocol::Extract& request) const {
  if (request.instances.empty()) return visible_model(request.model) ? nullptr : &request.model;
  for (const protocol::Instance& instance : request.instances) {
    if (!visible_model(instance.model)) return &instance.model;
  }
  return nullptr;
}

void Connection::on_request(std::uint64_t seq, std::uint64_t id, const protocol::Hello& request) {
  const TokenTable* tokens = server_.config.tokens.get();
  // A token in hello is checked even on a connection already authorised: a wrong one revokes the
  // earlier grant, so a connection never holds more than its latest hello says.
  if (tokens && (!request.token.empty() || !authorised())) {
    const Grant* grant = request.token.empty() ? nullptr : tokens->find(request.token);
    authorise(grant);
    if (!grant) {
      // Worth a line for whoever audits access, but one per connection: a client repeating its
      // hello must not be able to fill the log.
      spdlog::log(refusal_logged_ ? spdlog::level::debug : spdlog::level::info, "conn={} from {}: hello {}",
                  number_, address(),
                  request.token.empty() ? "without a token" : "with a token that is not valid");
      refusal_logged_ = true;
      return reply_error(seq, protocol::ErrorKind::kUnauthorized,
                         request.token.empty() ? "this server needs an access token in hello's 'token'"
                                               : "the access token is not valid",
                         id);
    }
  }
  if (request.codec) codec_ = *request.codec;
  protocol::HelloReply reply{protocol::kProtocolVersion, "mtlod/0.1", server_.config.limits,
                             server_.config.instance};
  reply.auth_required = tokens != nullptr;
  reply.codec = codec_;
  replies_.fill(seq, make_frame(reply, id));
}
void Connection::on_request(std::uint64_t seq, std::uint64_t id, const protocol::ListModels&) {
  protocol::ModelsReply reply;
  for (const auto& model : server_.models.models()) {
    if (visible_model(model->name)) reply.models.push_back(model->summary());
  }
  replies_.fill(seq, make_frame(reply, id));
}
void Connection::on_request(std::uint64_t seq, std::uint64_t id, const protocol::ModelInfo& request) {
  const ModelPtr model = visible_model(request.model);
  if (!model) return reply_unknown_model(seq, id, request.model);
  replies_.fill(seq, make_frame(model->info(), id));
}
void Connection::on_request(std::uint64_t seq, std::uint64_t id, const protocol::Stats&) {
  protocol::StatsReply reply{server_.metrics.snapshot()};
  reply.counters.emplace_back("memory_held_bytes", static_cast<double>(server_.memory.held()));
  reply.counters.emplace_back("memory_limit_bytes", static_cast<double>(server_.memory.limit()));
  replies_.fill(seq, make_frame(reply, id));
}
void Connection::on_request(std::uint64_t seq, std::uint64_t id, const protocol::Ping&) {
  replies_.fill(seq, make_frame(protocol::Pong{}, id));
}
void Connection::on_request(std::uint64_t seq, std::uint64_t id, const protocol::Reload& request) {
  const TokenTable* admins = server_.config.admin_tokens.get();
  if (!admins || !admins->find(request.token)) {
    spdlog::log(refusal_logged_ ? spdlog::level::debug : spdlog::level::info,
                "conn={} from {}: reload refused", number_, address());
    refusal_logged_ = true;
    return reply_error(seq, protocol::ErrorKind::kUnauthorized,
                       admins ? "the admin token is not valid"
                              : "this server takes no reload requests (start it with --admin-tokens FILE)",
                       id);
  }
  spdlog::info("conn={} from {}: reload requested", number_, address());
  // Loading reads files: on a worker, with the reply filled in its turn once it is done.
  server_.scheduler.submit(address(), [self = shared_from_this(), seq, id] {
    protocol::ReloadReply reply;
    try {
      reply.models = self->server_.models.reload();
    } catch (const std::exception& e) {
      spdlog::error("reload failed: {}", e.what());
    }
    net::post(self->strand_, [self, seq, id, reply = std::move(reply)] {
      self->replies_.fill(seq, make_frame(reply, id));
      self->flush();
    });
  });
}
void Connection::on_request(std::uint64_t seq, std::uint64_t id, const protocol::Cancel& request) {
  std::optional<Job> job = jobs_.cancel(request.target);
  if (job)
    replies_.fill(job->seq, error_frame(protocol::ErrorKind::kCancelled, "cancelled by the client", job->id));
  replies_.fill(seq, make_frame(protocol::CancelReply{request.target, job.has_value()}, id));
}
void Connection::on_request(std::uint64_t seq, std::uint64_t id, const protocol::Extract& named) {
  // A scene the server loaded stands for its instances from here on (gazes included).
  const protocol::Extract* given = &named;
  protocol::Extract resolved;
  if (!named.scene_name.empty()) {
    const auto scene = server_.config.scenes.find(named.scene_name);
    if (scene == server_.config.scenes.end()) {
      std::string known;
      for (const auto& [name, instances] : server_.config.scenes) known += (known.empty() ? "" : ", ") + name;
      return reply_error(seq, protocol::ErrorKind::kUnknownModel,
                         fmt::format("no scene named '{}'; loaded: {}", named.scene_name,
                                     known.empty() ? "none (mtlod-server --scene FILE)" : known),
                         id);
    }
    resolved = named;
    resolved.scene_name.clear();
    resolved.instances = scene->second;
    given = &resolved;
  }
  const protocol::Extract& request = *given;
  if (const std::string* unseen = unseen_model(request)) return reply_unknown_model(seq, id, *unseen);
  if (!request.codec) {
    if (auto refusal = protocol::codec_refusal(request, codec_))
      return reply_error(seq, protocol::ErrorKind::kBadRequest, *refusal, id);
  }
  last_extract_ = request;
  last_extract_->codec = request.codec.value_or(codec_);
  enqueue(Job{seq, id, false, *last_extract_, 0, received_ns_});
}
void Connection::on_request(std::uint64_t seq, std::uint64_t id, const protocol::Gaze& gaze) {
  if (!last_extract_) {
    return reply_error(seq, protocol::ErrorKind::kNoView,
                       "gaze needs an earlier extract on this connection to know the view", id);
  }
  // A later hello may have changed the token: the view's model must still be one it sees.
  if (const std::string* unseen = unseen_model(*last_extract_)) return reply_unknown_model(seq, id, *unseen);
  protocol::Extract request = *last_extract_;
  protocol::Region& region = protocol::gaze_region(request.criteria);
  region.points.front() = {gaze.x, gaze.y};
  if (gaze.distance) region.distance = *gaze.distance;
  if (gaze.factor) region.factor = *gaze.factor;
  last_extract_ = request;  // later gazes and extracts start from here
  enqueue(Job{seq, id, true, std::move(request), 0, received_ns_});
}

void Connection::enqueue(Job job) {
  // In flight: extractions queued or running. A gaze that replaces a queued gaze adds none.
  const bool coalesces = job.gaze && jobs_.last_is_gaze();
  const std::size_t in_flight = jobs_.queued() + (jobs_.running() ? 1 : 0);
  if (!coalesces && in_flight >= server_.config.limits.max_in_flight) {
    return reply_error(job.seq, protocol::ErrorKind::kLimitExceeded,
                       fmt::format("{} extractions are in flight on this connection; the limit is {}",
                                   in_flight, server_.config.limits.max_in_flight),
                       job.id);
  }
  if (std::optional<Job> replaced = jobs_.push(std::move(job))) {
    server_.metrics.error(protocol::ErrorKind::kSuperseded);
    replies_.fill(replaced->seq, error_frame(protocol::ErrorKind::kSuperseded,
                                             "a newer gaze replaced this one", replaced->id));
  }
  start_next_job();
}

void Connection::start_next_job() {
  std::optional<Job> job;
  for (;;) {
    job = jobs_.start_next();
    if (!job) return;
    const std::uint64_t need = server_.engine.estimate_bytes(job->extract, &cut_);
    if (server_.memory.reserve(need)) {
      reserved_ = need;
      break;
    }
    jobs_.finish();
    reply_error(job->seq, protocol::ErrorKind::kLimitExceeded,
                fmt::format("this extraction could need {:.1f} MiB (grid {}x{} of {}); the server holds "
                            "{:.1f} MiB of its {:.1f} MiB memory limit",
                            need / 1048576.0, job->extract.grid[0], job->extract.grid[1],
                            job->extract.instances.empty()
                                ? fmt::format("model '{}'", job->extract.model)
                                : fmt::format("a scene of {} instances", job->extract.instances.size()),
                            server_.memory.held() / 1048576.0, server_.memory.limit() / 1048576.0),
                job->id);
  }
  server_.scheduler.submit(address(), [self = shared_from_this(), job = std::move(*job)]() mutable {
    const std::int64_t started = now_ns();
    ExtractResult outcome = [&]() -> ExtractResult {
      try {
        return self->server_.engine.extract(job.extract, job.gaze, self->cut_);
      } catch (const std::exception& e) {
        // A throw on a worker thread would end the process. The session's cut may be half-updated:
        // drop it, so the next extraction on this connection starts afresh.
        spdlog::error("conn={} id={} extraction failed: {}", self->number_, job.id, e.what());
        self->cut_ = ExtractionState{};
        return protocol::ProtocolError{protocol::ErrorKind::kInternal,
                                       "the server failed on this extraction"};
      }
    }();
    // This worker's scratch: a huge grid's is freed now rather than kept for the next request (the
    // reservation counted it while the extraction ran).
    self->server_.metrics.scratch_bytes(Engine::settle_worker_scratch());
    net::post(self->strand_, [self, job = std::move(job), started, outcome = std::move(outcome)]() mutable {
      self->finish_job(job, started, outcome);
    });
  });
}

void Connection::finish_job(const Job& job, std::int64_t started_ns, ExtractResult& outcome) {
  jobs_.finish();
  // The reservation gives way to what the extraction really left in its session.
  server_.memory.release(std::exchange(reserved_, 0));
  const std::uint64_t session_bytes = cut_.memory_bytes();
  const std::int64_t session_growth =
      static_cast<std::int64_t>(session_bytes) - static_cast<std::int64_t>(session_accounted_);
  server_.memory.adjust(session_growth);
  server_.metrics.session_bytes(session_growth);
  session_accounted_ = session_bytes;
  if (closed_) release_session();
  try {
    finish_reply(job, started_ns, outcome);
  } catch (const std::exception& e) {
    spdlog::error("conn={} id={} reply failed: {}", number_, job.id, e.what());
    if (!replies_.filled(job.seq)) {
      reply_error(job.seq, protocol::ErrorKind::kInternal, "the server failed on this extraction", job.id);
    }
  }
  start_next_job();
  flush();
}

void Connection::finish_reply(const Job& job, std::int64_t started_ns, ExtractResult& outcome) {
  if (!outcome) {
    reply_error(job.seq, outcome.error().code, outcome.error().message, job.id);
  } else {
    ExtractOutcome& result = *outcome;
    protocol::MeshReply& reply = result.reply;
    reply.timings.queue_us =
        static_cast<std::uint64_t>(std::max<std::int64_t>(0, started_ns - job.received_ns) / 1000);
    reply.timings.total_us = static_cast<std::uint64_t>((now_ns() - job.received_ns) / 1000);
    reply.superseded = job.superseded;
    const std::optional<protocol::Region>& gazed = job.extract.criteria.regions[core::view::kGazeCriterion];
    if (job.gaze && gazed && !gazed->points.empty())
      reply.focus = std::array<double, 2>{gazed->points.front().x, gazed->points.front().y};
    log_extraction(number_, job.id, job.gaze, reply);
    server_.metrics.extraction(reply.timings, reply.triangles, job.gaze);
    replies_.fill(job.seq, make_frame(reply, job.id, result.payload), /*mesh=*/true);
  }
}

void Connection::reply_unknown_model(std::uint64_t seq, std::uint64_t id, const std::string& name) {
  std::string known;
  for (const auto& m : server_.models.models()) {
    if (visible_model(m->name)) known += (known.empty() ? "" : ", ") + m->name;
  }
  reply_error(seq, protocol::ErrorKind::kUnknownModel,
              fmt::format("no model named '{}'; loaded: {}", name, known), id);
}

void Connection::reply_error(std::uint64_t seq, protocol::ErrorKind code, const std::string& message,
                             std::optional<std::uint64_t> id) {
  server_.metrics.error(code);
  const std::string text = protocol::printable(message);  // it may quote what the client sent
  spdlog::debug("conn={} id={} error {}: {}", number_, id.value_or(0), protocol::to_string(code), text);
  replies_.fill(seq, error_frame(code, text, id));
}

void Connection::failed(const char* what, const char* reason) noexcept {
  try {
    spdlog::error("conn={} {} failed: {}; closing the connection", number_, what,
                  protocol::printable(reason));
    server_.metrics.error(protocol::ErrorKind::kInternal);
  } catch (...) {
  }
  close();
}

void Connection::drain_jobs(protocol::ErrorKind code, const char* message) {
  for (Job& job : jobs_.drain()) replies_.fill(job.seq, error_frame(code, message, job.id));
}

void Connection::flush() {
  if (writing_ || closed_) return;
  std::optional<Reply> reply = replies_.pop();
  if (!reply) {
    if (stopping_ && replies_.outstanding() == 0 && !jobs_.running()) close();
    return;
  }
  writing_ = true;
  outgoing_ = std::move(reply->frame);
  outgoing_mesh_ = reply->mesh;
  write_frame(outgoing_);
}

void Connection::on_written(bool ok, std::size_t bytes) {
  writing_ = false;
  if (!ok) return close();
  server_.metrics.bytes_out(bytes);
  if (outgoing_mesh_) server_.metrics.mesh_sent();
  flush();
  if (read_paused_ && !paused() && !ending()) {
    read_paused_ = false;
    resume_reading();
  }
}

bool Connection::paused() const {
  // A client that sends faster than it reads gets no more reads until it catches up.
  return replies_.outstanding() > 2 * std::size_t{server_.config.limits.max_in_flight} + 32;
}

bool Connection::may_read() {
  if (ending()) return false;
  if (paused()) {
    read_paused_ = true;
    return false;
  }
  return true;
}

void Connection::release_session() {
  server_.metrics.session_bytes(-static_cast<std::int64_t>(session_accounted_));
  server_.memory.release(std::exchange(session_accounted_, 0));
  cut_ = ExtractionState{};
}

void Connection::close() {
  if (closed_) return;
  closed_ = true;
  close_transport();
  slot_.reset();
  if (!jobs_.running()) release_session();
  server_.metrics.connection_closed();
  server_.on_connection_closed();
}

}  // namespace mtlod::server

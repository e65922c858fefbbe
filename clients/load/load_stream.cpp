// One connection of mtlod-load (see load_stream.hpp).
#include "clients/load/load_stream.hpp"

#include <algorithm>
#include <thread>
#include <utility>

namespace mtlod::clients {
namespace {

// Records a reply whose request was due at `intended_ns`, read at `now` from the server process
// `instance`.
void record_reply(LoadTotals& totals, const ReplyFrame& frame, std::int64_t intended_ns, std::int64_t now,
                  const std::string& instance) {
  if (const auto* mesh = std::get_if<protocol::MeshReply>(&frame.header.reply)) {
    ++totals.ok;
    auto& server = totals.instances[instance];
    ++server.ok;
    if (server.first_ns < 0) server.first_ns = now;
    server.last_ns = now;
    totals.latency_us.record(static_cast<std::uint64_t>(std::max<std::int64_t>(0, now - intended_ns) / 1000));
    totals.server_total_us.record(mesh->timings.total_us);
    totals.bytes += frame.payload.size();
    totals.triangles += mesh->triangles;
    auto& s = totals.stage_sums;
    const auto& t = mesh->timings;
    s.queue_us += t.queue_us, s.map_us += t.map_us, s.occupancy_us += t.occupancy_us, s.dt_us += t.dt_us;
    s.labels_us += t.labels_us, s.refine_us += t.refine_us, s.encode_us += t.encode_us,
        s.total_us += t.total_us;
  } else if (const auto* error = std::get_if<protocol::ErrorReply>(&frame.header.reply)) {
    ++totals.errors_by_code[protocol::to_string(error->code)];
    if (error->code == protocol::ErrorKind::kSuperseded)
      ++totals.superseded;
    else
      ++totals.errors;
  }
}

}  // namespace

LoadStream::LoadStream(LoadRun& run, unsigned index)
    : run_(run),
      index_(index),
      session_(*this, run.options.endpoint, "mtlod-load/0.1", run.options.retry,
               run.options.seed * 7919 + index, run.finished) {}

bool LoadStream::wait_for_turn(std::size_t i, std::int64_t& intended_ns) {
  const LoadOptions& o = run_.options;
  if (o.open_loop()) {
    const std::vector<std::int64_t>& due = run_.plan[index_];
    if (i >= due.size()) return false;
    intended_ns = due[i];
    std::this_thread::sleep_until(run_.start + std::chrono::nanoseconds(intended_ns));
    return true;
  }
  if (nanoseconds_between(run_.start, Clock::now()) >= run_.duration_ns) return false;
  return !(o.max_requests && run_.issued.fetch_add(1) >= o.max_requests);
}

bool LoadStream::wait_for_window(std::size_t i) {
  // Past the end of the test, the due requests left are given up.
  StreamSession::Locked locked = session_.lock();
  const bool room = locked.wait_until(run_.end_of_sending(), [&] { return pending_.size() < run_.window; });
  if (locked.closed()) return false;
  if (!room) {
    unsent_ += run_.options.open_loop() ? run_.plan[index_].size() - i : 0;
    return false;
  }
  return true;
}

void LoadStream::send_requests() {
  const LoadOptions& o = run_.options;
  RequestSequence requests(run_.models[index_ % run_.models.size()], run_.requests, o.seed * 1000003 + index_,
                           index_);
  for (std::size_t i = 0;; ++i) {
    std::int64_t intended_ns = 0;
    if (!wait_for_turn(i, intended_ns)) break;
    // Recycled once its replies are in, so that a load balancer can place the connection anew.
    if (o.reconnect_after && !session_.recycle_connection(o.reconnect_after, run_.end_of_sending(),
                                                          [&] { return pending_.empty(); }))
      break;
    if (!wait_for_window(i)) break;
    protocol::Request request = requests.next();
    const bool sent = session_.send([&] {
      if (!o.open_loop()) intended_ns = nanoseconds_between(run_.start, Clock::now());
      const std::uint64_t id = next_id_++;
      if (const auto* e = std::get_if<protocol::Extract>(&request)) view_ = *e;
      pending_.push_back(Pending{id, intended_ns, request});
      return OutgoingRequest{std::move(request), id};
    });
    if (!sent) break;
    std::lock_guard lock(run_.totals.mutex);
    ++run_.totals.sent;
  }
  ++run_.senders_done;
}

std::size_t LoadStream::outstanding() {
  StreamSession::Locked locked = session_.lock();
  std::size_t n = 0;
  for (const Pending& p : pending_) n += p.setup ? 0 : 1;
  return n;
}

void LoadStream::choose_resend(std::vector<OutgoingRequest>& resend) {
  // A gaze before any extract in the queue needs the view back first.
  for (const Pending& p : pending_) {
    if (std::holds_alternative<protocol::Extract>(p.request)) break;
    if (std::holds_alternative<protocol::Gaze>(p.request) && view_) {
      pending_.push_front(Pending{next_id_++, 0, *view_, true});
      break;
    }
  }
  for (const Pending& p : pending_) resend.push_back(OutgoingRequest{p.request, p.id, p.setup});
}

void LoadStream::on_reply(ReplyFrame& frame, Clock::time_point arrival, const std::string& instance) {
  const std::int64_t now = nanoseconds_between(run_.start, arrival);
  Pending pending{0, now, protocol::Ping{}};
  {
    // Replies come in request order; an unmatched id (a refusal without id) takes no request.
    StreamSession::Locked locked = session_.lock();
    if (!pending_.empty() && frame.header.id == pending_.front().id) {
      pending = std::move(pending_.front());
      pending_.pop_front();
    }
  }
  session_.wake_waiters();
  Status decoded = Ok{};
  std::int64_t decode_ns = 0;
  const auto* mesh = std::get_if<protocol::MeshReply>(&frame.header.reply);
  if (run_.options.decode && mesh) {
    const Clock::time_point started = Clock::now();
    decoded = mesh_.apply(*mesh, frame.payload);
    decode_ns = nanoseconds_between(started, Clock::now());
  }
  std::lock_guard lock(run_.totals.mutex);
  if (run_.options.decode && mesh) {
    LoadTotals& t = run_.totals;
    ++t.decoded;
    t.decode_us.record(static_cast<std::uint64_t>(decode_ns / 1000));
    if (!decoded && t.decode_errors++ == 0) t.first_decode_error = decoded.error().message;
  }
  run_.totals.last_reply_ns = std::max(run_.totals.last_reply_ns, now);
  if (pending.setup && std::holds_alternative<protocol::MeshReply>(frame.header.reply)) return;
  record_reply(run_.totals, frame, pending.intended_ns, now, instance);
}

}  // namespace mtlod::clients

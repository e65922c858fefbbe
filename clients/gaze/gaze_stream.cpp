// One gaze stream of mtlod-gaze (see gaze_stream.hpp).
#include "clients/gaze/gaze_stream.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <thread>
#include <utility>

#include "clients/common/scene_view.hpp"
#include "fmt/format.h"

namespace mtlod::clients {
namespace {

constexpr auto kUnavailablePatience = std::chrono::seconds(30);

std::uint64_t microseconds_from(std::int64_t from_ns, std::int64_t to_ns) {
  return static_cast<std::uint64_t>(std::max<std::int64_t>(0, to_ns - from_ns) / 1000);
}

// The flags' extract of the options' view: the scene's (framing its box unless --eye is given), or
// the model's.
Result<protocol::Extract> view_extract(ServerConnection& connection, const GazeOptions& options,
                                       const clients::ExtractFlags& flags) {
  if (!options.scene_file.empty()) {
    MTLOD_TRY(SceneView scene, describe_scene(connection, options.scene_file, options.scene, flags));
    return std::move(scene.extract);
  }
  const std::string& model = options.model;
  MTLOD_TRY(const ReplyFrame info, connection.call(protocol::ModelInfo{model}, 0));
  const auto* m = std::get_if<protocol::ModelInfoReply>(&info.header.reply);
  if (!m) return make_error(ErrorCode::kNotFound, fmt::format("model '{}' is not served", model));
  return clients::make_extract(flags, model, m->bounds_min, m->bounds_max);
}

}  // namespace

GazeStream::GazeStream(GazeReplay& replay, unsigned index, std::vector<GazeSample> trace)
    : replay_(replay),
      trace_(std::move(trace)),
      session_(*this, replay.options.endpoint, "mtlod-gaze/0.1", replay.options.retry,
               replay.options.synthesis.seed * 7919 + index, replay.finished) {
  tracked_before_.reserve(trace_.size() + 1);
  tracked_before_.push_back(0);
  for (const GazeSample& s : trace_) tracked_before_.push_back(tracked_before_.back() + s.tracked);
}

Status GazeStream::open_view(const clients::ExtractFlags& flags) {
  MTLOD_RETURN_IF_ERROR(session_.connect());
  ServerConnection& connection = session_.connection();
  MTLOD_TRY(protocol::Extract request, view_extract(connection, replay_.options, flags));
  const GazeSample& first_gaze =
      *std::find_if(trace_.begin(), trace_.end(), [](const GazeSample& s) { return s.tracked; });
  protocol::gaze_region(request.criteria).points.front() = {first_gaze.x, first_gaze.y};
  // A model whose file is being rewritten answers `unavailable` until the new file is loaded
  // (seconds): the stream waits for it instead of giving up before its first sample.
  const auto patience = std::chrono::steady_clock::now() + kUnavailablePatience;
  ReplyFrame first;
  for (;;) {
    MTLOD_TRY(first, connection.call(request, 0, std::chrono::seconds(120)));
    const auto* e = std::get_if<protocol::ErrorReply>(&first.header.reply);
    if (!e) break;
    if (e->code != protocol::ErrorKind::kUnavailable || std::chrono::steady_clock::now() >= patience)
      return make_error(ErrorCode::kInvalidArgument, "extract: " + e->message);
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  if (const auto* mesh = std::get_if<protocol::MeshReply>(&first.header.reply);
      mesh && is_delta_reply(*mesh)) {
    MTLOD_RETURN_IF_ERROR(apply_delta(*mesh, first.payload));
  }
  view_ = std::move(request);
  return Ok{};
}

void GazeStream::send_samples() {
  for (std::size_t i = 0; i < trace_.size(); ++i) {
    const GazeSample& sample = trace_[i];
    if (!sample.tracked) {
      std::lock_guard lock(replay_.totals.mutex);
      ++replay_.totals.tracker_lost;
      if (i == 0 || trace_[i - 1].tracked) ++replay_.totals.blinks;
      continue;
    }
    std::this_thread::sleep_until(replay_.start + std::chrono::nanoseconds(sample_ns(sample)));
    const bool sent = session_.send([&] {
      sent_ = i + 1;
      return OutgoingRequest{protocol::Gaze{sample.x, sample.y, std::nullopt, std::nullopt}, i + 1};
    });
    if (!sent) break;
    std::lock_guard lock(replay_.totals.mutex);
    ++replay_.totals.sent;
  }
  ++replay_.senders_done;
}

void GazeStream::receive_replies() {
  session_.receive_replies();
  {
    std::lock_guard lock(apply_mutex_);
    receiving_done_ = true;
  }
  apply_changed_.notify_all();
}

void GazeStream::apply_deltas() {
  for (;;) {
    Received received;
    {
      std::unique_lock lock(apply_mutex_);
      apply_changed_.wait(lock, [&] { return !to_apply_.empty() || receiving_done_; });
      if (to_apply_.empty()) return;
      received = std::move(to_apply_.front());
      to_apply_.pop_front();
    }
    const auto& mesh = std::get<protocol::MeshReply>(received.frame.header.reply);
    auto applied = apply_delta(mesh, received.frame.payload);
    const std::int64_t now = nanoseconds_between(replay_.start, Clock::now());
    GazeTotals& totals = replay_.totals;
    std::lock_guard lock(totals.mutex);
    if (!applied) {
      if (totals.delta_errors == 0) fmt::print(stderr, "mtlod-gaze: {}\n", applied.error().message);
      totals.delta_errors += mesh.instances.empty() ? 1 : scene_mesh_.failed_instances();
    } else if (received.sample_ns >= 0) {
      totals.applied_latency_us.record(microseconds_from(received.sample_ns, now));
    }
  }
}

Status GazeStream::apply_delta(const protocol::MeshReply& reply, std::span<const std::uint8_t> payload) {
  return reply.instances.empty() ? mesh_.apply(reply, payload) : scene_mesh_.apply(reply, payload);
}

std::size_t GazeStream::outstanding() {
  StreamSession::Locked locked = session_.lock();
  return locked.closed() ? 0 : tracked_before_[sent_] - tracked_before_[std::min(answered_, sent_)];
}

OutgoingRequest GazeStream::view_request() const {
  protocol::Extract view = view_;
  if (sent_ > 0) {
    protocol::gaze_region(view.criteria).points.front() = {trace_[sent_ - 1].x, trace_[sent_ - 1].y};
  }
  return OutgoingRequest{std::move(view), 0, true};
}

void GazeStream::restore_view() {
  {
    StreamSession::Locked locked = session_.lock();
    if (view_pending_) return;
    view_pending_ = true;
  }
  session_.send([&] { return view_request(); });
}

void GazeStream::choose_resend(std::vector<OutgoingRequest>& resend) {
  // The view's extract first, focused on the newest sample sent; then that sample, if unanswered.
  resend.push_back(view_request());
  view_pending_ = true;
  if (sent_ > answered_) {
    const GazeSample& newest = trace_[sent_ - 1];
    resend.push_back(OutgoingRequest{protocol::Gaze{newest.x, newest.y, std::nullopt, std::nullopt}, sent_});
  }
}

void GazeStream::queue_delta(ReplyFrame& frame, std::int64_t sample_time_ns) {
  ReplyFrame copy;
  copy.header = frame.header;
  copy.payload = std::move(frame.payload);
  {
    std::lock_guard lock(apply_mutex_);
    to_apply_.push_back({std::move(copy), sample_time_ns});
  }
  apply_changed_.notify_one();
}

void GazeStream::on_reply(ReplyFrame& frame, Clock::time_point arrival, const std::string&) {
  const std::int64_t now = nanoseconds_between(replay_.start, arrival);
  const std::uint64_t id = frame.header.id.value_or(0);
  const bool known_sample = id != 0 && id <= trace_.size();
  const std::size_t payload_bytes = frame.payload.size();  // before a delta's payload moves on
  if (id == 0) {  // the view's extract, answered with a mesh or refused
    StreamSession::Locked locked = session_.lock();
    view_pending_ = false;
  }
  if (const auto* error = std::get_if<protocol::ErrorReply>(&frame.header.reply);
      error && error->code == protocol::ErrorKind::kNoView) {
    restore_view();
  }
  if (const auto* mesh = std::get_if<protocol::MeshReply>(&frame.header.reply);
      mesh && is_delta_reply(*mesh)) {
    // Every delta in arrival order, the view's re-extract after a reconnect (id 0) included.
    queue_delta(frame, known_sample ? sample_ns(trace_[id - 1]) : -1);
  }
  if (!known_sample) return;
  const std::size_t index = id - 1;
  std::size_t newly_from = 0, newly_to = 0;
  {
    StreamSession::Locked locked = session_.lock();
    answered_ = std::max(answered_, index + 1);
    if (std::holds_alternative<protocol::MeshReply>(frame.header.reply) && reflected_ <= index) {
      newly_from = reflected_;
      newly_to = index + 1;
      reflected_ = index + 1;
    }
  }
  record_reply(frame.header.reply, payload_bytes, index, now, newly_from, newly_to);
}

void GazeStream::record_reply(const protocol::Reply& reply, std::size_t payload_bytes, std::size_t index,
                              std::int64_t now, std::size_t newly_from, std::size_t newly_to) {
  const GazeSample& sample = trace_[index];
  GazeTotals& totals = replay_.totals;
  std::lock_guard lock(totals.mutex);
  if (const auto* mesh = std::get_if<protocol::MeshReply>(&reply)) {
    ++totals.meshes;
    totals.mesh_latency_us.record(microseconds_from(sample_ns(sample), now));
    for (std::size_t i = newly_from; i < newly_to; ++i) {
      if (trace_[i].tracked) totals.sample_latency_us.record(microseconds_from(sample_ns(trace_[i]), now));
    }
    // The reply must say it reflects this sample (JSON carries doubles exactly).
    if (!mesh->focus || (*mesh->focus)[0] != sample.x || (*mesh->focus)[1] != sample.y)
      ++totals.focus_mismatches;
    totals.superseded_counted += mesh->superseded;
    totals.bytes += payload_bytes;
    totals.triangles += mesh->triangles;
    totals.server_total_us += mesh->timings.total_us;
  } else if (const auto* error = std::get_if<protocol::ErrorReply>(&reply)) {
    ++totals.errors_by_code[protocol::to_string(error->code)];
    if (error->code == protocol::ErrorKind::kSuperseded)
      ++totals.superseded;
    else
      ++totals.errors;
  }
}

}  // namespace mtlod::clients

// One gaze stream of mtlod-gaze: a sending thread that replays its trace (sample i at its time, as
// request i + 1), a receiving thread that matches each reply to its sample and measures it, and with
// --delta an applying thread that decodes the delta replies into the stream's copy of the mesh, so
// that decoding one reply never delays the arrival time taken for the next. The stream lives on a
// StreamSession: after a reconnect the view's extract and the newest unanswered sample are sent
// again (older samples are stale: the newest supersedes them, as the server's coalescing would).
// The view is a model's, or with --scene a scene's, whose delta replies are kept per instance.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "clients/common/delta_mesh.hpp"
#include "clients/common/extract_flags.hpp"
#include "clients/common/scene_delta_mesh.hpp"
#include "clients/common/stream_session.hpp"
#include "clients/gaze/gaze_options.hpp"
#include "clients/gaze/trace.hpp"
#include "clients/load/histogram.hpp"

namespace mtlod::clients {

using Clock = StreamSession::Clock;

// A sample's time in the replay, in nanoseconds after its start.
inline std::int64_t sample_ns(const GazeSample& sample) {
  return static_cast<std::int64_t>(sample.time_ms * 1e6);
}

struct GazeTotals {
  std::mutex mutex;
  LatencyHistogram mesh_latency_us;     // per mesh reply: its sample's time → arrival
  LatencyHistogram sample_latency_us;   // per sample: its time → a mesh showing it or a newer one
  LatencyHistogram applied_latency_us;  // per delta mesh reply: its sample's time → applied
  std::uint64_t sent = 0, meshes = 0, superseded = 0, superseded_counted = 0, errors = 0,
                focus_mismatches = 0;
  std::uint64_t bytes = 0, triangles = 0, server_total_us = 0;
  std::map<std::string, std::uint64_t> errors_by_code;
  // Delta replies that did not apply cleanly to the kept mesh; for a scene, instance meshes (a reply
  // may count once per instance).
  std::uint64_t delta_errors = 0;
  // Samples where the tracker lost the eye (not sent), and the runs of them (blinks).
  std::uint64_t tracker_lost = 0, blinks = 0;
};

// What every stream of a replay shares. Fixed before the threads start, but for the atomics and
// the totals.
struct GazeReplay {
  GazeReplay(const GazeOptions& options, GazeTotals& totals) : options(options), totals(totals) {}

  const GazeOptions& options;
  GazeTotals& totals;
  Clock::time_point start;
  std::atomic<bool> finished{false};  // no more reconnecting: the replay is over
  std::atomic<unsigned> senders_done{0};
};

class GazeStream : public StreamSession::Handler {
 public:
  // Stream `index` of `replay`, replaying `trace` (with at least one tracked sample).
  GazeStream(GazeReplay& replay, unsigned index, std::vector<GazeSample> trace);

  // Connects and opens the stream's view: one extract of the model or the scene, focused on the
  // first tracked sample (set-up, not measured). Errors name what failed.
  Status open_view(const clients::ExtractFlags& flags);

  StreamSession& session() { return session_; }
  const std::vector<GazeSample>& trace() const { return trace_; }

  // The sending thread: each tracked sample at its time, until the trace ends or the stream closes;
  // samples where the tracker lost the eye are counted, not sent (the server keeps the last gaze).
  void send_samples();
  // The receiving thread (StreamSession::receive_replies), then tells the applying thread it is done.
  void receive_replies();
  // The applying thread (--delta): applies the delta replies in arrival order until the receiving
  // thread is done and none is left.
  void apply_deltas();
  // Samples sent and not answered; 0 once the stream is closed.
  std::size_t outstanding();

  void choose_resend(std::vector<OutgoingRequest>& resend) override;
  void on_reply(ReplyFrame& frame, Clock::time_point arrival, const std::string& instance) override;

 private:
  // A delta reply received and not yet applied, with its sample's time (ns; -1 for the view's extract).
  struct Received {
    ReplyFrame frame;
    std::int64_t sample_ns;
  };

  // Applies a delta reply to the kept mesh: the model's, or the scene's instance by instance.
  Status apply_delta(const protocol::MeshReply& reply, std::span<const std::uint8_t> payload);
  // Hands a delta reply's header and payload to the applying thread.
  void queue_delta(ReplyFrame& frame, std::int64_t sample_time_ns);
  // The view's extract, focused on the newest sample sent (under the session's lock).
  OutgoingRequest view_request() const;
  // Sends the view's extract again when a gaze found the connection without one (its extract was
  // refused while the model was being replaced, after a reconnect), unless one is on its way.
  void restore_view();
  // Records the reply to sample `index`, read at `now`, which newly shows samples
  // [newly_from, newly_to).
  void record_reply(const protocol::Reply& reply, std::size_t payload_bytes, std::size_t index,
                    std::int64_t now, std::size_t newly_from, std::size_t newly_to);

  GazeReplay& replay_;
  const std::vector<GazeSample> trace_;
  std::vector<std::size_t> tracked_before_;  // [i]: tracked samples among the first i
  protocol::Extract view_;                   // the extract that opened the stream's view
  // Under the session's lock:
  std::size_t sent_ = 0;       // samples up to the newest sent; sample i has request id i + 1
  std::size_t answered_ = 0;   // samples up to the newest answered (mesh or error)
  std::size_t reflected_ = 0;  // samples [0, reflected_) have a mesh showing them or a newer sample
  // The view's extract was sent on the current connection and not answered yet.
  bool view_pending_ = false;
  // The applying thread's queue, under its own lock.
  std::mutex apply_mutex_;
  std::condition_variable apply_changed_;
  std::deque<Received> to_apply_;
  bool receiving_done_ = false;
  // With --delta: the mesh the replies build, or the scene's meshes (set-up, then the applying
  // thread only).
  DeltaMesh mesh_;
  SceneDeltaMesh scene_mesh_;
  StreamSession session_;
};

}  // namespace mtlod::clients

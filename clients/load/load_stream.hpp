// One connection of mtlod-load: a sending thread that issues its requests on schedule (open loop)
// or one after another (closed loop), and a receiving thread that matches the replies to them, in
// request order, and records what they measured. Both work on a StreamSession, which reconnects when
// the connection drops or its server drains; the unanswered requests are then sent again.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "clients/common/reply_mesh.hpp"
#include "clients/common/stream_session.hpp"
#include "clients/load/histogram.hpp"
#include "clients/load/load_options.hpp"
#include "clients/load/workload.hpp"

namespace mtlod::clients {

using Clock = StreamSession::Clock;

// Everything the receivers record, under one mutex (a few thousand replies per second at most).
struct LoadTotals {
  std::mutex mutex;
  LatencyHistogram latency_us;       // mesh replies, from the due (open) or send (closed) time
  LatencyHistogram server_total_us;  // the server's own total per mesh reply
  std::uint64_t sent = 0, ok = 0, superseded = 0, errors = 0, bytes = 0, triangles = 0;
  std::map<std::string, std::uint64_t> errors_by_code;
  protocol::StageTimings stage_sums;
  std::int64_t last_reply_ns = 0;
  struct Instance {
    std::uint64_t ok = 0;
    std::int64_t first_ns = -1, last_ns = 0;
  };
  std::map<std::string, Instance> instances;  // mesh replies by the server process that sent them
  // --decode: payloads decoded (view-restoring extracts too), those that failed, the first failure.
  std::uint64_t decoded = 0, decode_errors = 0;
  LatencyHistogram decode_us;
  std::string first_decode_error;
};

// What every connection of a run shares. Fixed before the threads start, but for the atomics and
// the totals.
struct LoadRun {
  LoadRun(const LoadOptions& options, const RequestSettings& requests, LoadTotals& totals)
      : options(options), requests(requests), totals(totals) {}

  const LoadOptions& options;
  const RequestSettings& requests;
  LoadTotals& totals;
  std::vector<ModelView> models;
  std::vector<std::vector<std::int64_t>> plan;  // open loop: each connection's due times (ns)
  unsigned window = 1;                          // unanswered requests per connection
  std::int64_t duration_ns = 0;
  Clock::time_point start;
  std::atomic<bool> finished{false};     // no more reconnecting: the run is over
  std::atomic<std::uint64_t> issued{0};  // closed loop: requests taken from --requests
  std::atomic<unsigned> senders_done{0};

  Clock::time_point end_of_sending() const { return start + std::chrono::nanoseconds(duration_ns); }
};

class LoadStream : public StreamSession::Handler {
 public:
  // Connection `index` of `run`.
  LoadStream(LoadRun& run, unsigned index);

  StreamSession& session() { return session_; }

  // The sending thread: issues requests until the schedule, the duration or --requests ends, or the
  // stream closes.
  void send_requests();
  // Requests sent and not answered (view-restoring extracts not included).
  std::size_t outstanding();
  // Due requests that the window held back past the end of the test.
  std::uint64_t unsent() const { return unsent_; }

  void choose_resend(std::vector<OutgoingRequest>& resend) override;
  void on_reply(ReplyFrame& frame, Clock::time_point arrival, const std::string& instance) override;

 private:
  struct Pending {
    std::uint64_t id;
    std::int64_t intended_ns;   // latency starts here
    protocol::Request request;  // kept to send again after a reconnect
    bool setup = false;         // an extract re-sent to restore the view for gazes: not counted
  };

  // Waits for request `i`'s turn; false when there is none. Sets its due time (open loop).
  bool wait_for_turn(std::size_t i, std::int64_t& intended_ns);
  // Waits for room in the window; false when the stream closed or the test ended first.
  bool wait_for_window(std::size_t i);

  LoadRun& run_;
  const unsigned index_;
  // Under the session's lock:
  std::deque<Pending> pending_;
  std::optional<protocol::Extract> view_;  // the last extract sent: restores the view for gazes
  std::uint64_t next_id_ = 1;
  std::uint64_t unsent_ = 0;
  ReplyMesh mesh_;  // --decode: the receiving thread's copy of what the replies hold
  StreamSession session_;
};

}  // namespace mtlod::clients

// Per-connection request policy, no sockets (core/ARCHITECTURE.md §4; PROTOCOL.md): replies
// leave in request order, compute jobs of one connection run one at a time (they share the
// connection's cut for dynamic refinement), a newer gaze replaces a queued one, cancel removes a
// queued job, and the number of unanswered requests is bounded.
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <vector>

#include "protocol/messages.hpp"

namespace mtlod::server {

// A reply frame waiting for its turn.
struct Reply {
  std::vector<std::uint8_t> frame;
  bool mesh = false;  // an extraction's mesh: counted as sent once written whole
};

// Holds replies until every earlier request has its reply, then releases them in order.
class ReplyOrder {
 public:
  // Reserves the next place in the reply order; returns its sequence number.
  std::uint64_t open();
  // Gives the reply for a place (once).
  void fill(std::uint64_t seq, std::vector<std::uint8_t> frame, bool mesh = false);
  // Whether a place has its reply (popped places had theirs).
  bool filled(std::uint64_t seq) const {
    return seq < next_pop_ ||
           (seq < next_seq_ && waiting_[static_cast<std::size_t>(seq - next_pop_)].has_value());
  }
  // The next reply that may be written, if its turn has come.
  std::optional<Reply> pop();
  // Places opened and not yet popped: the connection's unanswered requests.
  std::size_t outstanding() const { return next_seq_ - next_pop_; }

 private:
  std::uint64_t next_seq_ = 0;
  std::uint64_t next_pop_ = 0;
  std::deque<std::optional<Reply>> waiting_;  // index 0 is next_pop_
};

// A compute request (extract, or a gaze already turned into a full extract) waiting for a worker.
struct Job {
  std::uint64_t seq = 0;  // place in the reply order
  std::uint64_t id = 0;   // the client's request id
  bool gaze = false;
  protocol::Extract extract;
  std::uint64_t superseded = 0;  // gazes this job replaced
  std::int64_t received_ns = 0;  // when its frame arrived (steady clock), for queue timings
};

class JobQueue {
 public:
  // Queues a job. A gaze replaces a gaze still waiting at the end of the queue; the replaced job
  // is returned so its caller can answer it `superseded`.
  std::optional<Job> push(Job job);
  // Removes a queued job by request id; nothing when it is running, done or unknown.
  std::optional<Job> cancel(std::uint64_t id);
  // The next job to run when none is running.
  std::optional<Job> start_next();
  void finish() { running_ = false; }
  bool running() const { return running_; }
  std::size_t queued() const { return queue_.size(); }
  // True when a push of a gaze would replace the last queued job.
  bool last_is_gaze() const { return !queue_.empty() && queue_.back().gaze; }
  // Drops every queued job (shutdown), returning them to be answered.
  std::vector<Job> drain();

 private:
  std::deque<Job> queue_;
  bool running_ = false;
};

}  // namespace mtlod::server

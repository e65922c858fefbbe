// Per-connection request policy (see session_queue.hpp).
#include "server/session_queue.hpp"

#include <cassert>

namespace mtlod::server {

std::uint64_t ReplyOrder::open() {
  waiting_.emplace_back();
  return next_seq_++;
}

void ReplyOrder::fill(std::uint64_t seq, std::vector<std::uint8_t> frame, bool mesh) {
  assert(seq >= next_pop_ && seq < next_seq_);
  auto& slot = waiting_[static_cast<std::size_t>(seq - next_pop_)];
  assert(!slot.has_value());
  slot = Reply{std::move(frame), mesh};
}

std::optional<Reply> ReplyOrder::pop() {
  if (waiting_.empty() || !waiting_.front().has_value()) return std::nullopt;
  std::optional<Reply> frame = std::move(waiting_.front());
  waiting_.pop_front();
  ++next_pop_;
  return frame;
}

std::optional<Job> JobQueue::push(Job job) {
  if (job.gaze && last_is_gaze()) {
    // Latest wins: the waiting gaze is replaced, never queued behind.
    Job replaced = std::move(queue_.back());
    job.superseded = replaced.superseded + 1;
    queue_.back() = std::move(job);
    return replaced;
  }
  queue_.push_back(std::move(job));
  return std::nullopt;
}

std::optional<Job> JobQueue::cancel(std::uint64_t id) {
  for (auto it = queue_.begin(); it != queue_.end(); ++it) {
    if (it->id == id) {
      Job job = std::move(*it);
      queue_.erase(it);
      return job;
    }
  }
  return std::nullopt;
}

std::optional<Job> JobQueue::start_next() {
  if (running_ || queue_.empty()) return std::nullopt;
  Job job = std::move(queue_.front());
  queue_.pop_front();
  running_ = true;
  return job;
}

std::vector<Job> JobQueue::drain() {
  std::vector<Job> jobs(std::make_move_iterator(queue_.begin()), std::make_move_iterator(queue_.end()));
  queue_.clear();
  return jobs;
}

}  // namespace mtlod::server

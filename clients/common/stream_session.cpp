// A stream of pipelined requests that reconnects (see stream_session.hpp).
#include "clients/common/stream_session.hpp"

namespace mtlod::clients {

StreamSession::StreamSession(Handler& handler, Endpoint endpoint, std::string client, RetryPolicy retry,
                             std::uint64_t jitter_seed, const std::atomic<bool>& run_over)
    : handler_(handler),
      endpoint_(std::move(endpoint)),
      client_(std::move(client)),
      retry_(retry),
      run_over_(run_over),
      jitter_rng_(jitter_seed) {}

Result<protocol::HelloReply> StreamSession::connect() {
  MTLOD_TRY(Session session, open_session(endpoint_, client_, retry_, jitter_rng_));
  connection_ = std::make_shared<ServerConnection>(std::move(session.connection));
  instance_ = session.hello.instance;
  return std::move(session.hello);
}

bool StreamSession::reconnect(std::uint64_t failed) {
  std::lock_guard send_lock(send_mutex_);
  std::shared_ptr<ServerConnection> old;
  {
    std::lock_guard lock(mutex_);
    if (generation_ != failed || closed_) return !closed_;
    reconnecting_ = true;
    old = connection_;
  }
  // The receiving thread may be blocked on the old connection (when the sending thread recycles it).
  if (old) old->interrupt();
  auto session = open_session(endpoint_, client_, retry_, jitter_rng_, nullptr, &run_over_);
  auto connection = session ? std::make_shared<ServerConnection>(std::move(session->connection)) : nullptr;
  std::vector<OutgoingRequest> resend;
  {
    std::lock_guard lock(mutex_);
    reconnecting_ = false;
    if (!connection) {
      closed_ = true;
    } else {
      connection_ = connection;
      ++generation_;
      instance_ = session->hello.instance;
      sent_on_connection_ = 0;
      handler_.choose_resend(resend);
    }
  }
  changed_.notify_all();
  if (!connection) {
    ++gave_up_;
    return false;
  }
  ++reconnects_;
  for (const OutgoingRequest& r : resend) resent_ += r.restores_view ? 0 : 1;
  // A send that fails here shows up as a failed receive on the new connection.
  for (const OutgoingRequest& r : resend) {
    if (!connection->send(r.request, r.id)) break;
  }
  return true;
}

void StreamSession::receive_replies() {
  for (;;) {
    std::shared_ptr<ServerConnection> connection;
    std::uint64_t generation = 0;
    std::string instance;
    {
      std::unique_lock lock(mutex_);
      changed_.wait(lock, [&] { return !reconnecting_; });
      if (closed_) break;
      connection = connection_;
      generation = generation_;
      instance = instance_;
    }
    auto frame = connection->receive(std::chrono::hours(1));
    const Clock::time_point arrival = Clock::now();
    if (!frame || asks_for_retry(*frame)) {
      if (run_over_) break;
      {
        // Replaced by the sending thread (recycled, or it is being replaced): carry on with the new one.
        std::lock_guard lock(mutex_);
        if (reconnecting_ || generation_ != generation) continue;
      }
      if (!reconnect(generation)) break;
      continue;
    }
    handler_.on_reply(*frame, arrival, instance);
  }
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  changed_.notify_all();
}

void StreamSession::interrupt() {
  std::lock_guard lock(mutex_);
  if (connection_) connection_->interrupt();
}

void StreamSession::close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
    if (connection_) connection_->interrupt();
  }
  changed_.notify_all();
}

}  // namespace mtlod::clients

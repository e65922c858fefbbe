// One stream of pipelined requests to mtlod-server that outlives its connections, shared by the
// load tester and the gaze replay: a sending thread and a receiving thread work on it at once. When
// the connection drops or its server drains (`shutting_down`), the receiving thread reconnects with
// backoff (retry.hpp) and sends again what the program chooses, so a failover shows as latency and
// retries, not as lost requests. The program keeps its own record of the requests in flight; the
// session's lock guards that record too, so that recording a request and sending it, or replacing
// the connection and choosing what to send again, are single steps for the other thread.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "clients/common/retry.hpp"
#include "clients/common/server_connection.hpp"
#include "core/result.hpp"
#include "protocol/messages.hpp"
#include "protocol/replies.hpp"

namespace mtlod::clients {

// A request with the id it goes out with.
struct OutgoingRequest {
  protocol::Request request;
  std::uint64_t id = 0;
  // An extract that gives a new connection the view its gazes refer to: set-up, not a request
  // sent again, so not counted in resent().
  bool restores_view = false;
};

class StreamSession {
 public:
  using Clock = std::chrono::steady_clock;

  // What the program decides at the session's turning points. Called from the receiving thread, and
  // choose_resend also from the sending thread when it recycles the connection.
  class Handler {
   public:
    virtual ~Handler() = default;
    // A new connection replaced a failed or recycled one; the session's lock is held. Appends to
    // `resend` the requests to send on it, in order.
    virtual void choose_resend(std::vector<OutgoingRequest>& resend) = 0;
    // A reply other than `shutting_down`, read at `arrival` from the server process `instance` (its
    // hello's instance); the session's lock is not held. The payload may be moved out.
    virtual void on_reply(ReplyFrame& frame, Clock::time_point arrival, const std::string& instance) = 0;
  };

  // Holds the session's lock, which also guards the program's record of the stream's requests.
  class Locked {
   public:
    // No connection and none to come: the receiving thread has ended or the run is over.
    bool closed() const { return session_.closed_; }
    // Waits, the lock released meanwhile, until ready() (called with the lock held) or the stream
    // closes; false when the deadline passed first.
    template <class Ready>
    bool wait_until(Clock::time_point deadline, Ready&& ready) {
      return session_.changed_.wait_until(lock_, deadline, [&] { return session_.closed_ || ready(); });
    }

   private:
    friend class StreamSession;
    explicit Locked(StreamSession& session) : session_(session), lock_(session.mutex_) {}
    StreamSession& session_;
    std::unique_lock<std::mutex> lock_;
  };

  // `client` is the name said in hello ("mtlod-load/0.1"); `jitter_seed` seeds the backoff jitter.
  // Once `run_over` is set no reconnection starts and a failed receive ends the receiving thread.
  StreamSession(Handler& handler, Endpoint endpoint, std::string client, RetryPolicy retry,
                std::uint64_t jitter_seed, const std::atomic<bool>& run_over);
  StreamSession(const StreamSession&) = delete;
  StreamSession& operator=(const StreamSession&) = delete;

  // Opens the first connection (with the retry policy's attempts) and returns its hello. Before the
  // stream's threads start; errors as open_session's.
  Result<protocol::HelloReply> connect();
  // The connection, after connect(): for set-up calls before the stream's threads start (model
  // info, a first view).
  ServerConnection& connection() { return *connection_; }

  Locked lock() { return Locked(*this); }
  // Wakes the threads waiting in Locked::wait_until, after the program changed its record.
  void wake_waiters() { changed_.notify_all(); }

  // For the sending thread: `record()` runs under the lock, records the request as in flight and
  // returns it; then it is sent, the connection being held steady meanwhile. False when the stream is
  // closed (nothing recorded or sent). A failed send is left to the receiving thread: its receive
  // fails too, and it reconnects and sends again what the handler chooses.
  template <class Record>
  bool send(Record&& record) {
    std::lock_guard send_lock(send_mutex_);
    std::shared_ptr<ServerConnection> connection;
    OutgoingRequest outgoing;
    {
      std::lock_guard lock(mutex_);
      if (closed_) return false;
      outgoing = record();
      ++sent_on_connection_;
      connection = connection_;
    }
    (void)connection->send(outgoing.request, outgoing.id);
    return true;
  }

  // For the sending thread: once `requests` went over the current connection, waits until idle()
  // (called with the lock held; say, every reply is in) and then replaces the connection, so that a
  // load balancer can place the stream anew. When `deadline` passes first it keeps the connection.
  // False when the stream is closed or gave up reconnecting.
  template <class Idle>
  bool recycle_connection(std::uint64_t requests, Clock::time_point deadline, Idle&& idle) {
    std::uint64_t generation = 0;
    {
      Locked locked = lock();
      if (sent_on_connection_ < requests) return true;
      if (!locked.wait_until(deadline, idle)) return true;
      generation = generation_;
    }
    return reconnect(generation);
  }

  // The receiving thread: reads replies and hands them to the handler, reconnecting when the
  // connection fails or the server drains. Returns when the stream closes: reconnecting gave up, or
  // the run is over and the connection was interrupted.
  void receive_replies();

  // Makes a receive blocked on the connection return (at the end of the run).
  void interrupt();
  // Closes the stream at the end of the run: the sending thread's waits and sends end too.
  void close();

  // Connections that replaced a failed or recycled one.
  std::uint64_t reconnects() const { return reconnects_; }
  // Requests sent again on a new connection, the view-restoring extracts not included.
  std::uint64_t resent() const { return resent_; }
  // 1 when reconnecting gave up after every attempt, else 0.
  std::uint64_t gave_up() const { return gave_up_; }

 private:
  // Replaces the connection unless another thread already replaced generation `failed`: closes it,
  // reconnects with backoff, and sends on the new one what the handler chooses. Returns false when
  // the stream is closed or gave up.
  bool reconnect(std::uint64_t failed);

  Handler& handler_;
  const Endpoint endpoint_;
  const std::string client_;
  const RetryPolicy retry_;
  const std::atomic<bool>& run_over_;
  std::mt19937_64 jitter_rng_;  // backoff jitter: used only by the thread holding send_mutex_

  std::mutex send_mutex_;  // held while sending and while the connection is replaced (before mutex_)
  std::mutex mutex_;       // guards what follows, and the program's record of requests in flight
  std::condition_variable changed_;
  std::shared_ptr<ServerConnection> connection_;
  std::uint64_t generation_ = 0;  // bumped at every new connection
  bool reconnecting_ = false;
  bool closed_ = false;
  std::string instance_;  // the server process on the current connection
  std::uint64_t sent_on_connection_ = 0;

  std::atomic<std::uint64_t> reconnects_{0}, resent_{0}, gave_up_{0};
};

// Nanoseconds from `from` to `to`: the clients' times are counted from the start of their run.
inline std::int64_t nanoseconds_between(StreamSession::Clock::time_point from,
                                        StreamSession::Clock::time_point to) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(to - from).count();
}

}  // namespace mtlod::clients

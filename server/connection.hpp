// One client connection's request logic, independent of its transport (TCP frames or WebSocket
// messages): parse, answer cheap requests at once, queue extractions one at a time per connection
// on the worker pool, coalesce gazes, keep replies in request order, drain on shutdown. A transport
// subclass moves bytes; everything here runs on the connection's strand.
#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/thread_pool.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "protocol/errors.hpp"
#include "protocol/messages.hpp"
#include "server/engine.hpp"
#include "server/metrics.hpp"
#include "server/server.hpp"
#include "server/session_queue.hpp"

namespace mtlod::server {

// What every connection of a server shares.
struct ServerContext {
  const ServerConfig& config;
  const ModelRegistry& models;
  Engine& engine;
  Metrics& metrics;
  boost::asio::thread_pool& workers;
  std::function<void()> on_connection_closed;  // called once per connection, from its strand
};

class Connection : public std::enable_shared_from_this<Connection> {
 public:
  virtual ~Connection() = default;

  // Graceful end, from any thread: stop reading, answer queued extractions `shutting_down`, let the
  // running one finish, close once every reply is written.
  void shutdown();
  // Immediate close, from any thread (drain timeout).
  void force_close();

 protected:
  Connection(ServerContext& server, boost::asio::any_io_executor strand, std::uint64_t number);

  // ---- Transport hooks (called on the strand) ----
  // Starts writing one reply frame (8-byte header, JSON, payload); call on_written() when done.
  virtual void write_frame(std::vector<std::uint8_t>& frame) = 0;
  // Ends the pending read (the transport then calls on_read_end()).
  virtual void stop_reading() = 0;
  // Reading was paused by paused(); read again.
  virtual void resume_reading() = 0;
  // Closes the socket.
  virtual void close_transport() = 0;

  // ---- For transports (call on the strand) ----
  void opened();
  // A complete request's JSON text arrived at received_ns (steady clock).
  void handle_frame(std::string_view json, std::int64_t received_ns);
  // The stream cannot continue (bad frame header): answer `bad_frame`, then close.
  void bad_frame(const std::string& message);
  // The last write_frame finished (ok = false: the peer is gone).
  void on_written(bool ok, std::size_t bytes);
  // The peer closed its side or the read failed.
  void on_read_end();
  // Whether the transport may start the next read. False once ending, and false while the client
  // has too many unanswered requests (resume_reading() is called when it catches up).
  bool may_read();
  // True while replies are owed: a connection waiting on the server is not idle.
  bool waiting_on_server() const { return replies_.outstanding() > 0; }
  bool ending() const { return stopping_ || closed_; }
  std::uint64_t number() const { return number_; }
  const boost::asio::any_io_executor& strand() const { return strand_; }
  ServerContext& server_;

 private:
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::Hello& request);
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::ListModels& request);
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::ModelInfo& request);
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::Extract& request);
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::Gaze& request);
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::Cancel& request);
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::Stats& request);
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::Ping& request);
  bool paused() const;
  void enqueue(Job job);
  void start_next_job();
  void finish_job(const Job& job, std::int64_t started_ns,
                  std::variant<ExtractOutcome, protocol::ProtocolError>& outcome);
  void reply_unknown_model(std::uint64_t seq, std::uint64_t id, const std::string& name);
  void reply_error(std::uint64_t seq, protocol::ErrorKind code, const std::string& message,
                   std::optional<std::uint64_t> id);
  void drain_jobs(protocol::ErrorKind code, const char* message);
  void flush();
  void close();

  boost::asio::any_io_executor strand_;
  std::uint64_t number_;
  ReplyOrder replies_;
  JobQueue jobs_;
  SessionCut cut_;
  std::optional<protocol::Extract> last_extract_;
  std::int64_t received_ns_ = 0;  // arrival of the request being handled
  std::vector<std::uint8_t> outgoing_;
  bool writing_ = false;
  bool read_paused_ = false;
  bool stopping_ = false;
  bool closed_ = false;
};

}  // namespace mtlod::server

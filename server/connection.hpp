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
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "protocol/errors.hpp"
#include "protocol/frame.hpp"
#include "protocol/messages.hpp"
#include "server/admission.hpp"
#include "server/auth.hpp"
#include "server/engine.hpp"
#include "server/metrics.hpp"
#include "server/server.hpp"
#include "server/session_queue.hpp"

namespace mtlod::server {

// What every connection of a server shares.
struct ServerContext {
  const ServerConfig& config;
  ModelRegistry& models;
  Engine& engine;
  Metrics& metrics;
  AddressTable& addresses;
  FairScheduler& scheduler;  // runs extractions on the worker pool, client addresses taking turns
  MemoryCeiling& memory;     // worker scratch plus sessions, against --max-memory
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
  // `slot`: this connection's hold on its client address (AddressTable), released when it closes.
  Connection(ServerContext& server, boost::asio::any_io_executor strand, std::uint64_t number,
             AddressTable::Slot slot);

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
  // A stream transport read a frame header: its decoded form, or nullopt after answering
  // `bad_frame` (the stream cannot continue).
  std::optional<protocol::FrameHeader> frame_header(
      std::span<const std::uint8_t, protocol::kFrameHeaderBytes> bytes);
  // A message transport received a whole message arriving at received_ns: a text message holds a
  // request's JSON, a binary one a whole frame (header included). False when the message broke
  // the stream (answered `bad_frame`; read no more).
  bool handle_message(bool text, std::string_view message, std::int64_t received_ns);
  // The stream cannot continue (bad frame header): answer `bad_frame`, then close.
  void bad_frame(const std::string& message);
  // The connection has shown a valid access token outside the protocol (the WebSocket upgrade
  // request): it is served as after a hello carrying it. `grant` comes from the server's tokens.
  void authorise(const Grant* grant);
  // Runs a transport's completion handler so that no exception leaves it: a throw (an allocation
  // failure, a bug) is logged and closes this connection only, never the process.
  template <class F>
  void guarded(const char* what, F&& handler) noexcept {
    try {
      handler();
    } catch (const std::exception& e) {
      failed(what, e.what());
    } catch (...) {
      failed(what, "an unknown exception");
    }
  }
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
  const std::string& address() const { return slot_.address(); }
  // Whether a request has arrived yet: until then the first-frame deadline applies, not the idle one.
  bool got_request() const { return got_request_; }
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
  void on_request(std::uint64_t seq, std::uint64_t id, const protocol::Reload& request);
  bool paused() const;
  void failed(const char* what, const char* reason) noexcept;
  void enqueue(Job job);
  void start_next_job();
  void finish_job(const Job& job, std::int64_t started_ns, ExtractResult& outcome);
  void finish_reply(const Job& job, std::int64_t started_ns, ExtractResult& outcome);
  // Whether this connection may be served yet: true without access tokens, else once a token is shown.
  bool authorised() const { return !server_.config.tokens || grant_ != nullptr; }
  // The model of that name if this connection's token lets it see it, else nullptr.
  ModelPtr visible_model(std::string_view name) const;
  // The first model an extract names (its model, or its scene's) that visible_model does not give.
  const std::string* unseen_model(const protocol::Extract& request) const;
  void reply_unknown_model(std::uint64_t seq, std::uint64_t id, const std::string& name);
  void reply_error(std::uint64_t seq, protocol::ErrorKind code, const std::string& message,
                   std::optional<std::uint64_t> id);
  void drain_jobs(protocol::ErrorKind code, const char* message);
  void flush();
  void close();
  // Frees the session's cut and its share of the memory ceiling (no job may be running).
  void release_session();

  boost::asio::any_io_executor strand_;
  std::uint64_t number_;
  AddressTable::Slot slot_;
  bool got_request_ = false;
  std::uint64_t session_accounted_ = 0;  // the session's bytes as counted in the memory ceiling
  std::uint64_t reserved_ = 0;           // the running job's reservation in the memory ceiling
  ReplyOrder replies_;
  JobQueue jobs_;
  ExtractionState cut_;
  const Grant* grant_ = nullptr;  // the access token shown (with --auth-tokens), owned by the server
  bool refusal_logged_ = false;   // a hello's token was refused, and said so in the log
  std::optional<protocol::Extract> last_extract_;          // its codec always set
  core::codec::Codec codec_ = core::codec::Codec::kDraco;  // for extracts that name none (hello)
  std::int64_t received_ns_ = 0;                           // arrival of the request being handled
  std::vector<std::uint8_t> outgoing_;
  bool outgoing_mesh_ = false;  // outgoing_ is an extraction's mesh
  bool writing_ = false;
  bool read_paused_ = false;
  bool stopping_ = false;
  bool closed_ = false;
};

}  // namespace mtlod::server

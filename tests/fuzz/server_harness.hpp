// End-to-end fuzzing of the server (fuzz_server_stream.cpp, fuzz_server_messages.cpp): one
// in-process server — a small real model, the engine, a worker pool, an io_context — and client
// transports that feed fuzz input through the same Connection code as server/tcp_session.cpp and
// server/web_session.cpp. Every reply is checked as it is written: the frame, its JSON (parsed back
// as a client would, and UTF-8), mesh payloads (decoded, deltas applied), one reply per request in
// request order, no `internal` error. Any violation traps, so libFuzzer and the replay driver stop.
#pragma once

#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/thread_pool.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "protocol/errors.hpp"
#include "protocol/messages.hpp"
#include "protocol/replies.hpp"
#include "server/admission.hpp"
#include "server/connection.hpp"
#include "server/engine.hpp"
#include "server/metrics.hpp"
#include "server/model_registry.hpp"
#include "server/server.hpp"

namespace mtlod::fuzz {

// What one connection was sent and what it answered; checks the two against each other.
class Transcript {
 public:
  Transcript(const protocol::Limits& limits, std::size_t model_triangles);

  // A request's JSON reached Connection::handle_frame: one reply is owed, with the id, and the
  // type or error code, that parse_request reads from it.
  void expect_request(std::string_view json);
  // A Connection call of the transport answered `bad_frame`: one reply is owed, the last one.
  void expect_bad_frame();
  // A reply frame as the connection hands it to its transport.
  void check_reply(std::span<const std::uint8_t> frame);
  // After the connection closed: every request got its reply, in order.
  void check_complete() const;
  // Whether a valid extract or gaze was sent (its reply, unless refused, is a mesh).
  bool asked_for_meshes() const;

 private:
  struct Expected {
    std::optional<std::uint64_t> id;
    std::optional<protocol::ErrorKind> error;  // a request the parser refuses, or a bad frame
    const char* reply_type = nullptr;          // a valid request's reply type, when it does not fail
  };
  struct Written {
    std::optional<std::uint64_t> id;
    const char* type;
    std::optional<protocol::ErrorKind> error;
  };
  void check_mesh(const protocol::MeshReply& mesh, std::span<const std::uint8_t> payload);

  const protocol::Limits& limits_;
  std::vector<Expected> expected_;
  std::vector<Written> written_;
  // The client's mesh as delta replies build it, by MT triangle id.
  std::vector<bool> client_has_;
  std::size_t client_triangles_ = 0;
  bool client_keyed_ = false;  // false: no mesh yet, or a full mesh without ids
};

// What a FuzzServer hands to the transport it runs.
struct ConnectionArgs {
  server::ServerContext& server;
  boost::asio::any_io_executor strand;
  std::uint64_t number;
  server::AddressTable::Slot slot;
  Transcript& transcript;
  bool patient;  // the client waits for every reply owed before it sends on, or hangs up
};

// A client transport: a Connection whose input comes from the fuzzer and whose writes are checked.
// Completions are posted to the strand as Asio's would be, so worker results interleave with
// reads and writes as they do on a socket. An impatient client sends its whole input at once and
// hangs up (queued work is cancelled, gazes coalesce); a patient one sends a request only when
// every reply owed has gone out and hangs up after the last, so each gaze and delta really runs.
class FuzzConnection : public server::Connection {
 public:
  // Opens the connection and starts reading, on its strand (as TcpSession::start).
  void start();

 protected:
  explicit FuzzConnection(ConnectionArgs&& args)
      : Connection(args.server, std::move(args.strand), args.number, std::move(args.slot)),
        transcript_(args.transcript),
        patient_(args.patient) {}

  // Starts the next read; the transport's own do_read.
  virtual void read() = 0;
  // Whether read() may go on: Connection::may_read(), and for a patient client no reply owed (the
  // read starts again when the last one is written).
  bool may_read_next();

  void write_frame(std::vector<std::uint8_t>& frame) override;
  void resume_reading() override { read(); }
  void close_transport() override { transport_closed_ = true; }

  Transcript& transcript_;
  bool transport_closed_ = false;

 private:
  const bool patient_;
  bool awaiting_replies_ = false;
};

// The server every input talks to, built once per process.
class FuzzServer {
 public:
  static FuzzServer& get();

  // Runs a connection made by `make` for an impatient client, then, when it asked for meshes, one
  // for a patient client (see FuzzConnection; without extractions the two take the same path), each
  // until it has closed and been destroyed, and checks their transcripts. Traps when one does not
  // close or stays referenced.
  using Factory = std::function<std::shared_ptr<FuzzConnection>(ConnectionArgs&&)>;
  void run(const Factory& make);

 private:
  FuzzServer();
  // Returns the transcript's asked_for_meshes().
  bool run(const Factory& make, bool patient);
  void on_closed();
  void wait_for_workers();

  server::ServerConfig config_;
  server::ModelRegistry models_;
  std::size_t model_triangles_ = 0;
  server::Engine engine_{models_};
  server::Metrics metrics_;
  server::AddressTable addresses_{0};
  server::MemoryCeiling memory_;
  // One worker: extractions still run off the I/O thread and post back, as in the server.
  boost::asio::thread_pool workers_{1};
  server::FairScheduler scheduler_{workers_, 1};
  boost::asio::io_context io_;
  // Keeps io_.run() going while an extraction is on the worker; dropped when the connection closes.
  std::optional<boost::asio::executor_work_guard<boost::asio::io_context::executor_type>> guard_;
  server::ServerContext context_{config_,    models_,    engine_, metrics_,
                                 addresses_, scheduler_, memory_, [this] { on_closed(); }};
  std::uint64_t next_number_ = 1;
  bool closed_ = false;
};

// Writes the targets' model to `file` (an .mt file; the model "bunny" when the file is bunny.mt)
// and returns its triangle count.
std::size_t write_fuzz_model(const std::filesystem::path& file);

// Reports a broken server contract and traps.
[[noreturn]] void fail(const std::string& what);

std::int64_t now_ns();

}  // namespace mtlod::fuzz

// The fuzz targets that go through the whole server process (fuzz_process_*.cpp): real
// server::Server instances in this process, with ServerConfig's defaults and the production limits
// (protocol::Limits' defaults), their acceptors, TcpSession, the WebSocket and HTTP sessions
// (Beast), TLS, an I/O thread and a worker, reached over loopback sockets as any client reaches
// them. Nothing of the transport is imitated (server_harness.hpp imitates it to run faster): bytes
// go through the kernel, replies are read back from the socket and checked by the same Transcript,
// and a failed check traps.
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/system/error_code.hpp>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "protocol/messages.hpp"
#include "tests/fuzz/server_harness.hpp"

namespace mtlod::fuzz {

// How long the server may take to answer or close after the client's input ended: far longer than
// the extractions of any input, so only a stuck connection reaches it.
inline constexpr auto kReplyDeadline = std::chrono::seconds(20);

// Two servers serving one small model ("bunny", about 2,000 triangles, with normals), started once
// per process and never stopped: one plain (protocol and HTTP ports), one with TLS on both.
class ProcessServer {
 public:
  static ProcessServer& get();

  std::uint16_t port() const { return port_; }
  std::uint16_t http_port() const { return http_port_; }
  std::uint16_t tls_port() const { return tls_port_; }
  const std::filesystem::path& certificate() const { return cert_; }  // the TLS server's, its own CA
  const protocol::Limits& limits() const { return limits_; }
  std::size_t model_triangles() const { return model_triangles_; }

 private:
  ProcessServer();

  protocol::Limits limits_;
  std::size_t model_triangles_ = 0;
  std::filesystem::path cert_;
  std::uint16_t port_ = 0, http_port_ = 0, tls_port_ = 0;
};

// A client's byte stream to a server: plain TCP, or TLS over it.
class Channel {
 public:
  virtual ~Channel() = default;
  // Sends every byte; false once the server has closed its side (the rest is not sent).
  virtual bool send(std::span<const std::uint8_t> bytes) = 0;
  // Ends the sending side: the server reads end of stream.
  virtual void finish_sending() = 0;
  // Appends what arrives to `into`; false once the server has closed (end of stream or reset).
  // Traps when nothing arrives and the server does not close within kReplyDeadline.
  virtual bool receive(std::vector<std::uint8_t>& into) = 0;
  // Everything until the server closes.
  std::vector<std::uint8_t> receive_all();
};

// A blocking TCP socket to 127.0.0.1.
class ClientSocket final : public Channel {
 public:
  explicit ClientSocket(std::uint16_t port);
  ~ClientSocket() override;
  ClientSocket(const ClientSocket&) = delete;
  ClientSocket& operator=(const ClientSocket&) = delete;

  bool send(std::span<const std::uint8_t> bytes) override;
  void finish_sending() override;
  bool receive(std::vector<std::uint8_t>& into) override;

 private:
  int fd_ = -1;
};

// One frame of a client's byte stream as the server's TCP session reads it (PROTOCOL.md,
// "Framing"): a whole frame, or a header the server refuses (`bad`, the last one it reads).
struct StreamFrame {
  std::span<const std::uint8_t> bytes;  // header, JSON and payload (the header alone when bad)
  std::string_view json;
  bool bad = false;
};

// The frames the server reads from `input` followed by end of stream: up to a refused header, or
// the last whole frame.
std::vector<StreamFrame> split_stream(std::span<const std::uint8_t> input, const protocol::Limits& limits);

// Tells `transcript` what `frame` owes: a reply to its request, or the bad_frame error.
void expect(Transcript& transcript, const StreamFrame& frame);

// Splits the whole reply frames off the front of `bytes`, checks each with `transcript` and returns
// how many there were.
std::size_t take_replies(std::vector<std::uint8_t>& bytes, Transcript& transcript);

// Sends `input` as a client's byte stream over connections that `open` makes (plain or TLS) and
// checks every reply against what its frames owe: once impatient (all bytes at once, then end of
// stream) and, when it asked for meshes, once patient (a frame only when every reply owed has
// come, so that each gaze and delta really runs).
void run_stream_client(std::span<const std::uint8_t> input,
                       const std::function<std::unique_ptr<Channel>()>& open);

// Runs one asynchronous operation on `io` to its end and returns its error; traps, naming `what`,
// when it takes longer than kReplyDeadline. Clients here use Asio's asynchronous calls only: its
// synchronous ones fail with EINTR when a signal (libFuzzer's timer) interrupts them.
template <typename Start>
boost::system::error_code complete(boost::asio::io_context& io, const char* what, const Start& start) {
  boost::system::error_code result;
  bool done = false;
  start([&](boost::system::error_code ec, auto&&...) {
    result = ec;
    done = true;
  });
  io.restart();
  const auto deadline = std::chrono::steady_clock::now() + kReplyDeadline;
  while (!done) {
    if (io.run_one_until(deadline) == 0 && !done) fail(std::string("no end in time: ") + what);
  }
  return result;
}

// Whether `text` is UTF-8 as RFC 3629 defines it (what a WebSocket text message must be).
bool valid_utf8(std::string_view text);

}  // namespace mtlod::fuzz

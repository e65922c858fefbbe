// A blocking connection to mtlod-server for command-line clients and tests: connect (over TLS when
// asked), send a request, read the reply frame (JSON header + payload). One request at a time or
// pipelined.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/result.hpp"
#include "protocol/messages.hpp"
#include "protocol/replies.hpp"

namespace mtlod::clients {

struct ReplyFrame {
  protocol::ParsedReply header;
  std::string json;                   // the reply's JSON text as received
  std::vector<std::uint8_t> payload;  // the encoded mesh, for mesh replies
};

// TLS for a connection (mtlod-client, mtlod-load, mtlod-gaze: --tls, --tls-ca). The server's
// certificate must be valid for the host connected to (a name or an IP address) and chain to a
// trusted certificate.
struct TlsOptions {
  bool enabled = false;
  std::string
      ca_file;  // PEM certificates to trust instead of the system's (a private CA, a self-signed server)
};

class ServerConnection {
 public:
  ServerConnection();
  ~ServerConnection();
  ServerConnection(ServerConnection&&) noexcept;
  ServerConnection& operator=(ServerConnection&&) noexcept;

  // Connects, and with tls.enabled completes the TLS handshake, within `timeout`. Errors name the
  // address (and for TLS what failed: the handshake, or why the certificate was not trusted). An
  // untrusted certificate or an unreadable tls.ca_file is kInvalidArgument: trying again will not help.
  static Result<ServerConnection> open(const std::string& host, std::uint16_t port,
                                       std::chrono::milliseconds timeout = std::chrono::seconds(5),
                                       const TlsOptions& tls = {});

  // Sends one request frame. `id` is the request id.
  Status send(const protocol::Request& request, std::uint64_t id);
  // Sends raw bytes (tests send malformed frames this way).
  Status send_raw(const std::vector<std::uint8_t>& bytes);
  // Reads the next reply frame; fails on a closed connection, a timeout or a broken frame.
  Result<ReplyFrame> receive(std::chrono::milliseconds timeout = std::chrono::seconds(30));
  // Sends and waits for the reply with that id (replies come in request order).
  Result<ReplyFrame> call(const protocol::Request& request, std::uint64_t id,
                          std::chrono::milliseconds timeout = std::chrono::seconds(30));
  void close();
  // From another thread: shuts the socket down so that a receive() blocked in it returns an error.
  // send() and receive() may run on two threads at once; interrupt() ends both.
  void interrupt();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mtlod::clients

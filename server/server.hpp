// mtlod-server's shell (core/ARCHITECTURE.md §5.1): a Boost.Asio TCP listener, one session per
// connection, a worker pool for extractions, limits, metrics and graceful shutdown. Asio stays in
// server.cpp; this header is light.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "protocol/messages.hpp"
#include "server/engine.hpp"
#include "server/metrics.hpp"

namespace mtlod::server {

class TokenTable;

struct ServerConfig {
  std::string host = "127.0.0.1";
  std::uint16_t port = 7878;                // 0: let the OS choose (see Server::port)
  unsigned io_threads = 1;                  // socket threads
  unsigned workers = 0;                     // extraction threads; 0 = one per core
  std::uint32_t drain_timeout_ms = 10'000;  // on SIGINT/SIGTERM: in-flight work must finish by then
  protocol::Limits limits;
  // The browser viewer over HTTP + WebSocket (server/web_session.hpp); off when empty, 0 = any port.
  std::optional<std::uint16_t> http_port;
  std::string web_root;  // repository root holding clients/web and scripts/node_modules/three
  // This process in hello replies and /health: "<name>@<random hex>" (see instance_id()).
  std::string instance = "mtlod";
  // TLS on both listeners, from PEM files (server/tls.hpp); plain TCP and HTTP when both are empty.
  std::string tls_cert_file, tls_key_file;
  // Networks of trusted load balancers (--proxy-protocol-from; CIDRs, server/proxy_accept.hpp): a
  // connection from one must open with a PROXY protocol v2 header, and the client address in it
  // stands for the connection. Empty: no header is read and every peer is its own client.
  std::vector<std::string> proxy_protocol_from;
  // Access tokens (server/auth.hpp): when set, a connection is served only once it has shown a
  // valid token, and sees only its token's models.
  std::shared_ptr<const TokenTable> tokens;
  // Tokens that may send `reload` (mtlod-server --admin-tokens); without them `reload` is refused.
  std::shared_ptr<const TokenTable> admin_tokens;
  // Load changed model files when they change (inotify); off: on SIGHUP or `reload` only.
  bool watch_models = true;
  // Scenes an extract may name ("scene": "room"; mtlod-server --scene), by name.
  std::map<std::string, std::vector<protocol::Instance>, std::less<>> scenes;
};

// "<name>@<8 hex digits>", random per call: a replica's identity for this run.
std::string instance_id(const std::string& name);

class Server {
 public:
  // The server reloads `models` when their files change, on SIGHUP and on `reload` (model_watch.hpp).
  Server(ServerConfig config, ModelRegistry& models);
  ~Server();

  // Loads the TLS certificate and key when configured, binds and listens; errors name the file or
  // the address.
  Status listen();
  // The bound port (useful with port 0).
  std::uint16_t port() const;
  // The bound HTTP port, 0 when HTTP is off.
  std::uint16_t http_port() const;
  // Serves until stop() or SIGINT/SIGTERM has drained every connection. SIGHUP reloads the models.
  void run();
  // Starts a graceful shutdown: stop accepting, answer queued work `shutting_down`, finish running
  // extractions, write their replies, close. Safe from any thread.
  void stop();

  const Metrics& metrics() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mtlod::server

// Browser transport (core/ARCHITECTURE.md §4): one HTTP port that serves the viewer's static
// files (clients/web/ and three.js from scripts/node_modules/three) and upgrades `GET /ws` to a
// WebSocket carrying the protocol (PROTOCOL.md, first paragraph). A WebSocket connection is a
// server::Connection like a TCP one, so ordering, coalescing, limits and drain are shared. Beast
// stays in web_session.cpp.
#pragma once

#include <boost/asio/any_io_executor.hpp>
#include <boost/asio/io_context.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "core/result.hpp"
#include "server/connection.hpp"

namespace boost::asio::ssl {
class context;
}

namespace mtlod::server {

class ProxyGate;

// The files served over HTTP:
//   /              → <root>/clients/web/index.html
//   /<name>        → <root>/clients/web/<name>
//   /three/<path>  → <root>/scripts/node_modules/three/<path>, only under build/ and examples/jsm/
//   /health        → 200, JSON: status, instance, models, connections
//   /ws            → WebSocket upgrade; with access tokens, only for a valid token (else 401)
struct WebConfig {
  std::filesystem::path root;  // the repository root (or an install with the same two folders)
  // HTTPS and wss only, with this context (server/tls.hpp); plain HTTP when null.
  boost::asio::ssl::context* tls = nullptr;
  // PROXY protocol v2 headers from trusted balancers (server/proxy_accept.hpp); none read when null.
  ProxyGate* proxies = nullptr;
};

// What the server lends the web listener for WebSocket connections.
struct WebHooks {
  std::function<std::uint64_t()> next_number;                     // connection numbers shared with TCP
  std::function<void(const std::shared_ptr<Connection>&)> track;  // drained on shutdown
};

class WebServer {
 public:
  // Accepts on `control` (the server's listener strand); sessions get strands of `ioc`.
  WebServer(boost::asio::io_context& ioc, boost::asio::any_io_executor control, WebConfig config);
  ~WebServer();

  // Binds host:port (0: any free port); errors name the address.
  Status listen(const std::string& host, std::uint16_t port);
  std::uint16_t port() const;
  // Starts accepting; `context` must outlive the server's run.
  void start(ServerContext& context, WebHooks hooks);
  // Stops accepting and closes plain HTTP sessions; WebSocket connections drain like TCP ones.
  // Call on the server's control strand.
  void stop();

  struct Impl;  // defined in web_session.cpp, shared with the HTTP sessions

 private:
  std::shared_ptr<Impl> impl_;
};

}  // namespace mtlod::server

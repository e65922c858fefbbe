// The browser transport (see web_session.hpp), after Beast's example/advanced/server and
// advanced_server_flex: an HTTP session per accepted socket (plain or TLS) serves files and, on
// `GET /ws` with an upgrade, hands its stream to a WebSocket session. Text messages are JSON
// requests; binary messages hold a whole frame (header included). Replies without payload go out
// as text, mesh replies as binary whole frames. Sessions are templates over their stream, so plain
// and TLS connections share every line but the handshake.
#include "server/web_session.hpp"

#include <boost/asio/dispatch.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/strand.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/beast/websocket/ssl.hpp>

#include <atomic>
#include <cassert>
#include <chrono>
#include <list>
#include <mutex>
#include <optional>
#include <type_traits>

#include "fmt/format.h"
#include "protocol/frame.hpp"
#include "protocol/text.hpp"
#include "server/auth.hpp"
#include "server/proxy_accept.hpp"
#include "spdlog/spdlog.h"

namespace mtlod::server {
namespace {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace ssl = net::ssl;
using tcp = net::ip::tcp;
using TlsStream = beast::ssl_stream<beast::tcp_stream>;
using boost::system::error_code;
using Request = http::request<http::string_body>;

constexpr auto kWebSocketHandshake = std::chrono::seconds(10);  // opening and closing handshakes
constexpr std::size_t kHttpRequestMaxBytes = 16 * 1024;         // the viewer only sends small GETs
// How long a closing HTTP connection keeps reading what its client still sends (see
// HttpSession::linger_then_close), as web servers' lingering close does.
constexpr auto kHttpLinger = std::chrono::seconds(2);

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

const char* content_type(const std::filesystem::path& path) {
  const std::string ext = path.extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js" || ext == ".mjs") return "text/javascript; charset=utf-8";
  if (ext == ".wasm") return "application/wasm";  // WebAssembly.instantiateStreaming insists on it
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".json") return "application/json";
  if (ext == ".csv" || ext == ".txt" || ext == ".md") return "text/plain; charset=utf-8";
  if (ext == ".png") return "image/png";
  return "application/octet-stream";
}

// The file a request target names, or nullopt. Only plain names are served: no escapes, no "..",
// nothing outside the two folders.
std::optional<std::filesystem::path> resolve_target(std::string_view target,
                                                    const std::filesystem::path& root) {
  if (const std::size_t query = target.find('?'); query != std::string_view::npos)
    target = target.substr(0, query);
  if (target.empty() || target.front() != '/') return std::nullopt;
  for (const char c : target) {
    const bool plain = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                       c == '-' || c == '_' || c == '.' || c == '/';
    if (!plain) return std::nullopt;
  }
  if (target.find("..") != std::string_view::npos || target.find("//") != std::string_view::npos)
    return std::nullopt;
  if (target == "/") return root / "clients/web/index.html";
  constexpr std::string_view kThree = "/three/";
  if (target.starts_with(kThree)) {
    const std::string_view rest = target.substr(kThree.size());
    if (!rest.starts_with("build/") && !rest.starts_with("examples/jsm/")) return std::nullopt;
    return root / "scripts/node_modules/three" / std::string(rest);
  }
  return root / "clients/web" / std::string(target.substr(1));
}

// The access token a WebSocket upgrade shows: `Authorization: Bearer TOKEN`, else the `token`
// parameter of its query (browsers cannot set headers on a WebSocket). Tokens are made of
// characters a URL carries as they are, so the value is taken without decoding.
std::string_view upgrade_token(const Request& request) {
  const auto field = request[http::field::authorization];
  const std::string_view authorization(field.data(), field.size());
  constexpr std::string_view kBearer = "Bearer ";
  if (authorization.starts_with(kBearer)) return authorization.substr(kBearer.size());
  std::string_view target(request.target().data(), request.target().size());
  const std::size_t query = target.find('?');
  if (query == std::string_view::npos) return {};
  for (std::string_view rest = target.substr(query + 1); !rest.empty();) {
    const std::size_t end = std::min(rest.find('&'), rest.size());
    const std::string_view pair = rest.substr(0, end);
    if (pair.starts_with("token=")) return pair.substr(6);
    rest = rest.substr(std::min(end + 1, rest.size()));
  }
  return {};
}

// ---- WebSocket: a Connection whose frames are WebSocket messages ----

// NextLayer: beast::tcp_stream, or TlsStream for wss.
template <class NextLayer>
class WebSocketSession final : public Connection {
 public:
  WebSocketSession(ServerContext& server, NextLayer stream, std::uint64_t number, AddressTable::Slot slot)
      : Connection(server, stream.get_executor(), number, std::move(slot)),
        ws_(std::move(stream)),
        deadline_(ws_.get_executor()) {}

  // Answers the upgrade request (already read by the HTTP session, its token already checked into
  // `grant`) and starts reading.
  void start(Request request, const Grant* grant) {
    request_ = std::move(request);
    net::dispatch(strand(), [self = shared_self(), grant] {
      self->opened();
      self->authorise(grant);
      auto& ws = self->ws_;
      beast::get_lowest_layer(ws).expires_never();  // the WebSocket's own timeouts apply instead
      ws.set_option(
          websocket::stream_base::timeout{kWebSocketHandshake, websocket::stream_base::none(), false});
      ws.set_option(websocket::stream_base::decorator(
          [](websocket::response_type& response) { response.set(http::field::server, "mtlod/0.1"); }));
      // A binary message holds a whole frame: the header comes on top of the frame limit.
      ws.read_message_max(std::size_t{self->server_.config.limits.max_frame_bytes} +
                          protocol::kFrameHeaderBytes);
      ws.async_accept(self->request_, [self](error_code ec) {
        self->guarded("websocket handshake", [&] { self->on_accept(ec); });
      });
    });
  }

 private:
  std::shared_ptr<WebSocketSession> shared_self() {
    return std::static_pointer_cast<WebSocketSession>(shared_from_this());
  }

  void on_accept(error_code ec) {
    request_ = {};
    if (ec) {
      spdlog::debug("conn={} websocket handshake failed: {}", number(), ec.message());
      read_failed_ = true;
      return on_read_end();
    }
    do_read();
  }

  void do_read() {
    if (!may_read()) return;
    reading_ = true;
    arm_idle_deadline();
    ws_.async_read(buffer_, [self = shared_self()](error_code ec, std::size_t n) {
      self->guarded("websocket read", [&] { self->on_read(ec, n); });
    });
  }

  void on_read(error_code ec, std::size_t n) {
    reading_ = false;
    if (ec) {
      read_failed_ = true;
      if (ec != websocket::error::closed && ec != net::error::eof && ec != net::error::operation_aborted &&
          ec != ssl::error::stream_truncated) {
        spdlog::debug("conn={} websocket read failed: {}", number(), ec.message());
      }
      return on_read_end();
    }
    server_.metrics.bytes_in(n);
    if (ending()) return buffer_.clear();  // draining: nothing new is taken
    const auto data = buffer_.cdata();
    const bool more =
        handle_message(ws_.got_text(), {static_cast<const char*>(data.data()), data.size()}, now_ns());
    buffer_.clear();
    if (more) do_read();
  }

  void arm_idle_deadline() {
    // Until its first message a connection gets the short first-frame deadline, as over TCP.
    const auto& limits = server_.config.limits;
    deadline_.expires_after(
        std::chrono::milliseconds(got_request() ? limits.idle_timeout_ms : limits.first_frame_timeout_ms));
    deadline_.async_wait([self = shared_self()](error_code ec) {
      if (ec || !self->reading_) return;  // cancelled, or a message has arrived since
      if (self->waiting_on_server()) return self->arm_idle_deadline();  // not idle: we owe replies
      spdlog::info("conn={} closed: {} timeout", self->number(),
                   self->got_request() ? "idle" : "first frame");
      self->force_close();
    });
  }

  void write_frame(std::vector<std::uint8_t>& frame) override {
    assert(frame.size() >= protocol::kFrameHeaderBytes);
    const auto header = protocol::decode_frame_header(
        std::span<const std::uint8_t, protocol::kFrameHeaderBytes>(frame.data(), protocol::kFrameHeaderBytes),
        frame.size());
    const bool has_payload = header.ok() && header->payload_bytes > 0;
    write_pending_ = true;
    auto done = [self = shared_self()](error_code ec, std::size_t n) {
      self->write_pending_ = false;
      if (ec) spdlog::debug("conn={} websocket write failed: {}", self->number(), ec.message());
      self->guarded("websocket write", [&] { self->on_written(!ec, n); });
    };
    if (has_payload) {
      ws_.binary(true);
      ws_.async_write(net::buffer(frame), std::move(done));
    } else {
      // JSON only: a text message without the frame header.
      ws_.text(true);
      ws_.async_write(
          net::buffer(frame.data() + protocol::kFrameHeaderBytes, frame.size() - protocol::kFrameHeaderBytes),
          std::move(done));
    }
  }
  // A WebSocket cannot half-close its reading side without failing the stream, which would lose the
  // replies still owed. The pending read stays; on_read drops what arrives while ending, and the
  // connection closes once its replies are written.
  void stop_reading() override {}
  void resume_reading() override { do_read(); }
  void close_transport() override {
    deadline_.cancel();
    if (closing_) return;
    closing_ = true;
    if (write_pending_ || read_failed_ || !ws_.is_open()) return close_socket();
    // A close handshake when the stream is idle, bounded by the handshake timeout.
    ws_.async_close(websocket::close_code::normal,
                    [self = shared_self()](error_code) { self->close_socket(); });
  }
  void close_socket() {
    error_code ignored;
    auto& socket = beast::get_lowest_layer(ws_).socket();
    socket.shutdown(tcp::socket::shutdown_both, ignored);
    socket.close(ignored);
  }

  websocket::stream<NextLayer> ws_;
  net::steady_timer deadline_;
  beast::flat_buffer buffer_;
  Request request_;
  bool reading_ = false;
  bool write_pending_ = false;
  bool read_failed_ = false;
  bool closing_ = false;
};

}  // namespace

// ---- HTTP ----

// What the listener needs of an HTTP session of either kind: closing it on shutdown.
class HttpSessionBase {
 public:
  virtual ~HttpSessionBase() = default;
  // From any thread: ends the session (server shutdown).
  virtual void close() = 0;
};

struct WebServer::Impl : std::enable_shared_from_this<WebServer::Impl> {
  Impl(boost::asio::io_context& i, net::any_io_executor control, WebConfig c)
      : ioc(i), config(std::move(c)), acceptor(std::move(control)) {}

  void accept();
  // A slot for a new HTTP connection from `address` (the socket's, or its PROXY header's), or an
  // empty one after refusing it with 503.
  AddressTable::Slot acquire(tcp::socket& socket, const std::string& address);
  // Starts an HTTP session on an admitted socket.
  void serve(tcp::socket socket, AddressTable::Slot slot);
  // Whether another WebSocket connection fits under max_connections.
  bool admit() const {
    if (context->metrics.open_connections() < context->config.limits.max_connections) return true;
    context->metrics.connection_refused();
    return false;
  }
  // Hands an HTTP session's stream, its upgrade request already read, to a new WebSocket session.
  template <class Stream>
  void upgrade(Stream stream, Request request, AddressTable::Slot slot, const Grant* grant);

  boost::asio::io_context& ioc;
  WebConfig config;
  tcp::acceptor acceptor;
  ServerContext* context = nullptr;
  WebHooks hooks;
  std::atomic<bool> stopping{false};
  std::mutex sessions_mutex;
  std::list<std::weak_ptr<HttpSessionBase>> sessions;
};

// Stream: beast::tcp_stream, or TlsStream for https.
template <class Stream>
class HttpSession : public HttpSessionBase, public std::enable_shared_from_this<HttpSession<Stream>> {
 public:
  static constexpr bool kTls = std::is_same_v<Stream, TlsStream>;

  template <class... TlsContext>
  HttpSession(tcp::socket socket, std::shared_ptr<WebServer::Impl> server, AddressTable::Slot slot,
              TlsContext&... tls)
      : executor_(socket.get_executor()),
        stream_(std::move(socket), tls...),
        server_(std::move(server)),
        slot_(std::move(slot)) {}

  void start() {
    net::dispatch(executor_, [self = this->shared_from_this()] {
      if constexpr (kTls) {
        self->do_handshake();
      } else {
        self->do_read();
      }
    });
  }
  void close() override {
    net::post(executor_, [self = this->shared_from_this()] { self->close_socket(); });
  }

 private:
  beast::tcp_stream& tcp() { return beast::get_lowest_layer(stream_); }

  // HTTPS only: the handshake must end within the first-frame deadline, as the first request must.
  void do_handshake() {
    tcp().expires_after(std::chrono::milliseconds(server_->context->config.limits.first_frame_timeout_ms));
    stream_.async_handshake(ssl::stream_base::server, [self = this->shared_from_this()](error_code ec) {
      if (ec) {
        spdlog::debug("https from {}: TLS handshake failed: {}", self->slot_.address(), ec.message());
        return self->close_socket();
      }
      self->do_read();
    });
  }

  void do_read() {
    parser_.emplace();
    parser_->header_limit(kHttpRequestMaxBytes);
    parser_->body_limit(kHttpRequestMaxBytes);
    // Each request must arrive within the first-frame deadline: idle sockets hold no slot for long.
    tcp().expires_after(std::chrono::milliseconds(server_->context->config.limits.first_frame_timeout_ms));
    http::async_read(
        stream_, buffer_, *parser_, [self = this->shared_from_this()](error_code ec, std::size_t) {
          // As for protocol connections: a throw while answering ends this HTTP
          // connection only.
          try {
            self->on_read(ec);
          } catch (const std::exception& e) {
            spdlog::error("http request failed: {}; closing the connection", protocol::printable(e.what()));
            self->close_socket();
          }
        });
  }

  void on_read(error_code ec) {
    if (ec == http::error::end_of_stream) return close_socket();
    if (ec) {
      if (ec != net::error::operation_aborted && ec != beast::error::timeout &&
          ec != ssl::error::stream_truncated) {
        spdlog::debug("http read failed: {}", ec.message());
        // A request that does not parse ends the connection, and what the client pipelined
        // behind it is unread: the responses before it must still arrive whole.
        return linger_then_close();
      }
      return close_socket();
    }
    Request request = parser_->release();
    if (websocket::is_upgrade(request)) {
      // A refused upgrade ends the connection: the client wanted a WebSocket, not more HTTP.
      auto refuse = [&](http::status status, std::string text) {
        auto response = text_response(request, status, std::move(text));
        response.keep_alive(false);
        if (status == http::status::unauthorized) response.set(http::field::www_authenticate, "Bearer");
        send(std::move(response));
      };
      const std::string_view target(request.target().data(), request.target().size());
      if (target.substr(0, target.find('?')) != "/ws")
        return refuse(http::status::not_found, "WebSocket endpoint is /ws\n");
      if (server_->stopping) return refuse(http::status::service_unavailable, "shutting down\n");
      const Grant* grant = nullptr;
      if (const TokenTable* tokens = server_->context->config.tokens.get()) {
        const std::string_view token = upgrade_token(request);
        grant = tokens->find(token);
        if (!grant) {
          server_->context->metrics.error(protocol::ErrorKind::kUnauthorized);
          spdlog::info("http from {}: WebSocket upgrade refused: {}", slot_.address(),
                       token.empty() ? "no token" : "a token that is not valid");
          return refuse(http::status::unauthorized,
                        "a valid access token is needed: /ws?token=TOKEN or Authorization: Bearer TOKEN\n");
        }
      }
      if (!server_->admit()) {
        return refuse(http::status::service_unavailable,
                      fmt::format("the server has {} connections, its limit\n",
                                  server_->context->config.limits.max_connections));
      }
      tcp().expires_never();
      upgraded_ = true;
      return server_->upgrade(std::move(stream_), std::move(request), std::move(slot_), grant);
    }
    respond(request);
  }

  void respond(const Request& request) {
    if (request.method() != http::verb::get) {
      return send(text_response(request, http::status::method_not_allowed, "only GET is served\n"));
    }
    const std::string_view target(request.target().data(), request.target().size());
    if (target == "/health") {
      // For load balancers and orchestrators: this replica serves. While it drains, the HTTP
      // listener is closed, so probes fail to connect and traffic moves elsewhere. It needs no
      // token: probes carry none, and it tells nothing about the models' contents.
      const ServerContext& context = *server_->context;
      auto response =
          text_response(request, http::status::ok,
                        fmt::format(R"({{"status": "ok", "instance": "{}", "models": {}, "connections": {}}})"
                                    "\n",
                                    context.config.instance, context.models.models().size(),
                                    context.metrics.open_connections()));
      response.set(http::field::content_type, "application/json");
      return send(std::move(response));
    }
    if (target == "/metrics") {
      // Prometheus scrapes this, with no token as /health: counts and timings only, no model names.
      const ServerContext& context = *server_->context;
      MetricsGauges gauges;
      gauges.memory_held_bytes = context.memory.held();
      gauges.memory_limit_bytes = context.memory.limit();
      gauges.models = context.models.models().size();
      for (const auto& model : context.models.models()) {
        gauges.model_bytes += model->memory_bytes;
        gauges.model_mapped_bytes += model->mt.mapped_bytes();
        if (!context.config.tokens) gauges.model_versions.emplace_back(model->name, model->version);
      }
      gauges.model_reloads = context.models.reloads();
      auto response = text_response(request, http::status::ok, context.metrics.prometheus_text(gauges));
      response.set(http::field::content_type, "text/plain; version=0.0.4; charset=utf-8");
      return send(std::move(response));
    }
    const auto path = resolve_target(target, server_->config.root);
    std::error_code missing;
    if (!path || !std::filesystem::is_regular_file(*path, missing)) {
      return send(text_response(request, http::status::not_found,
                                fmt::format("{} not found\n", protocol::printable(target))));
    }
    error_code ec;
    http::file_body::value_type body;
    body.open(path->c_str(), beast::file_mode::scan, ec);
    if (ec) return send(text_response(request, http::status::internal_server_error, ec.message() + "\n"));
    const std::uint64_t size = body.size();
    http::response<http::file_body> response{std::piecewise_construct, std::make_tuple(std::move(body)),
                                             std::make_tuple(http::status::ok, request.version())};
    response.set(http::field::server, "mtlod/0.1");
    response.set(http::field::content_type, content_type(*path));
    response.set(http::field::cache_control, "no-cache");
    response.content_length(size);
    response.keep_alive(request.keep_alive());
    send(std::move(response));
  }

  static http::response<http::string_body> text_response(const Request& request, http::status status,
                                                         std::string text) {
    http::response<http::string_body> response{status, request.version()};
    response.set(http::field::server, "mtlod/0.1");
    response.set(http::field::content_type, "text/plain; charset=utf-8");
    response.keep_alive(request.keep_alive());
    response.body() = std::move(text);
    response.prepare_payload();
    return response;
  }

  template <class Body>
  void send(http::response<Body>&& response) {
    auto message = std::make_shared<http::response<Body>>(std::move(response));
    http::async_write(stream_, *message,
                      [self = this->shared_from_this(), message](error_code ec, std::size_t) {
                        if (ec) return self->close_socket();
                        if (!message->keep_alive()) return self->linger_then_close();
                        self->do_read();
                      });
  }

  // Ends the connection without losing the last response. A socket closed with input still unread
  // sends a reset, and the reset discards whatever of the response the client has not yet received
  // (a large file, say). So the sending side ends first (the client reads the response, then end
  // of stream), and what still arrives is read and dropped until the client closes or kHttpLinger
  // passes. Only with no read pending (not from close(), which a pending read may race).
  void linger_then_close() {
    error_code ignored;
    tcp().socket().shutdown(tcp::socket::shutdown_send, ignored);
    tcp().expires_after(kHttpLinger);
    drain();
  }
  void drain() {
    buffer_.clear();
    tcp().async_read_some(buffer_.prepare(4096),
                          [self = this->shared_from_this()](error_code ec, std::size_t) {
                            if (ec) return self->close_socket();
                            self->drain();
                          });
  }

  // No TLS close_notify: every response is written whole, and waiting on the peer's would hold the
  // socket for nothing.
  void close_socket() {
    if (upgraded_) return;  // the stream now belongs to the WebSocket session
    error_code ignored;
    tcp().socket().shutdown(tcp::socket::shutdown_both, ignored);
    tcp().close();
  }

  net::any_io_executor executor_;  // the stream's strand, kept apart: the stream moves on an upgrade
  Stream stream_;
  beast::flat_buffer buffer_;
  std::optional<http::request_parser<http::string_body>> parser_;
  std::shared_ptr<WebServer::Impl> server_;
  AddressTable::Slot slot_;  // moves to the WebSocket session on an upgrade
  bool upgraded_ = false;
};

void WebServer::Impl::accept() {
  acceptor.async_accept(
      net::make_strand(ioc), [self = shared_from_this()](error_code ec, tcp::socket socket) {
        if (ec) {
          if (ec != net::error::operation_aborted) spdlog::warn("http accept failed: {}", ec.message());
          if (!self->stopping && self->acceptor.is_open()) self->accept();
          return;
        }
        if (self->stopping) return;
        error_code ignored;
        socket.set_option(tcp::no_delay(true), ignored);  // as for TCP sessions: no Nagle delay on replies
        ProxyGate* proxies = self->config.proxies;
        if (proxies && proxies->trusted(socket)) {
          // The slot is the client's, so it is taken once the header has named the client.
          proxies->read_header(std::move(socket), "http", [self](tcp::socket socket, std::string address) {
            if (self->stopping) return;
            if (AddressTable::Slot slot = self->acquire(socket, address))
              self->serve(std::move(socket), std::move(slot));
          });
        } else if (AddressTable::Slot slot = self->acquire(socket, remote_address(socket))) {
          if (!proxies) {
            self->serve(std::move(socket), std::move(slot));
          } else {
            auto held = std::make_shared<AddressTable::Slot>(std::move(slot));
            proxies->screen(std::move(socket), "http", [self, held](tcp::socket socket, std::string) {
              if (!self->stopping) self->serve(std::move(socket), std::move(*held));
            });
          }
        }
        self->accept();
      });
}

AddressTable::Slot WebServer::Impl::acquire(tcp::socket& socket, const std::string& address) {
  AddressTable::Slot slot = context->addresses.acquire(address);
  if (!slot) {
    context->metrics.connection_refused();
    // Over TLS a plain-text answer would only break the client's handshake: just close.
    refuse_socket(std::move(socket), config.tls ? ""
                                                : "HTTP/1.1 503 Service Unavailable\r\n"
                                                  "Connection: close\r\nContent-Length: 0\r\n\r\n");
  }
  return slot;
}

void WebServer::Impl::serve(tcp::socket socket, AddressTable::Slot slot) {
  std::shared_ptr<HttpSessionBase> session;
  if (config.tls) {
    auto tls = std::make_shared<HttpSession<TlsStream>>(std::move(socket), shared_from_this(),
                                                        std::move(slot), *config.tls);
    tls->start();
    session = std::move(tls);
  } else {
    auto plain = std::make_shared<HttpSession<beast::tcp_stream>>(std::move(socket), shared_from_this(),
                                                                  std::move(slot));
    plain->start();
    session = std::move(plain);
  }
  {
    std::lock_guard lock(sessions_mutex);
    sessions.remove_if([](const std::weak_ptr<HttpSessionBase>& s) { return s.expired(); });
    sessions.push_back(session);
  }
  // A stop that began while a PROXY header was read (on the socket's strand) has not seen it.
  if (stopping) session->close();
}

template <class Stream>
void WebServer::Impl::upgrade(Stream stream, Request request, AddressTable::Slot slot, const Grant* grant) {
  auto session = std::make_shared<WebSocketSession<Stream>>(*context, std::move(stream), hooks.next_number(),
                                                            std::move(slot));
  hooks.track(session);
  session->start(std::move(request), grant);
  // A shutdown that began while this upgrade was on its way has not seen the connection.
  if (stopping) session->shutdown();
}

WebServer::WebServer(boost::asio::io_context& ioc, net::any_io_executor control, WebConfig config)
    : impl_(std::make_shared<Impl>(ioc, std::move(control), std::move(config))) {}

WebServer::~WebServer() = default;

Status WebServer::listen(const std::string& host, std::uint16_t port) {
  error_code ec;
  const auto address = net::ip::make_address(host, ec);
  if (ec)
    return make_error(ErrorCode::kInvalidArgument, fmt::format("bad host '{}': {}", host, ec.message()));
  const tcp::endpoint endpoint(address, port);
  auto& acceptor = impl_->acceptor;
  acceptor.open(endpoint.protocol(), ec);
  if (!ec) acceptor.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) acceptor.bind(endpoint, ec);
  if (!ec) acceptor.listen(net::socket_base::max_listen_connections, ec);
  if (ec)
    return make_error(ErrorCode::kIoError,
                      fmt::format("cannot listen for HTTP on {}:{}: {}", host, port, ec.message()));
  return Ok{};
}

std::uint16_t WebServer::port() const {
  error_code ec;
  return impl_->acceptor.local_endpoint(ec).port();
}

void WebServer::start(ServerContext& context, WebHooks hooks) {
  impl_->context = &context;
  impl_->hooks = std::move(hooks);
  impl_->accept();
}

void WebServer::stop() {
  if (impl_->stopping.exchange(true)) return;
  error_code ignored;
  impl_->acceptor.close(ignored);
  std::lock_guard lock(impl_->sessions_mutex);
  for (auto& weak : impl_->sessions) {
    if (auto session = weak.lock()) session->close();
  }
}

}  // namespace mtlod::server

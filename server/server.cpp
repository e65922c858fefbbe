// mtlod-server's network shell: the listener, the worker pool, signals and the drain. Connections
// (server/connection.*) hold the request logic; transports (server/tcp_session.*) move the bytes.
#include "server/server.hpp"

#include <boost/asio.hpp>

#include <atomic>
#include <chrono>
#include <list>
#include <mutex>
#include <random>
#include <thread>

#include "core/io/memory_limit.hpp"
#include "fmt/format.h"
#include "protocol/frame.hpp"
#include "protocol/replies.hpp"
#include "protocol/text.hpp"
#include "server/connection.hpp"
#include "server/model_watch.hpp"
#include "server/proxy_accept.hpp"
#include "server/tcp_session.hpp"
#include "server/tls.hpp"
#include "server/web_session.hpp"
#include "spdlog/spdlog.h"

namespace mtlod::server {
namespace {

namespace net = boost::asio;
using tcp = net::ip::tcp;
using boost::system::error_code;

}  // namespace

std::string instance_id(const std::string& name) {
  std::random_device entropy;
  return fmt::format("{}@{:08x}", name, entropy());
}

struct Server::Impl {
  ServerConfig config;
  ModelRegistry& models;
  Engine engine;
  Metrics metrics;
  net::io_context ioc;
  // Listener, signals and shutdown run on one strand, whatever the number of I/O threads.
  net::strand<net::io_context::executor_type> control{net::make_strand(ioc)};
  tcp::acceptor acceptor{control};
  std::unique_ptr<net::thread_pool> workers;
  std::unique_ptr<FairScheduler> scheduler;
  AddressTable addresses{config.limits.max_connections_per_address};
  MemoryCeiling memory{config.limits.max_memory_bytes};
  std::unique_ptr<ServerContext> context;
  net::signal_set signals{control, SIGINT, SIGTERM, SIGHUP};
  std::unique_ptr<ModelWatch> watch;  // from run() on
  net::steady_timer drain_timer{control};
  std::atomic<bool> stopping{false};
  std::atomic<std::uint64_t> next_connection{1};
  std::mutex connections_mutex;
  std::list<std::weak_ptr<Connection>> connections;
  std::unique_ptr<WebServer> web;          // HTTP + WebSocket, when config.http_port is set
  std::unique_ptr<net::ssl::context> tls;  // both listeners' TLS, when config names a certificate
  std::unique_ptr<ProxyGate> proxies;      // both listeners' PROXY headers, with --proxy-protocol-from

  Impl(ServerConfig c, ModelRegistry& m) : config(with_memory_limit(std::move(c))), models(m), engine(m) {}
  static ServerConfig with_memory_limit(ServerConfig c) {
    if (c.limits.max_memory_bytes == 0) c.limits.max_memory_bytes = core::io::default_memory_limit();
    return c;
  }

  void accept();
  void begin_stop();
  void wait_for_signals();
  // The new connection's address slot, or an empty one after refusing it with an error frame (over
  // the server's or its address's connection limit). `address`: the client's, the socket's own or
  // the one its PROXY header names.
  AddressTable::Slot admit(tcp::socket& socket, std::uint64_t number, const std::string& address);
  void start_session(tcp::socket socket, std::uint64_t number, AddressTable::Slot slot);
  void track(const std::shared_ptr<Connection>& connection) {
    std::lock_guard lock(connections_mutex);
    connections.remove_if([](const std::weak_ptr<Connection>& c) { return c.expired(); });
    connections.push_back(connection);
  }
  // Called by each connection as it closes: the last one during a shutdown ends the drain early.
  void on_connection_closed() {
    net::post(control, [this] {
      if (stopping && metrics.open_connections() == 0) drain_timer.cancel();
    });
  }
};

AddressTable::Slot Server::Impl::admit(tcp::socket& socket, std::uint64_t number,
                                       const std::string& address) {
  std::string why;
  AddressTable::Slot slot;
  if (metrics.open_connections() >= config.limits.max_connections) {
    why = fmt::format("the server has {} connections, its limit", config.limits.max_connections);
  } else if (!(slot = addresses.acquire(address))) {
    why = fmt::format("{} holds {} connections, the limit per client address", address,
                      config.limits.max_connections_per_address);
  } else {
    return slot;
  }
  metrics.connection_refused();
  spdlog::warn("conn={} from {} refused: {}", number, address, why);
  std::vector<std::uint8_t> frame;
  protocol::append_frame(
      protocol::to_json(protocol::ErrorReply{protocol::ErrorKind::kLimitExceeded, why}, std::nullopt), {},
      frame);
  // Over TLS the frame could only go out after a handshake, which a refused client is not worth:
  // it sees its connection close.
  refuse_socket(std::move(socket), tls ? std::string() : std::string(frame.begin(), frame.end()));
  return slot;
}

void Server::Impl::accept() {
  acceptor.async_accept(net::make_strand(ioc), [this](error_code ec, tcp::socket socket) {
    if (ec) {
      if (ec != net::error::operation_aborted) spdlog::warn("accept failed: {}", ec.message());
      if (!stopping && acceptor.is_open()) accept();
      return;
    }
    if (stopping) return;
    // Replies are written whole: without this, Nagle's algorithm meeting the client's delayed ACK
    // holds a reply back for up to 40 ms.
    error_code ignored;
    socket.set_option(tcp::no_delay(true), ignored);
    const std::uint64_t number = next_connection++;
    if (proxies && proxies->trusted(socket)) {
      // Admission waits for the header: the cap and the turns are the client's, not the balancer's.
      proxies->read_header(std::move(socket), fmt::format("conn={}", number),
                           [this, number](tcp::socket socket, std::string address) {
                             if (stopping) return;
                             if (AddressTable::Slot slot = admit(socket, number, address))
                               start_session(std::move(socket), number, std::move(slot));
                           });
    } else if (AddressTable::Slot slot = admit(socket, number, remote_address(socket))) {
      if (!proxies) {
        start_session(std::move(socket), number, std::move(slot));
      } else {
        // Admitted before its first bytes are looked at, so that idle sockets count against the cap
        // as they do without a balancer.
        auto held = std::make_shared<AddressTable::Slot>(std::move(slot));
        proxies->screen(std::move(socket), fmt::format("conn={}", number),
                        [this, number, held](tcp::socket socket, std::string) {
                          if (!stopping) start_session(std::move(socket), number, std::move(*held));
                        });
      }
    }
    accept();
  });
}

void Server::Impl::start_session(tcp::socket socket, std::uint64_t number, AddressTable::Slot slot) {
  auto connection = start_tcp_session(*context, std::move(socket), number, std::move(slot), tls.get());
  track(connection);
  // A drain that began while a PROXY header was read (on the socket's strand) has not seen it.
  if (stopping) connection->shutdown();
}

void Server::Impl::wait_for_signals() {
  signals.async_wait([this](error_code ec, int signal) {
    if (ec) return;
    if (signal == SIGHUP) {
      // The usual way to ask a daemon to read its files again: the models, not a shutdown.
      spdlog::info("SIGHUP: reloading the models from their files");
      watch->request_reload();
      return wait_for_signals();
    }
    spdlog::info("received signal {}", signal);
    begin_stop();
  });
}

void Server::Impl::begin_stop() {
  if (stopping.exchange(true)) return;
  spdlog::info("shutting down: no new connections, finishing in-flight work (at most {} ms)",
               config.drain_timeout_ms);
  error_code ignored;
  acceptor.close(ignored);
  signals.cancel(ignored);
  // Sockets still sending their PROXY header are no connections yet: they are closed here.
  if (proxies) proxies->stop();
  if (web) web->stop();  // before collecting connections: an upgrade in progress sees `stopping`
  std::vector<std::shared_ptr<Connection>> live;
  {
    std::lock_guard lock(connections_mutex);
    for (auto& weak : connections) {
      if (auto c = weak.lock()) live.push_back(std::move(c));
    }
  }
  for (auto& s : live) s->shutdown();
  if (live.empty()) return;
  drain_timer.expires_after(std::chrono::milliseconds(config.drain_timeout_ms));
  drain_timer.async_wait([this](error_code ec) {
    if (ec) return;
    spdlog::warn("drain timeout: closing the remaining connections");
    std::lock_guard lock(connections_mutex);
    for (auto& weak : connections) {
      if (auto c = weak.lock()) c->force_close();
    }
  });
}

Server::Server(ServerConfig config, ModelRegistry& models)
    : impl_(std::make_unique<Impl>(std::move(config), models)) {}

Server::~Server() {
  if (impl_->workers) impl_->workers->join();
}

Status Server::listen() {
  const ServerConfig& config = impl_->config;
  if (!config.tls_cert_file.empty() || !config.tls_key_file.empty()) {
    if (config.tls_cert_file.empty() || config.tls_key_file.empty())
      return make_error(ErrorCode::kInvalidArgument, "TLS needs both --tls-cert and --tls-key");
    MTLOD_TRY(impl_->tls, make_tls_context(config.tls_cert_file, config.tls_key_file));
  }
  if (!config.proxy_protocol_from.empty()) {
    MTLOD_TRY(TrustedNetworks networks, TrustedNetworks::parse(config.proxy_protocol_from));
    spdlog::info(
        "PROXY protocol v2 header required from {}: their connections are served as the client "
        "address it names",
        networks.to_string());
    // The header is the first thing a balancer sends: it gets the deadline of a first frame.
    impl_->proxies = std::make_unique<ProxyGate>(std::move(networks), config.limits.first_frame_timeout_ms,
                                                 impl_->metrics);
  }
  error_code ec;
  const auto address = net::ip::make_address(impl_->config.host, ec);
  if (ec)
    return make_error(ErrorCode::kInvalidArgument,
                      fmt::format("bad host '{}': {}", impl_->config.host, ec.message()));
  const tcp::endpoint endpoint(address, impl_->config.port);
  auto& acceptor = impl_->acceptor;
  acceptor.open(endpoint.protocol(), ec);
  if (!ec) acceptor.set_option(net::socket_base::reuse_address(true), ec);
  if (!ec) acceptor.bind(endpoint, ec);
  if (!ec) acceptor.listen(net::socket_base::max_listen_connections, ec);
  if (ec) {
    return make_error(ErrorCode::kIoError, fmt::format("cannot listen on {}:{}: {}", impl_->config.host,
                                                       impl_->config.port, ec.message()));
  }
  if (impl_->config.http_port) {
    impl_->web = std::make_unique<WebServer>(
        impl_->ioc, impl_->control,
        WebConfig{impl_->config.web_root, impl_->tls.get(), impl_->proxies.get()});
    MTLOD_RETURN_IF_ERROR(impl_->web->listen(impl_->config.host, *impl_->config.http_port));
  }
  return Ok{};
}

std::uint16_t Server::port() const {
  error_code ec;
  return impl_->acceptor.local_endpoint(ec).port();
}

std::uint16_t Server::http_port() const {
  return impl_->web ? impl_->web->port() : 0;
}

void Server::run() {
  Impl& s = *impl_;
  const unsigned workers =
      s.config.workers ? s.config.workers : std::max(1u, std::thread::hardware_concurrency());
  s.workers = std::make_unique<net::thread_pool>(workers);
  s.scheduler = std::make_unique<FairScheduler>(*s.workers, workers);
  s.context.reset(new ServerContext{s.config, s.models, s.engine, s.metrics, s.addresses, *s.scheduler,
                                    s.memory, [&s] { s.on_connection_closed(); }});
  s.watch = std::make_unique<ModelWatch>(s.models, ModelWatchOptions{s.config.watch_models});
  s.wait_for_signals();
  s.accept();
  if (s.web) {
    s.web->start(*s.context, WebHooks{[&s] { return s.next_connection++; },
                                      [&s](const std::shared_ptr<Connection>& c) { s.track(c); }});
  }
  // Handlers catch what they can throw; should one still escape, the I/O thread logs it and runs on
  // rather than ending the process with every client's connection.
  auto run_io = [&s] {
    for (;;) {
      try {
        s.ioc.run();
        return;
      } catch (const std::exception& e) {
        spdlog::error("an I/O handler failed: {}", protocol::printable(e.what()));
      } catch (...) {
        spdlog::error("an I/O handler failed with an unknown exception");
      }
    }
  };
  std::vector<std::thread> extra;
  for (unsigned i = 1; i < std::max(1u, s.config.io_threads); ++i) extra.emplace_back(run_io);
  run_io();
  for (auto& t : extra) t.join();
  s.workers->join();
  s.watch.reset();
}

void Server::stop() {
  net::post(impl_->control, [this] { impl_->begin_stop(); });
}

const Metrics& Server::metrics() const {
  return impl_->metrics;
}

}  // namespace mtlod::server

// The TCP transport (see tcp_session.hpp). Shaped after Beast's async examples: do_read/on_read,
// every error branch returns; a steady_timer enforces the idle and read timeouts. One template
// serves plain sockets and TLS streams: only the handshake and the socket under the stream differ.
#include "server/tcp_session.hpp"

#include <boost/asio/dispatch.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/ssl/error.hpp>
#include <boost/asio/ssl/stream.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/write.hpp>

#include <array>
#include <chrono>
#include <type_traits>

#include "protocol/frame.hpp"
#include "spdlog/spdlog.h"

namespace mtlod::server {
namespace {

namespace net = boost::asio;
namespace ssl = net::ssl;
using tcp = net::ip::tcp;
using boost::system::error_code;

// Stream: tcp::socket, or ssl::stream<tcp::socket> for TLS.
template <class Stream>
class TcpSession final : public Connection {
 public:
  static constexpr bool kTls = !std::is_same_v<Stream, tcp::socket>;

  TcpSession(ServerContext& server, Stream stream, std::uint64_t number, AddressTable::Slot slot)
      : Connection(server, stream.get_executor(), number, std::move(slot)),
        stream_(std::move(stream)),
        deadline_(stream_.get_executor()) {}

  void start() {
    net::dispatch(strand(), [self = shared_self()] {
      self->opened();
      if constexpr (kTls) {
        self->do_handshake();
      } else {
        self->do_read_header();
      }
    });
  }

 private:
  std::shared_ptr<TcpSession> shared_self() {
    return std::static_pointer_cast<TcpSession>(shared_from_this());
  }
  tcp::socket& socket() {
    if constexpr (kTls) {
      return stream_.next_layer();
    } else {
      return stream_;
    }
  }

  // TLS only. The handshake counts as the wait for the first frame: a client that never completes
  // it holds its connection slot no longer than one that connects and sends nothing.
  void do_handshake() {
    reading_ = true;
    arm_deadline(server_.config.limits.first_frame_timeout_ms, /*idle=*/true);
    stream_.async_handshake(ssl::stream_base::server, [self = shared_self()](error_code ec) {
      self->guarded("TLS handshake", [&] { self->on_handshake(ec); });
    });
  }

  void on_handshake(error_code ec) {
    reading_ = false;
    if (ec) {
      // A plain client, a port scanner or an untrusted certificate on the client's side: worth a
      // line when debugging, never a warning that anyone can trigger at will.
      spdlog::debug("conn={} from {}: TLS handshake failed: {}", number(), address(), ec.message());
      return on_read_end();
    }
    if (ending()) return on_read_end();
    do_read_header();
  }

  void do_read_header() {
    if (!may_read()) return;
    reading_ = true;
    // A connection that has sent nothing yet gets a short deadline: idle sockets must not hold the
    // connection slots of clients that would use them.
    const auto& limits = server_.config.limits;
    arm_deadline(got_request() ? limits.idle_timeout_ms : limits.first_frame_timeout_ms, /*idle=*/true);
    net::async_read(stream_, net::buffer(header_), [self = shared_self()](error_code ec, std::size_t) {
      self->guarded("read header", [&] { self->on_header(ec); });
    });
  }

  void on_header(error_code ec) {
    reading_ = false;
    if (ec) return end(ec, "read header");
    // Closed or draining while the header was on its way: read no further. (Reading on would also
    // arm a read deadline after close_transport cancelled it, and hold up a shutdown by that long.)
    if (ending()) return end(net::error::operation_aborted, "read header");
    const std::optional<protocol::FrameHeader> header = frame_header(header_);
    if (!header) return;
    body_.resize(header->body_bytes());
    json_bytes_ = header->json_bytes;
    reading_ = true;
    arm_deadline(server_.config.limits.read_timeout_ms, /*idle=*/false);
    net::async_read(stream_, net::buffer(body_), [self = shared_self()](error_code ec, std::size_t n) {
      self->guarded("read body", [&] { self->on_body(ec, n); });
    });
  }

  void on_body(error_code ec, std::size_t n) {
    reading_ = false;
    if (ec) return end(ec, "read body");
    server_.metrics.bytes_in(n);
    const auto received = std::chrono::steady_clock::now().time_since_epoch();
    handle_frame(std::string_view(reinterpret_cast<const char*>(body_.data()), json_bytes_),
                 std::chrono::duration_cast<std::chrono::nanoseconds>(received).count());
    do_read_header();
  }

  void end(error_code ec, const char* what) {
    // Clients that hang up without TLS's close_notify end with stream_truncated: as common as EOF.
    if (ec != net::error::eof && ec != net::error::operation_aborted && ec != net::error::connection_reset &&
        ec != ssl::error::stream_truncated) {
      spdlog::debug("conn={} {} failed: {}", number(), what, ec.message());
    }
    on_read_end();
  }

  void arm_deadline(std::uint32_t timeout_ms, bool idle) {
    if (ending()) return;  // nothing more is read, and a pending timer would keep the server alive
    deadline_.expires_after(std::chrono::milliseconds(timeout_ms));
    deadline_.async_wait([self = shared_self(), idle](error_code ec) {
      if (ec || !self->reading_) return;  // cancelled, or the read it guarded has completed
      if (idle && self->waiting_on_server()) {
        return self->arm_deadline(self->server_.config.limits.idle_timeout_ms,
                                  true);  // not idle: we owe replies
      }
      spdlog::info("conn={} closed: {} timeout", self->number(),
                   !idle                 ? "read"
                   : self->got_request() ? "idle"
                                         : "first frame");
      self->force_close();
    });
  }

  void write_frame(std::vector<std::uint8_t>& frame) override {
    net::async_write(stream_, net::buffer(frame), [self = shared_self()](error_code ec, std::size_t n) {
      if (ec) spdlog::debug("conn={} write failed: {}", self->number(), ec.message());
      self->guarded("write", [&] { self->on_written(!ec, n); });
    });
  }
  // Over TLS too the socket's receiving side is shut: the pending read ends (stream_truncated), and
  // replies still go out, as Asio's TLS engine never saw an end of stream to fail on.
  void stop_reading() override {
    error_code ignored;
    socket().shutdown(tcp::socket::shutdown_receive, ignored);  // completes the pending read with EOF
  }
  void resume_reading() override { do_read_header(); }
  // No TLS close_notify: it would wait on the peer, and every reply owed has been written whole.
  // With no read pending (after a bad frame, or once the client has ended its side) the socket
  // lingers: its sending side ends, and what the client still sends is read and dropped until it
  // closes or kLinger passes. Closed with input unread, it would send a reset, and a reset discards
  // whatever of the replies the client has not yet received.
  void close_transport() override {
    deadline_.cancel();
    if (reading_ || !socket().is_open()) return close_socket();
    error_code ignored;
    socket().shutdown(tcp::socket::shutdown_send, ignored);
    deadline_.expires_after(kLinger);
    deadline_.async_wait([self = shared_self()](error_code ec) {
      if (!ec) self->close_socket();  // the pending drain ends with it
    });
    drain();
  }
  void drain() {
    socket().async_read_some(net::buffer(drained_), [self = shared_self()](error_code ec, std::size_t) {
      if (!ec) return self->drain();
      self->deadline_.cancel();
      self->close_socket();
    });
  }
  void close_socket() {
    error_code ignored;
    socket().shutdown(tcp::socket::shutdown_both, ignored);
    socket().close(ignored);
  }

  // How long a closing connection keeps reading what its client still sends (close_transport).
  static constexpr auto kLinger = std::chrono::seconds(2);

  Stream stream_;
  net::steady_timer deadline_;
  std::array<std::uint8_t, 4096> drained_;
  std::array<std::uint8_t, protocol::kFrameHeaderBytes> header_{};
  std::vector<std::uint8_t> body_;
  std::uint32_t json_bytes_ = 0;
  bool reading_ = false;
};

}  // namespace

std::shared_ptr<Connection> start_tcp_session(ServerContext& server, tcp::socket socket, std::uint64_t number,
                                              AddressTable::Slot slot, ssl::context* tls) {
  if (tls) {
    using Session = TcpSession<ssl::stream<tcp::socket>>;
    auto session = std::make_shared<Session>(server, ssl::stream<tcp::socket>(std::move(socket), *tls),
                                             number, std::move(slot));
    session->start();
    return session;
  }
  auto session =
      std::make_shared<TcpSession<tcp::socket>>(server, std::move(socket), number, std::move(slot));
  session->start();
  return session;
}

}  // namespace mtlod::server

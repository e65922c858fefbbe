// Blocking client connection (see server_connection.hpp). Plain POSIX sockets with poll() for timeouts:
// a command-line client needs neither an event loop nor threads. TLS runs OpenSSL on the same
// non-blocking socket: each OpenSSL call returns at once, asking to wait for the socket to become
// readable or writable, and the wait is the plain path's poll() with its deadline.
#include "clients/common/server_connection.hpp"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <openssl/x509v3.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <mutex>

#include "fmt/format.h"
#include "protocol/frame.hpp"
#include "protocol/parse.hpp"

namespace mtlod::clients {
namespace {

struct TlsFree {
  void operator()(SSL_CTX* context) const { ::SSL_CTX_free(context); }
  void operator()(SSL* ssl) const { ::SSL_free(ssl); }
};

// What one read or write on the socket did.
struct Transfer {
  enum Outcome { kDone, kWaitRead, kWaitWrite, kClosed, kFailed } outcome;
  std::size_t bytes = 0;
  std::string error;  // kFailed

  static Transfer of(Outcome outcome, std::size_t bytes = 0) { return {outcome, bytes, {}}; }
  static Transfer failed(std::string why) { return {kFailed, 0, std::move(why)}; }
};

// OpenSSL's most recent error as text, or `fallback` when it left none.
std::string tls_error(const char* fallback) {
  const unsigned long code = ::ERR_get_error();
  if (code == 0) return fallback;
  char text[256];
  ::ERR_error_string_n(code, text, sizeof text);
  return text;
}

// OpenSSL writes with write(2), which raises SIGPIPE when the server has gone (the plain path sends
// with MSG_NOSIGNAL instead). For the duration of one OpenSSL call the signal is blocked in this
// thread and one it raised is discarded, leaving the process's handlers as they were.
class SigpipeBlock {
 public:
  SigpipeBlock() {
    ::sigemptyset(&pipe_);
    ::sigaddset(&pipe_, SIGPIPE);
    sigset_t pending;
    ::sigpending(&pending);
    was_pending_ = ::sigismember(&pending, SIGPIPE) == 1;
    ::pthread_sigmask(SIG_BLOCK, &pipe_, &previous_);
  }
  ~SigpipeBlock() {
    sigset_t pending;
    ::sigpending(&pending);
    if (!was_pending_ && ::sigismember(&pending, SIGPIPE) == 1) {
      const timespec now{0, 0};
      ::sigtimedwait(&pipe_, nullptr, &now);
    }
    ::pthread_sigmask(SIG_SETMASK, &previous_, nullptr);
  }
  SigpipeBlock(const SigpipeBlock&) = delete;
  SigpipeBlock& operator=(const SigpipeBlock&) = delete;

 private:
  sigset_t pipe_, previous_;
  bool was_pending_ = false;
};

// Waits until fd is ready for `events` or the deadline passes.
bool wait_for(int fd, short events, std::chrono::steady_clock::time_point deadline) {
  for (;;) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    if (left.count() <= 0) return false;
    pollfd p{fd, events, 0};
    const int r = ::poll(&p, 1, static_cast<int>(left.count()));
    if (r > 0) return true;
    if (r < 0 && errno != EINTR) return false;
  }
}

}  // namespace

struct ServerConnection::Impl {
  int fd = -1;
  std::string peer;
  std::unique_ptr<SSL_CTX, TlsFree> tls_context;
  std::unique_ptr<SSL, TlsFree> tls;  // null: plain TCP
  // OpenSSL takes one call at a time on a connection, and send() and receive() may run on two
  // threads: each call holds this, and the waits between calls do not.
  std::mutex tls_mutex;

  ~Impl() {
    tls.reset();
    if (fd >= 0) ::close(fd);
  }

  Transfer read_some(std::uint8_t* out, std::size_t size) {
    if (!tls) {
      const ssize_t n = ::recv(fd, out, size, 0);
      if (n > 0) return Transfer::of(Transfer::kDone, static_cast<std::size_t>(n));
      if (n == 0) return Transfer::of(Transfer::kClosed);
      if (errno == EAGAIN || errno == EINTR) return Transfer::of(Transfer::kWaitRead);
      return Transfer::failed(std::strerror(errno));
    }
    std::lock_guard lock(tls_mutex);
    SigpipeBlock no_sigpipe;
    ::ERR_clear_error();
    errno = 0;
    const int n = ::SSL_read(tls.get(), out, static_cast<int>(std::min<std::size_t>(size, INT32_MAX)));
    return tls_outcome(n);
  }

  Transfer write_some(const std::uint8_t* data, std::size_t size) {
    if (!tls) {
      const ssize_t n = ::send(fd, data, size, MSG_NOSIGNAL);
      if (n > 0) return Transfer::of(Transfer::kDone, static_cast<std::size_t>(n));
      if (n < 0 && (errno == EAGAIN || errno == EINTR)) return Transfer::of(Transfer::kWaitWrite);
      return Transfer::failed(std::strerror(errno));
    }
    std::lock_guard lock(tls_mutex);
    SigpipeBlock no_sigpipe;
    ::ERR_clear_error();
    errno = 0;
    const int n = ::SSL_write(tls.get(), data, static_cast<int>(std::min<std::size_t>(size, INT32_MAX)));
    return tls_outcome(n);
  }

  // The outcome of an SSL_read or SSL_write that returned n (the TLS mutex held).
  Transfer tls_outcome(int n) {
    if (n > 0) return Transfer::of(Transfer::kDone, static_cast<std::size_t>(n));
    switch (::SSL_get_error(tls.get(), n)) {
      case SSL_ERROR_WANT_READ:
        return Transfer::of(Transfer::kWaitRead);
      case SSL_ERROR_WANT_WRITE:
        return Transfer::of(Transfer::kWaitWrite);
      case SSL_ERROR_ZERO_RETURN:
        return Transfer::of(Transfer::kClosed);
      case SSL_ERROR_SYSCALL:
        if (errno == 0 || errno == EPIPE) return Transfer::of(Transfer::kClosed);
        return Transfer::failed(std::strerror(errno));
      default:
        return Transfer::failed(tls_error("TLS failure"));
    }
  }

  // Connects TLS on the connected socket by `deadline`: the server's certificate must chain to
  // options.ca_file (else the system's store) and name `host`.
  Status start_tls(const std::string& host, const TlsOptions& options,
                   std::chrono::steady_clock::time_point deadline) {
    tls_context.reset(::SSL_CTX_new(::TLS_client_method()));
    if (!tls_context) return make_error(ErrorCode::kInternal, tls_error("cannot create a TLS context"));
    SSL_CTX* context = tls_context.get();
    ::SSL_CTX_set_min_proto_version(context, TLS1_2_VERSION);
    // Frames carry their own lengths, so a connection cut without TLS's close_notify loses nothing
    // unnoticed: read it as the end of the stream, as over plain TCP.
    ::SSL_CTX_set_options(context, SSL_OP_IGNORE_UNEXPECTED_EOF);
    ::SSL_CTX_set_mode(context, SSL_MODE_ENABLE_PARTIAL_WRITE | SSL_MODE_ACCEPT_MOVING_WRITE_BUFFER);
    ::SSL_CTX_set_verify(context, SSL_VERIFY_PEER, nullptr);
    const int trusted = options.ca_file.empty()
                            ? ::SSL_CTX_set_default_verify_paths(context)
                            : ::SSL_CTX_load_verify_locations(context, options.ca_file.c_str(), nullptr);
    if (trusted != 1) {
      return make_error(ErrorCode::kInvalidArgument,
                        fmt::format("{}: cannot load trusted certificates: {}",
                                    options.ca_file.empty() ? "the system's CA store" : options.ca_file,
                                    tls_error("no certificates")));
    }
    tls.reset(::SSL_new(context));
    if (!tls || ::SSL_set_fd(tls.get(), fd) != 1)
      return make_error(ErrorCode::kInternal, tls_error("cannot start TLS"));
    // The certificate must name what was dialled: an IP address as such, a host name (also sent as
    // SNI, so a proxy terminating TLS for several names picks the right certificate).
    in6_addr address;
    const bool ip = ::inet_pton(AF_INET, host.c_str(), &address) == 1 ||
                    ::inet_pton(AF_INET6, host.c_str(), &address) == 1;
    const int named =
        ip ? ::X509_VERIFY_PARAM_set1_ip_asc(::SSL_get0_param(tls.get()), host.c_str())
           : ::SSL_set1_host(tls.get(), host.c_str()) && ::SSL_set_tlsext_host_name(tls.get(), host.c_str());
    if (named != 1)
      return make_error(ErrorCode::kInvalidArgument, fmt::format("{}: bad TLS host name", host));
    for (;;) {
      int outcome = 0;
      {
        std::lock_guard lock(tls_mutex);
        SigpipeBlock no_sigpipe;
        ::ERR_clear_error();
        const int n = ::SSL_connect(tls.get());
        if (n == 1) return Ok{};
        outcome = ::SSL_get_error(tls.get(), n);
      }
      const bool wait_read = outcome == SSL_ERROR_WANT_READ;
      if (!wait_read && outcome != SSL_ERROR_WANT_WRITE) {
        const long verified = ::SSL_get_verify_result(tls.get());
        if (verified != X509_V_OK) {
          return make_error(ErrorCode::kInvalidArgument,
                            fmt::format("{}: the server's TLS certificate is not trusted: {}", peer,
                                        ::X509_verify_cert_error_string(verified)));
        }
        return make_error(
            ErrorCode::kIoError,
            fmt::format("{}: TLS handshake failed: {} (does the server speak TLS?)", peer,
                        outcome == SSL_ERROR_SYSCALL ? "the connection closed" : tls_error("TLS failure")));
      }
      if (!wait_for(fd, wait_read ? POLLIN : POLLOUT, deadline))
        return make_error(ErrorCode::kIoError, fmt::format("{}: TLS handshake timed out", peer));
    }
  }
};

ServerConnection::ServerConnection() = default;
ServerConnection::~ServerConnection() = default;
ServerConnection::ServerConnection(ServerConnection&&) noexcept = default;
ServerConnection& ServerConnection::operator=(ServerConnection&&) noexcept = default;

Result<ServerConnection> ServerConnection::open(const std::string& host, std::uint16_t port,
                                                std::chrono::milliseconds timeout, const TlsOptions& tls) {
  const std::string peer = fmt::format("{}:{}", host, port);
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (int rc = ::getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &found); rc != 0) {
    return make_error(ErrorCode::kNotFound, fmt::format("{}: {}", peer, ::gai_strerror(rc)));
  }
  std::string last_error = "no address";
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (addrinfo* a = found; a; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) continue;
    int rc = ::connect(fd, a->ai_addr, a->ai_addrlen);
    if (rc < 0 && errno == EINPROGRESS) {
      if (wait_for(fd, POLLOUT, deadline)) {
        int err = 0;
        socklen_t len = sizeof err;
        ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len);
        rc = err == 0 ? 0 : -1;
        errno = err;
      } else {
        errno = ETIMEDOUT;
      }
    }
    if (rc == 0) {
      const int one = 1;
      ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
      ::freeaddrinfo(found);
      ServerConnection c;
      c.impl_ = std::make_unique<Impl>();
      c.impl_->fd = fd;
      c.impl_->peer = peer;
      if (tls.enabled) MTLOD_RETURN_IF_ERROR(c.impl_->start_tls(host, tls, deadline));
      return c;
    }
    last_error = std::strerror(errno);
    ::close(fd);
  }
  ::freeaddrinfo(found);
  return make_error(ErrorCode::kIoError, fmt::format("cannot connect to {}: {}", peer, last_error));
}

Status ServerConnection::send_raw(const std::vector<std::uint8_t>& bytes) {
  if (!impl_ || impl_->fd < 0) return make_error(ErrorCode::kIoError, "connection is closed");
  std::size_t sent = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (sent < bytes.size()) {
    const Transfer t = impl_->write_some(bytes.data() + sent, bytes.size() - sent);
    if (t.outcome == Transfer::kDone) {
      sent += t.bytes;
    } else if (t.outcome == Transfer::kWaitRead || t.outcome == Transfer::kWaitWrite) {
      if (!wait_for(impl_->fd, t.outcome == Transfer::kWaitRead ? POLLIN : POLLOUT, deadline))
        return make_error(ErrorCode::kIoError, fmt::format("{}: send timed out", impl_->peer));
    } else {
      return make_error(ErrorCode::kIoError,
                        fmt::format("{}: send failed: {}", impl_->peer,
                                    t.outcome == Transfer::kClosed ? "connection closed" : t.error));
    }
  }
  return Ok{};
}

Status ServerConnection::send(const protocol::Request& request, std::uint64_t id) {
  std::vector<std::uint8_t> frame;
  protocol::append_frame(protocol::to_json(request, id), {}, frame);
  return send_raw(frame);
}

Result<ReplyFrame> ServerConnection::receive(std::chrono::milliseconds timeout) {
  if (!impl_ || impl_->fd < 0) return make_error(ErrorCode::kIoError, "connection is closed");
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  auto read_exact = [&](std::uint8_t* out, std::size_t size) -> Status {
    std::size_t got = 0;
    while (got < size) {
      const Transfer t = impl_->read_some(out + got, size - got);
      if (t.outcome == Transfer::kDone) {
        got += t.bytes;
      } else if (t.outcome == Transfer::kClosed) {
        return make_error(ErrorCode::kIoError,
                          fmt::format("{}: connection closed by the server", impl_->peer));
      } else if (t.outcome == Transfer::kWaitRead || t.outcome == Transfer::kWaitWrite) {
        if (!wait_for(impl_->fd, t.outcome == Transfer::kWaitRead ? POLLIN : POLLOUT, deadline)) {
          return make_error(ErrorCode::kIoError,
                            fmt::format("{}: no reply within {} ms", impl_->peer, timeout.count()));
        }
      } else {
        return make_error(ErrorCode::kIoError, fmt::format("{}: receive failed: {}", impl_->peer, t.error));
      }
    }
    return Ok{};
  };
  std::array<std::uint8_t, protocol::kFrameHeaderBytes> header_bytes;
  MTLOD_RETURN_IF_ERROR(read_exact(header_bytes.data(), header_bytes.size()));
  // A reply may carry a large mesh: accept up to 1 GiB.
  MTLOD_TRY(const protocol::FrameHeader header,
            protocol::decode_frame_header(header_bytes, std::size_t{1} << 30));
  ReplyFrame frame;
  frame.json.resize(header.json_bytes);
  MTLOD_RETURN_IF_ERROR(read_exact(reinterpret_cast<std::uint8_t*>(frame.json.data()), frame.json.size()));
  frame.payload.resize(header.payload_bytes);
  MTLOD_RETURN_IF_ERROR(read_exact(frame.payload.data(), frame.payload.size()));
  MTLOD_TRY(frame.header, protocol::parse_reply(frame.json));
  return frame;
}

Result<ReplyFrame> ServerConnection::call(const protocol::Request& request, std::uint64_t id,
                                          std::chrono::milliseconds timeout) {
  MTLOD_RETURN_IF_ERROR(send(request, id));
  for (;;) {
    MTLOD_TRY(ReplyFrame frame, receive(timeout));
    if (frame.header.id == id) return frame;
  }
}

void ServerConnection::close() {
  impl_.reset();
}

void ServerConnection::interrupt() {
  if (impl_ && impl_->fd >= 0) ::shutdown(impl_->fd, SHUT_RDWR);
}

}  // namespace mtlod::clients

// Blocking client connection (see connection.hpp). Plain POSIX sockets with poll() for timeouts:
// a command-line client needs neither an event loop nor threads.
#include "clients/common/connection.hpp"

#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "fmt/format.h"
#include "protocol/frame.hpp"
#include "protocol/parse.hpp"

namespace mtlod::clients {

struct Connection::Impl {
  int fd = -1;
  std::string peer;
  ~Impl() {
    if (fd >= 0) ::close(fd);
  }
};

Connection::Connection() = default;
Connection::~Connection() = default;
Connection::Connection(Connection&&) noexcept = default;
Connection& Connection::operator=(Connection&&) noexcept = default;

namespace {

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

Result<Connection> Connection::open(const std::string& host, std::uint16_t port,
                                    std::chrono::milliseconds timeout) {
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
      Connection c;
      c.impl_ = std::make_unique<Impl>();
      c.impl_->fd = fd;
      c.impl_->peer = peer;
      return c;
    }
    last_error = std::strerror(errno);
    ::close(fd);
  }
  ::freeaddrinfo(found);
  return make_error(ErrorCode::kIoError, fmt::format("cannot connect to {}: {}", peer, last_error));
}

Status Connection::send_raw(const std::vector<std::uint8_t>& bytes) {
  if (!impl_ || impl_->fd < 0) return make_error(ErrorCode::kIoError, "connection is closed");
  std::size_t sent = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (sent < bytes.size()) {
    const ssize_t n = ::send(impl_->fd, bytes.data() + sent, bytes.size() - sent, MSG_NOSIGNAL);
    if (n > 0) {
      sent += static_cast<std::size_t>(n);
    } else if (n < 0 && (errno == EAGAIN || errno == EINTR)) {
      if (!wait_for(impl_->fd, POLLOUT, deadline))
        return make_error(ErrorCode::kIoError, fmt::format("{}: send timed out", impl_->peer));
    } else {
      return make_error(ErrorCode::kIoError,
                        fmt::format("{}: send failed: {}", impl_->peer, std::strerror(errno)));
    }
  }
  return Ok{};
}

Status Connection::send(const protocol::Request& request, std::uint64_t id) {
  std::vector<std::uint8_t> frame;
  protocol::append_frame(protocol::to_json(request, id), {}, frame);
  return send_raw(frame);
}

Result<ReplyFrame> Connection::receive(std::chrono::milliseconds timeout) {
  if (!impl_ || impl_->fd < 0) return make_error(ErrorCode::kIoError, "connection is closed");
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  auto read_exact = [&](std::uint8_t* out, std::size_t size) -> Status {
    std::size_t got = 0;
    while (got < size) {
      const ssize_t n = ::recv(impl_->fd, out + got, size - got, 0);
      if (n > 0) {
        got += static_cast<std::size_t>(n);
      } else if (n == 0) {
        return make_error(ErrorCode::kIoError,
                          fmt::format("{}: connection closed by the server", impl_->peer));
      } else if (errno == EAGAIN || errno == EINTR) {
        if (!wait_for(impl_->fd, POLLIN, deadline)) {
          return make_error(ErrorCode::kIoError,
                            fmt::format("{}: no reply within {} ms", impl_->peer, timeout.count()));
        }
      } else {
        return make_error(ErrorCode::kIoError,
                          fmt::format("{}: receive failed: {}", impl_->peer, std::strerror(errno)));
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

Result<ReplyFrame> Connection::call(const protocol::Request& request, std::uint64_t id,
                                    std::chrono::milliseconds timeout) {
  MTLOD_RETURN_IF_ERROR(send(request, id));
  for (;;) {
    MTLOD_TRY(ReplyFrame frame, receive(timeout));
    if (frame.header.id == id) return frame;
  }
}

void Connection::close() {
  impl_.reset();
}

void Connection::interrupt() {
  if (impl_ && impl_->fd >= 0) ::shutdown(impl_->fd, SHUT_RDWR);
}

}  // namespace mtlod::clients

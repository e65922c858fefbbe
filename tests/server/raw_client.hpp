// Blocking loopback sockets for abuse tests: connect from a chosen source address (any of
// 127.0.0.0/8 reaches the loopback server, so one test can play several client addresses), send
// raw bytes, read whole reply frames.
#pragma once

#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "protocol/frame.hpp"
#include "protocol/parse.hpp"
#include "protocol/replies.hpp"
#include "tests/server/loopback_socket.hpp"

namespace mtlod::test {

class RawClient {
 public:
  RawClient() = default;
  // Connects from `source` (e.g. "127.0.0.2") to 127.0.0.1:port; valid() says whether it did.
  RawClient(const std::string& source, std::uint16_t port) : fd_(connect_loopback_from(source, port)) {}
  RawClient(RawClient&& other) noexcept : fd_(other.fd_) { other.fd_ = -1; }
  RawClient& operator=(RawClient&& other) noexcept {
    std::swap(fd_, other.fd_);
    return *this;
  }
  ~RawClient() { close(); }

  bool valid() const { return fd_ >= 0; }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  // Closes with a reset instead of a FIN (an abrupt disconnect).
  void reset() {
    if (fd_ < 0) return;
    const linger abort{1, 0};
    ::setsockopt(fd_, SOL_SOCKET, SO_LINGER, &abort, sizeof abort);
    close();
  }

  bool send(const std::string& bytes) const { return send_all(fd_, bytes); }
  bool send_request(const protocol::Request& request, std::uint64_t id) const {
    return send(frame(protocol::to_json(request, id)));
  }
  static std::string frame(std::string_view json) {
    std::vector<std::uint8_t> bytes;
    protocol::append_frame(json, {}, bytes);
    return {bytes.begin(), bytes.end()};
  }

  struct Reply {
    std::string json;
    std::vector<std::uint8_t> payload;
    protocol::ParsedReply parsed;
  };
  // The next reply frame; nullopt on a closed connection, a timeout or a frame that does not parse.
  std::optional<Reply> receive(std::chrono::milliseconds timeout = std::chrono::seconds(30)) const {
    std::vector<std::uint8_t> header(protocol::kFrameHeaderBytes);
    if (!read_exactly(header, timeout)) return std::nullopt;
    auto decoded = protocol::decode_frame_header(
        std::span<const std::uint8_t, protocol::kFrameHeaderBytes>(header.data(), header.size()), 1u << 30);
    if (!decoded) return std::nullopt;
    std::vector<std::uint8_t> body(decoded->body_bytes());
    if (!read_exactly(body, timeout)) return std::nullopt;
    Reply reply;
    reply.json.assign(body.begin(), body.begin() + decoded->json_bytes);
    reply.payload.assign(body.begin() + decoded->json_bytes, body.end());
    auto parsed = protocol::parse_reply(reply.json);
    if (!parsed) return std::nullopt;
    reply.parsed = std::move(*parsed);
    return reply;
  }
  // Everything the server sends until it closes the connection, or nullopt when it has not closed
  // it within `timeout` (each read waits that long at most).
  std::optional<std::string> read_until_closed(std::chrono::milliseconds timeout) const {
    set_timeout(timeout);
    std::string all;
    char buffer[4096];
    for (;;) {
      const ssize_t n = ::recv(fd_, buffer, sizeof buffer, 0);
      if (n == 0 || (n < 0 && errno == ECONNRESET)) return all;
      if (n < 0) return std::nullopt;
      all.append(buffer, static_cast<std::size_t>(n));
    }
  }
  bool closed_by_server(std::chrono::milliseconds timeout) const {
    return read_until_closed(timeout).has_value();
  }

 private:
  void set_timeout(std::chrono::milliseconds timeout) const {
    const auto us = std::chrono::duration_cast<std::chrono::microseconds>(timeout).count();
    timeval tv{static_cast<time_t>(us / 1'000'000), static_cast<suseconds_t>(us % 1'000'000)};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  }
  bool read_exactly(std::vector<std::uint8_t>& out, std::chrono::milliseconds timeout) const {
    if (fd_ < 0) return false;
    set_timeout(timeout);
    std::size_t got = 0;
    while (got < out.size()) {
      const ssize_t n = ::recv(fd_, out.data() + got, out.size() - got, 0);
      if (n <= 0) return false;
      got += static_cast<std::size_t>(n);
    }
    return true;
  }

  int fd_ = -1;
};

}  // namespace mtlod::test

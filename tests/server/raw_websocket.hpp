// A blocking WebSocket client over a loopback socket bound to a chosen source address, written
// from RFC 6455 for tests that must control the bytes before and around the handshake (a PROXY
// header first, a refused upgrade's status): the upgrade is a plain HTTP request, client frames are
// masked, server messages are reassembled from their fragments.
#pragma once

#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <string>
#include <string_view>

#include "tests/server/loopback_socket.hpp"

namespace mtlod::test {

class RawWebSocket {
 public:
  // Connects from `source` (any of 127.0.0.0/8) to 127.0.0.1:port; valid() says whether it did.
  RawWebSocket(const std::string& source, std::uint16_t port) : fd_(connect_loopback_from(source, port)) {}
  RawWebSocket(RawWebSocket&& other) noexcept : fd_(other.fd_), buffered_(std::move(other.buffered_)) {
    other.fd_ = -1;
  }
  RawWebSocket(const RawWebSocket&) = delete;
  RawWebSocket& operator=(const RawWebSocket&) = delete;
  ~RawWebSocket() { close(); }

  bool valid() const { return fd_ >= 0; }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

  // Sends bytes as they are (a PROXY header before the upgrade).
  bool send_raw(std::string_view bytes) const { return send_all(fd_, bytes); }

  // Sends the upgrade request for `target` (e.g. "/ws?model=bunny") and reads the response's head.
  // Returns its status (101: upgraded), 0 when the connection closed or timed out first.
  int upgrade(const std::string& target, std::chrono::milliseconds timeout = std::chrono::seconds(30)) {
    const std::string request =
        "GET " + target +
        " HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n";
    if (!send_raw(request)) return 0;
    set_timeout(timeout);
    std::size_t end;
    while ((end = buffered_.find("\r\n\r\n")) == std::string::npos) {
      if (!fill()) return 0;
    }
    head_ = buffered_.substr(0, end);
    buffered_.erase(0, end + 4);
    if (head_.size() < 12 || head_.compare(0, 5, "HTTP/") != 0) return 0;
    return std::atoi(head_.c_str() + 9);
  }
  // The last upgrade response's status line and headers.
  const std::string& head() const { return head_; }

  // One text message, masked as every client frame must be.
  bool send_text(std::string_view payload) const {
    std::string frame(1, static_cast<char>(0x81));  // FIN, text
    if (payload.size() < 126) {
      frame += static_cast<char>(0x80 | payload.size());
    } else {
      frame += static_cast<char>(0x80 | 126);
      frame += static_cast<char>(payload.size() >> 8);
      frame += static_cast<char>(payload.size() & 0xFF);
    }
    const char mask[4] = {0x1B, 0x2C, 0x3D, 0x4E};
    frame.append(mask, 4);
    for (std::size_t i = 0; i < payload.size(); ++i) frame += static_cast<char>(payload[i] ^ mask[i % 4]);
    return send_raw(frame);
  }

  struct Message {
    bool text = false;
    std::string payload;
  };
  // The next whole message, its fragments joined; nullopt on a close frame, a closed connection or
  // a timeout. Pings and pongs are skipped.
  std::optional<Message> receive(std::chrono::milliseconds timeout = std::chrono::seconds(30)) {
    set_timeout(timeout);
    Message message;
    bool started = false;
    for (;;) {
      std::string head;
      if (!take(2, head)) return std::nullopt;
      const auto b0 = static_cast<std::uint8_t>(head[0]), b1 = static_cast<std::uint8_t>(head[1]);
      const unsigned opcode = b0 & 0x0F;
      std::uint64_t length = b1 & 0x7F;
      if (length >= 126) {
        std::string extended;
        if (!take(length == 126 ? 2 : 8, extended)) return std::nullopt;
        length = 0;
        for (const char c : extended) length = length << 8 | static_cast<std::uint8_t>(c);
      }
      std::string mask;
      if ((b1 & 0x80) && !take(4, mask)) return std::nullopt;
      std::string payload;
      if (!take(length, payload)) return std::nullopt;
      for (std::size_t i = 0; i < mask.size() && i < payload.size(); ++i) payload[i] ^= mask[i % 4];
      if (opcode == 0x8) return std::nullopt;
      if (opcode == 0x9 || opcode == 0xA) continue;
      if (!started) message.text = opcode == 0x1;
      started = true;
      message.payload += payload;
      if (b0 & 0x80) return message;
    }
  }

  // Whether the server closes the connection within `timeout` (what it sent before is dropped).
  bool closed_by_server(std::chrono::milliseconds timeout) {
    set_timeout(timeout);
    buffered_.clear();
    for (;;) {
      char buffer[4096];
      const ssize_t n = ::recv(fd_, buffer, sizeof buffer, 0);
      if (n == 0 || (n < 0 && errno == ECONNRESET)) return true;
      if (n < 0) return false;
    }
  }

 private:
  void set_timeout(std::chrono::milliseconds timeout) const {
    const auto us = std::chrono::duration_cast<std::chrono::microseconds>(timeout).count();
    timeval tv{static_cast<time_t>(us / 1'000'000), static_cast<suseconds_t>(us % 1'000'000)};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  }
  bool fill() {
    if (fd_ < 0) return false;
    char buffer[16384];
    const ssize_t n = ::recv(fd_, buffer, sizeof buffer, 0);
    if (n <= 0) return false;
    buffered_.append(buffer, static_cast<std::size_t>(n));
    return true;
  }
  bool take(std::uint64_t n, std::string& out) {
    while (buffered_.size() < n) {
      if (!fill()) return false;
    }
    out = buffered_.substr(0, n);
    buffered_.erase(0, n);
    return true;
  }

  int fd_ = -1;
  std::string buffered_;  // bytes received and not yet taken
  std::string head_;
};

}  // namespace mtlod::test

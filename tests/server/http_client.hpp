// A plain HTTP/1.1 client for tests that talk to mtlod-server's HTTP port (or a proxy in front of
// it): one request per fresh connection, read to the end.
#pragma once

#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstdint>
#include <string>

namespace mtlod::test {

struct HttpReply {
  int status = 0;    // 0 when nothing (or nothing HTTP) answered
  std::string head;  // status line and headers
  std::string body;
};

// Sends `request` (a whole HTTP request) on a fresh loopback connection and reads until it closes.
// `before` goes first on the connection (a PROXY protocol header, as a load balancer sends).
inline HttpReply http_request(std::uint16_t port, const std::string& request,
                              const std::string& before = "") {
  HttpReply reply;
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(port);
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    ::close(fd);
    return reply;
  }
  timeval timeout{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  const std::string bytes = before + request;
  (void)::send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL);
  std::string all;
  char buffer[65536];
  for (ssize_t n; (n = ::recv(fd, buffer, sizeof buffer, 0)) > 0;)
    all.append(buffer, static_cast<std::size_t>(n));
  ::close(fd);
  const auto end = all.find("\r\n\r\n");
  if (end == std::string::npos || all.size() < 12) return reply;
  reply.head = all.substr(0, end);
  reply.body = all.substr(end + 4);
  reply.status = std::stoi(all.substr(9, 3));
  return reply;
}

// GET http://127.0.0.1:port/target with Connection: close, after `before`.
inline HttpReply http_get(std::uint16_t port, const std::string& target, const std::string& before = "") {
  return http_request(port, "GET " + target + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n",
                      before);
}

}  // namespace mtlod::test

// Helpers for the deployment tests: free loopback ports and a child process with its own environment
// (HAProxy, the client tools). HTTP requests go through tests/server/http_client.hpp.
#pragma once

#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "tests/server/server_process.hpp"

namespace mtlod::test {

// A loopback port that was free a moment ago (the OS picks it; closing frees it again).
inline std::uint16_t free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address);
  socklen_t size = sizeof address;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &size);
  ::close(fd);
  return ntohs(address.sin_port);
}

// The environment docker/haproxy.cfg reads, for HAProxy on loopback ports in front of two replicas
// (each a protocol port and an HTTP port; the same replica twice is allowed).
struct HaproxyPorts {
  std::uint16_t lb = 0, lb_http = 0, stats = 0;
  std::array<std::pair<std::uint16_t, std::uint16_t>, 2> replicas{};  // protocol, HTTP
};
inline std::map<std::string, std::string> haproxy_environment(const HaproxyPorts& ports) {
  std::map<std::string, std::string> environment = {{"MTLOD_BIND", "127.0.0.1"},
                                                    {"MTLOD_LB_PORT", std::to_string(ports.lb)},
                                                    {"MTLOD_LB_HTTP_PORT", std::to_string(ports.lb_http)},
                                                    {"MTLOD_LB_STATS_PORT", std::to_string(ports.stats)}};
  for (std::size_t i = 0; i < ports.replicas.size(); ++i) {
    const std::string prefix = "MTLOD_REPLICA_" + std::to_string(i + 1);
    environment[prefix + "_HOST"] = "127.0.0.1";
    environment[prefix + "_PORT"] = std::to_string(ports.replicas[i].first);
    environment[prefix + "_HTTP_PORT"] = std::to_string(ports.replicas[i].second);
  }
  return environment;
}

// What the replicas behind docker/haproxy.cfg are given here: HAProxy connects to them from
// 127.0.0.1 with a PROXY protocol v2 header (send-proxy-v2), so they trust that address for one.
inline const std::vector<std::string> kBehindHaproxy = {"--proxy-protocol-from", "127.0.0.1/32"};
// The header HAProxy's health checks send (LOCAL: the balancer's own connection), for a test that
// talks to such a replica directly from 127.0.0.1 as HAProxy's checks do.
inline const std::string kProxyLocalHeader("\x0D\x0A\x0D\x0A\x00\x0D\x0A\x51\x55\x49\x54\x0A\x20\x00\x00\x00",
                                           16);

// A child process: argv, extra environment, output to a log file. Killed (SIGKILL) when destroyed
// unless it has exited.
class Child {
 public:
  Child(const std::vector<std::string>& args, const std::map<std::string, std::string>& environment,
        const std::filesystem::path& log)
      : pid_(spawn(args, environment, log)), log_(log) {}
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;
  ~Child() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }

  bool running() {
    if (pid_ <= 0) return false;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      status_ = status;
      return false;
    }
    return true;
  }
  // Waits for the exit up to `timeout`; returns the exit code, or -1 (still running, or a signal).
  int wait(std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (running() && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    if (pid_ > 0) return -1;
    return WIFEXITED(status_) ? WEXITSTATUS(status_) : -1;
  }
  std::string log() const {
    std::ifstream in(log_);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }

 private:
  pid_t pid_ = -1;
  int status_ = 0;
  std::filesystem::path log_;
};

}  // namespace mtlod::test

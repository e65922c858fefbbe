// Starts the real mtlod-server binary on an OS-chosen loopback port for integration tests, and
// stops it (SIGTERM, then SIGKILL) when the test ends.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <thread>
#include <vector>

namespace mtlod::test {

// Starts args[0] with args as its argv and `environment` added to its own, its stdout and stderr
// appended to `log`. Returns the child's pid.
inline pid_t spawn(const std::vector<std::string>& args,
                   const std::map<std::string, std::string>& environment, const std::filesystem::path& log) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    for (const auto& [name, value] : environment) ::setenv(name.c_str(), value.c_str(), 1);
    std::vector<std::string> copy = args;
    std::vector<char*> argv;
    for (auto& s : copy) argv.push_back(s.data());
    argv.push_back(nullptr);
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    if (fd >= 0) {
      ::dup2(fd, 1);
      ::dup2(fd, 2);
    }
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  return pid;
}

class ServerProcess {
 public:
  // args: everything after the binary name except --port and --port-file. `port` 0: any free one.
  // The log goes to dir/server.log (appended to, so a restart in the same folder keeps the first
  // run's log).
  ServerProcess(const std::vector<std::string>& args, const std::filesystem::path& dir,
                std::uint16_t port = 0) {
    const auto port_file = dir / "port";
    std::filesystem::remove(port_file);
    log_ = dir / "server.log";
    std::vector<std::string> argv_strings = {MTLOD_SERVER_BINARY, "--port", std::to_string(port),
                                             "--port-file", port_file.string()};
    argv_strings.insert(argv_strings.end(), args.begin(), args.end());
    pid_ = spawn(argv_strings, {}, log_);
    // Model loading may take a while under sanitizers: wait up to a minute for the port.
    for (int i = 0; i < 600 && port_ == 0; ++i) {
      std::ifstream in(port_file);
      unsigned p = 0, http = 0;
      if (in >> p) {
        port_ = static_cast<std::uint16_t>(p);
        if (in >> http) http_port_ = static_cast<std::uint16_t>(http);  // with --http-port
      } else {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
      }
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        break;
      }
    }
  }
  ~ServerProcess() { stop(SIGTERM); }

  std::uint16_t port() const { return port_; }
  pid_t pid() const { return pid_; }
  // The HTTP port when the server was given --http-port, else 0.
  std::uint16_t http_port() const { return http_port_; }
  bool running() const { return pid_ > 0; }
  std::string log() const {
    std::ifstream in(log_);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }

  // Sends `signal` and waits up to `timeout` for the exit; SIGKILL after that. Returns the exit
  // status as waitpid reports it, or -1 when it had to be killed.
  int stop(int signal, std::chrono::milliseconds timeout = std::chrono::seconds(20)) {
    if (pid_ <= 0) return exit_status_;
    ::kill(pid_, signal);
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        exit_status_ = status;
        return status;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
    exit_status_ = -1;
    return -1;
  }

 private:
  pid_t pid_ = -1;
  std::uint16_t port_ = 0;
  std::uint16_t http_port_ = 0;
  int exit_status_ = -1;
  std::filesystem::path log_;
};

}  // namespace mtlod::test

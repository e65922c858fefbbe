// The real servers and the client side of the whole-process fuzz targets (process_harness.hpp).
#include "tests/fuzz/process_harness.hpp"

#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <utility>

#include "fmt/format.h"
#include "protocol/frame.hpp"
#include "server/model_registry.hpp"
#include "server/server.hpp"
#include "spdlog/spdlog.h"

namespace mtlod::fuzz {
namespace {

// Starts `config`'s server on a thread of its own, for the life of the process, and returns it.
server::Server& start_server(server::ServerConfig config, const std::filesystem::path& model) {
  // The server's signal set takes SIGINT and SIGTERM; libFuzzer's own handlers (SIGINT ends a
  // campaign and merges what it found) are put back, so that a signal stops the fuzzer, not the
  // servers under it.
  std::array<struct sigaction, 3> saved{};
  const std::array<int, 3> signals{SIGINT, SIGTERM, SIGHUP};
  for (std::size_t i = 0; i < signals.size(); ++i) ::sigaction(signals[i], nullptr, &saved[i]);
  auto* registry = new server::ModelRegistry;  // never destroyed, as the server using it
  if (auto added = registry->add_file(model); !added) fail(added.error().message);
  auto* instance = new server::Server(std::move(config), *registry);
  for (std::size_t i = 0; i < signals.size(); ++i) ::sigaction(signals[i], &saved[i], nullptr);
  if (auto listening = instance->listen(); !listening)
    fail("the server cannot listen: " + listening.error().message);
  std::thread([instance] { instance->run(); }).detach();
  return *instance;
}

}  // namespace

// ---- ProcessServer ----

ProcessServer& ProcessServer::get() {
  static ProcessServer* const servers = new ProcessServer;
  return *servers;
}

ProcessServer::ProcessServer() {
  // Errors stay visible; per-request logging would cost more than the request. MTLOD_FUZZ_LOG=debug
  // shows the servers' own account of a reproducer.
  const char* level = std::getenv("MTLOD_FUZZ_LOG");
  spdlog::set_level(level ? spdlog::level::from_str(level) : spdlog::level::err);
  const auto dir = std::filesystem::temp_directory_path() / fmt::format("mtlod-fuzz-process-{}", ::getpid());
  std::filesystem::create_directories(dir);
  // The model file and the certificate go when the process exits (the servers run on to the end).
  static const struct Cleanup {
    std::filesystem::path dir;
    ~Cleanup() {
      std::error_code ignored;
      std::filesystem::remove_all(dir, ignored);
    }
  } cleanup{dir};
  const auto model = dir / "bunny.mt";
  model_triangles_ = write_fuzz_model(model);
  // An EC key: a TLS handshake per input stays cheap.
  cert_ = dir / "cert.pem";
  const std::string command = fmt::format(
      "openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 2 -subj /CN=127.0.0.1 "
      "-addext subjectAltName=IP:127.0.0.1 -keyout {}/key.pem -out {} > {}/openssl.log 2>&1",
      dir.string(), cert_.string(), dir.string());
  if (std::system(command.c_str()) != 0) fail("cannot make a certificate: " + command);

  server::ServerConfig config;  // the defaults mtlod-server runs with, but ports and threads
  config.port = 0;
  config.http_port = 0;
  config.workers = 1;
  config.web_root = MTLOD_SOURCE_DIR;
  config.instance = "fuzz";
  // The model file never changes while the servers run, and its folder goes at exit, when a
  // watcher waking up would log into a process tearing down.
  config.watch_models = false;
  limits_ = config.limits;
  const server::Server& plain = start_server(config, model);
  port_ = plain.port();
  http_port_ = plain.http_port();
  config.http_port.reset();
  config.tls_cert_file = cert_.string();
  config.tls_key_file = (dir / "key.pem").string();
  tls_port_ = start_server(config, model).port();
}

// ---- Channel, ClientSocket ----

std::vector<std::uint8_t> Channel::receive_all() {
  std::vector<std::uint8_t> out;
  while (receive(out)) {
  }
  return out;
}

ClientSocket::ClientSocket(std::uint16_t port) {
  fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd_ < 0) fail(fmt::format("socket: {}", std::strerror(errno)));
  const int one = 1;
  ::setsockopt(fd_, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(port);
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  int error = ::connect(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof address) == 0 ? 0 : errno;
  if (error == EINTR) {
    // A signal (libFuzzer's timer) interrupted the wait; the connection goes on: wait for it.
    pollfd p{fd_, POLLOUT, 0};
    while (::poll(&p, 1, static_cast<int>(std::chrono::milliseconds(kReplyDeadline).count())) < 0 &&
           errno == EINTR) {
    }
    socklen_t length = sizeof error;
    ::getsockopt(fd_, SOL_SOCKET, SO_ERROR, &error, &length);
  }
  if (error != 0)
    fail(fmt::format("the server on port {} refused a connection: {}", port, std::strerror(error)));
}

ClientSocket::~ClientSocket() {
  // The server closed first (the client read to its end), so no TIME_WAIT is left here either way;
  // an abortive close also ends a connection given up on.
  const linger abortive{1, 0};
  ::setsockopt(fd_, SOL_SOCKET, SO_LINGER, &abortive, sizeof abortive);
  ::close(fd_);
}

bool ClientSocket::send(std::span<const std::uint8_t> bytes) {
  while (!bytes.empty()) {
    const ssize_t n = ::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;  // EPIPE, ECONNRESET: the server has closed
    bytes = bytes.subspan(static_cast<std::size_t>(n));
  }
  return true;
}

void ClientSocket::finish_sending() {
  ::shutdown(fd_, SHUT_WR);
}

bool ClientSocket::receive(std::vector<std::uint8_t>& into) {
  pollfd p{fd_, POLLIN, 0};
  int ready = 0;
  do {
    ready = ::poll(&p, 1, static_cast<int>(std::chrono::milliseconds(kReplyDeadline).count()));
  } while (ready < 0 && errno == EINTR);
  if (ready == 0) fail("the server neither answered nor closed the connection in time");
  std::array<std::uint8_t, 65536> buffer;
  ssize_t n = 0;
  do {
    n = ::recv(fd_, buffer.data(), buffer.size(), 0);
  } while (n < 0 && errno == EINTR);
  if (n <= 0) return false;  // end of stream, or reset after the server's last reply
  into.insert(into.end(), buffer.begin(), buffer.begin() + n);
  return true;
}

// ---- frames ----

std::vector<StreamFrame> split_stream(std::span<const std::uint8_t> input, const protocol::Limits& limits) {
  std::vector<StreamFrame> frames;
  while (input.size() >= protocol::kFrameHeaderBytes) {
    const auto header =
        protocol::decode_frame_header(input.first<protocol::kFrameHeaderBytes>(), limits.max_frame_bytes);
    if (!header) {
      frames.push_back(StreamFrame{input.first(protocol::kFrameHeaderBytes), {}, true});
      break;
    }
    const std::size_t size = protocol::kFrameHeaderBytes + header->body_bytes();
    if (input.size() < size) break;  // cut short by end of stream: never read whole
    frames.push_back(StreamFrame{
        input.first(size),
        {reinterpret_cast<const char*>(input.data()) + protocol::kFrameHeaderBytes, header->json_bytes},
        false});
    input = input.subspan(size);
  }
  return frames;
}

void expect(Transcript& transcript, const StreamFrame& frame) {
  if (frame.bad) {
    transcript.expect_bad_frame();
  } else {
    transcript.expect_request(frame.json);
  }
}

std::size_t take_replies(std::vector<std::uint8_t>& bytes, Transcript& transcript) {
  std::size_t taken = 0, at = 0;
  while (bytes.size() - at >= protocol::kFrameHeaderBytes) {
    const std::span<const std::uint8_t> rest(bytes.data() + at, bytes.size() - at);
    // Replies may be far larger than a request may be: no limit but the reply's own.
    const auto header = protocol::decode_frame_header(rest.first<protocol::kFrameHeaderBytes>(), 1u << 31);
    if (!header) fail("a reply's frame header does not decode: " + header.error().message);
    const std::size_t size = protocol::kFrameHeaderBytes + header->body_bytes();
    if (rest.size() < size) break;
    transcript.check_reply(rest.first(size));
    at += size;
    ++taken;
  }
  bytes.erase(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(at));
  return taken;
}

void run_stream_client(std::span<const std::uint8_t> input,
                       const std::function<std::unique_ptr<Channel>()>& open) {
  const ProcessServer& server = ProcessServer::get();
  const std::vector<StreamFrame> frames = split_stream(input, server.limits());
  bool meshes = false;
  for (const bool patient : {false, true}) {
    if (patient && !meshes) break;
    Transcript transcript(server.limits(), server.model_triangles());
    const std::unique_ptr<Channel> channel = open();
    std::vector<std::uint8_t> received;
    if (!patient) {
      for (const StreamFrame& frame : frames) expect(transcript, frame);
      channel->send(input);
    } else {
      std::size_t owed = 0, answered = 0;
      bool connected = true;
      for (const StreamFrame& frame : frames) {
        expect(transcript, frame);
        ++owed;
        if (!channel->send(frame.bytes)) break;
        while (connected && answered < owed) {
          connected = channel->receive(received);
          answered += take_replies(received, transcript);
        }
        if (!connected) break;
      }
      // What follows the last whole frame: a frame cut short, or what a refused header hid.
      std::size_t sent = 0;
      for (const StreamFrame& frame : frames) sent += frame.bytes.size();
      if (connected && (frames.empty() || !frames.back().bad)) channel->send(input.subspan(sent));
    }
    channel->finish_sending();
    std::vector<std::uint8_t> rest = channel->receive_all();
    received.insert(received.end(), rest.begin(), rest.end());
    take_replies(received, transcript);
    if (!received.empty()) fail(fmt::format("the connection closed {} bytes into a reply", received.size()));
    transcript.check_complete();
    meshes = transcript.asked_for_meshes();
  }
}

bool valid_utf8(std::string_view text) {
  const auto* s = reinterpret_cast<const unsigned char*>(text.data());
  const std::size_t n = text.size();
  for (std::size_t i = 0; i < n;) {
    const unsigned char c = s[i];
    if (c < 0x80) {
      ++i;
      continue;
    }
    std::size_t length = 0;
    std::uint32_t code = 0, least = 0;
    if (c >= 0xC2 && c <= 0xDF) {
      length = 2, code = c & 0x1F, least = 0x80;
    } else if (c >= 0xE0 && c <= 0xEF) {
      length = 3, code = c & 0x0F, least = 0x800;
    } else if (c >= 0xF0 && c <= 0xF4) {
      length = 4, code = c & 0x07, least = 0x10000;
    } else {
      return false;
    }
    if (i + length > n) return false;
    for (std::size_t k = 1; k < length; ++k) {
      if ((s[i + k] & 0xC0) != 0x80) return false;
      code = code << 6 | (s[i + k] & 0x3F);
    }
    if (code < least || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return false;
    i += length;
  }
  return true;
}

}  // namespace mtlod::fuzz

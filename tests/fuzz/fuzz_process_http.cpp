// libFuzzer target: the bytes an HTTP client sends to a real server's HTTP port in this process
// (process_harness.hpp): Beast's request parser with the server's limits, the routes (/health,
// /metrics, the viewer's files, the WebSocket upgrade) and the responses as a client reads them.
// The input is the raw byte stream; its end is the client closing its side.
//
// What each response must be comes from reading the input as HTTP/1.1 requests, in order, until
// one the grammar (Beast's parser, with the server's 16 KiB limits) refuses: a GET of /health is
// 200 with {"status": "ok"}, of /metrics 200 with the request counters, another method 405, an
// upgrade of /ws 101 (or Beast's 400 or 426 for a handshake it refuses), of another target 404,
// and the last; a file is 200 or 404, and never 200 for a
// target that reaches outside the served folders. A request that keeps no connection alive, or
// one the parser refuses, is the last one answered.
#include <boost/asio/buffer.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket/rfc6455.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "fmt/format.h"
#include "tests/fuzz/process_harness.hpp"

namespace mtlod::fuzz {
namespace {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;

constexpr std::size_t kRequestMaxBytes = 16 * 1024;  // server/web_session.cpp's header and body limits

struct Expected {
  http::verb method = http::verb::unknown;
  std::string target;
  bool upgrade = false;
  bool last = false;  // the server closes after answering it
};

// Feeds `bytes` to `parser` until it holds one whole message, fails, or wants more than `bytes`
// holds (a header or chunk the input ends inside); returns the bytes it took.
template <class Parser>
std::size_t feed(Parser& parser, std::string_view bytes, beast::error_code& ec) {
  std::size_t used = 0;
  while (!parser.is_done() && !ec && used < bytes.size()) {
    const std::size_t n = parser.put(net::buffer(bytes.data() + used, bytes.size() - used), ec);
    used += n;
    if (ec == http::error::need_more) {
      ec = {};
      if (n == 0) break;
    }
  }
  return used;
}

// The requests of `input` the server answers, in order.
std::vector<Expected> read_requests(std::string_view input) {
  std::vector<Expected> out;
  while (!input.empty()) {
    http::request_parser<http::string_body> parser;
    parser.header_limit(kRequestMaxBytes);
    parser.body_limit(kRequestMaxBytes);
    parser.eager(true);
    beast::error_code ec;
    const std::size_t used = feed(parser, input, ec);
    // At the input's end the client has closed: a body without a length ends there.
    if (!ec && !parser.is_done()) parser.put_eof(ec);
    if (ec || !parser.is_done()) break;
    const auto& request = parser.get();
    Expected e;
    e.method = request.method();
    e.target = std::string(request.target());
    e.upgrade = beast::websocket::is_upgrade(request);
    e.last = e.upgrade || !request.keep_alive();
    out.push_back(std::move(e));
    if (out.back().last) break;
    input.remove_prefix(used);
  }
  return out;
}

struct Response {
  unsigned status = 0;
  std::string body;
};

// The responses in `bytes`, up to a 101 (after which the stream is a WebSocket). Traps on bytes
// that are not HTTP/1.1 responses.
std::vector<Response> read_responses(std::string_view bytes) {
  std::vector<Response> out;
  while (!bytes.empty()) {
    http::response_parser<http::string_body> parser;
    parser.body_limit(boost::none);
    parser.eager(true);
    beast::error_code ec;
    const std::size_t used = feed(parser, bytes, ec);  // a 101 has no body: done after its header
    if (parser.is_header_done() && parser.get().result_int() == 101) {
      out.push_back(Response{101, {}});
      break;
    }
    if (ec || !parser.is_done()) {
      fail(fmt::format("response {} is not HTTP/1.1 ({}): {}", out.size(), ec ? ec.message() : "cut short",
                       std::string(bytes.substr(0, 200))));
    }
    out.push_back(Response{parser.get().result_int(), parser.get().body()});
    bytes.remove_prefix(used);
  }
  return out;
}

// Whether a target's path (its query is not a path) names something outside the served folders:
// the server must not serve it.
bool escapes(std::string_view target) {
  return target.find("..") != std::string_view::npos || target.find('%') != std::string_view::npos ||
         target.find('\\') != std::string_view::npos || target.find("//") != std::string_view::npos;
}

void check(const Expected& request, const Response& response, std::size_t n) {
  const std::string_view path = std::string_view(request.target).substr(0, request.target.find('?'));
  auto wrong = [&](std::string_view wanted) {
    fail(fmt::format("response {} to {} {} is {}; wanted {}", n, std::string(http::to_string(request.method)),
                     request.target, response.status, wanted));
  };
  if (response.status >= 500) wrong("no server error");
  if (request.upgrade) {
    // Beast's handshake refuses an upgrade without a key (400) or of another version (426).
    const bool ok = path == "/ws" ? response.status == 101 || response.status == 400 || response.status == 426
                                  : response.status == 404;
    if (!ok) wrong("101, 400 or 426 for /ws, else 404");
    return;
  }
  if (request.method != http::verb::get) {
    if (response.status != 405) wrong("405");
    return;
  }
  if (request.target == "/health") {
    if (response.status != 200 || response.body.find("\"status\": \"ok\"") == std::string::npos)
      wrong("200 ok");
  } else if (request.target == "/metrics") {
    if (response.status != 200 || response.body.find("mtlod_requests_total") == std::string::npos)
      wrong("200 with the counters");
  } else if (response.status != 200 && response.status != 404) {
    wrong("200 or 404");
  } else if (response.status == 200 && escapes(path)) {
    wrong("404: the target reaches outside the served folders");
  }
}

}  // namespace
}  // namespace mtlod::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mtlod::fuzz;
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const std::vector<Expected> expected = read_requests(input);
  ClientSocket socket(ProcessServer::get().http_port());
  socket.send(std::span<const std::uint8_t>(data, size));
  socket.finish_sending();
  const std::vector<std::uint8_t> bytes = socket.receive_all();
  const std::vector<Response> responses =
      read_responses(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
  // After a 101 the server reads WebSocket frames: whatever the input held after the upgrade
  // request is its business (the WebSocket target fuzzes that).
  if (responses.size() != expected.size()) {
    fail(fmt::format("{} requests were answered with {} responses", expected.size(), responses.size()));
  }
  for (std::size_t i = 0; i < responses.size(); ++i) check(expected[i], responses[i], i);
  return 0;
}

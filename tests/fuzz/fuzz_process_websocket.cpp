// libFuzzer target: WebSocket messages to a real server in this process (process_harness.hpp),
// sent by a Beast client over a loopback socket to /ws on its HTTP port: the HTTP upgrade, the
// server's WebSocket session with Beast's real limits and checks, the connection, the engine and
// the replies as a client reads them. The input is server_messages' list of chunks (a flags byte,
// bit 0 set: a binary message; a 16-bit little-endian length; the message), so its seeds serve
// here too. A text message that is not UTF-8 breaks the WebSocket protocol: the client waits for
// every reply owed before sending it, and then the server closes without another reply.
#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "protocol/frame.hpp"
#include "tests/fuzz/process_harness.hpp"

namespace mtlod::fuzz {
namespace {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;

constexpr std::size_t kChunkHeaderBytes = 3;

struct Message {
  bool binary = false;
  std::string bytes;
  bool breaks_protocol = false;  // text that is not UTF-8: the server's WebSocket fails its read
};

std::vector<Message> split_messages(std::span<const std::uint8_t> input) {
  std::vector<Message> messages;
  while (input.size() >= kChunkHeaderBytes) {
    const std::size_t size =
        std::min<std::size_t>(input[1] | std::size_t{input[2]} << 8, input.size() - kChunkHeaderBytes);
    Message m;
    m.binary = (input[0] & 1) != 0;
    m.bytes.assign(reinterpret_cast<const char*>(input.data()) + kChunkHeaderBytes, size);
    m.breaks_protocol = !m.binary && !valid_utf8(m.bytes);
    messages.push_back(std::move(m));
    input = input.subspan(kChunkHeaderBytes + size);
  }
  return messages;
}

// What a message owes: a reply to its request or bad_frame (false: the last one the server reads).
bool expect_message(Transcript& transcript, const Message& m, const protocol::Limits& limits) {
  if (!m.binary) {
    transcript.expect_request(m.bytes);
    return true;
  }
  // A binary message is one whole frame: its header must announce exactly the bytes after it.
  const auto* bytes = reinterpret_cast<const std::uint8_t*>(m.bytes.data());
  if (m.bytes.size() < protocol::kFrameHeaderBytes) {
    transcript.expect_bad_frame();
    return false;
  }
  const auto header = protocol::decode_frame_header(
      std::span<const std::uint8_t, protocol::kFrameHeaderBytes>(bytes, protocol::kFrameHeaderBytes),
      limits.max_frame_bytes);
  if (!header || header->body_bytes() != m.bytes.size() - protocol::kFrameHeaderBytes) {
    transcript.expect_bad_frame();
    return false;
  }
  transcript.expect_request(
      std::string_view(m.bytes).substr(protocol::kFrameHeaderBytes, header->json_bytes));
  return true;
}

// A Beast WebSocket client whose every operation has a deadline.
class Client {
 public:
  explicit Client(std::uint16_t port) : ws_(io_) {
    auto& tcp = beast::get_lowest_layer(ws_);
    const net::ip::tcp::endpoint server(net::ip::address_v4::loopback(), port);
    beast::error_code ec = wait([&](auto done) { tcp.async_connect(server, done); });
    if (ec) fail("connecting to the WebSocket port: " + ec.message());
    // As browsers do: without it, each message sent right after another waits out the server's
    // delayed acknowledgement (40 ms).
    tcp.socket().set_option(net::ip::tcp::no_delay(true), ec);
    ec = wait([&](auto done) { ws_.async_handshake("127.0.0.1", "/ws", done); });
    if (ec) fail("the WebSocket upgrade failed: " + ec.message());
    ws_.read_message_max(0);  // replies carry meshes: no client-side limit
  }

  // false once the server has closed.
  bool send(const Message& m) {
    ws_.binary(m.binary);
    return !wait([&](auto done) { ws_.async_write(net::buffer(m.bytes), done); });
  }

  // Reads one reply; false once the server has closed.
  bool receive(Transcript& transcript) {
    beast::flat_buffer buffer;
    const beast::error_code ec = wait([&](auto done) { ws_.async_read(buffer, done); });
    if (ec) return false;
    const auto* data = static_cast<const std::uint8_t*>(buffer.data().data());
    if (ws_.got_binary()) {
      transcript.check_reply(std::span<const std::uint8_t>(data, buffer.size()));
      return true;
    }
    // A reply without a payload comes as its JSON alone, in a text message (PROTOCOL.md).
    std::vector<std::uint8_t> frame;
    protocol::append_frame(std::string_view(reinterpret_cast<const char*>(data), buffer.size()), {}, frame);
    transcript.check_reply(frame);
    return true;
  }

  // The closing handshake, every reply owed having come.
  void close() {
    (void)wait([&](auto done) { ws_.async_close(websocket::close_code::normal, done); });
  }

 private:
  template <typename Start>
  beast::error_code wait(const Start& start) {
    return complete(io_, "a WebSocket operation", start);
  }

  net::io_context io_;
  websocket::stream<beast::tcp_stream> ws_;
};

void run(const std::vector<Message>& messages, bool patient, bool& meshes) {
  const ProcessServer& server = ProcessServer::get();
  Transcript transcript(server.limits(), server.model_triangles());
  Client client(server.http_port());
  std::size_t owed = 0, answered = 0;
  bool open = true;
  auto collect = [&] {
    while (open && answered < owed) {
      open = client.receive(transcript);
      if (open) ++answered;
    }
  };
  for (const Message& m : messages) {
    if (m.breaks_protocol) {
      collect();  // every reply owed first: the failed read ends the session at once
      if (open) client.send(m);
      // Beast answers with a close frame (1007) and nothing else comes.
      if (open && client.receive(transcript)) fail("a reply came after a text message that is not UTF-8");
      open = false;
      break;
    }
    ++owed;
    const bool more = expect_message(transcript, m, server.limits());
    if (!client.send(m)) {
      open = false;
      break;
    }
    if (patient || !more) collect();
    if (!more || !open) break;
  }
  collect();
  if (open) client.close();
  transcript.check_complete();
  meshes = transcript.asked_for_meshes();
}

}  // namespace
}  // namespace mtlod::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mtlod::fuzz;
  const std::vector<Message> messages = split_messages(std::span<const std::uint8_t>(data, size));
  bool meshes = false;
  run(messages, /*patient=*/false, meshes);
  if (meshes) run(messages, /*patient=*/true, meshes);
  return 0;
}

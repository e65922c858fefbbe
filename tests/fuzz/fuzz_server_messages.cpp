// libFuzzer target: WebSocket messages, through the server's whole request path
// (server_harness.hpp), each handed to Connection::handle_message as WebSocketSession does. The
// input is a list of chunks: a flags byte (bit 0 set: a binary message), a 16-bit little-endian
// length, then the message (shorter when the input ends first). The input's end is the client
// closing the WebSocket.
#include <boost/asio/post.hpp>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "protocol/frame.hpp"
#include "tests/fuzz/server_harness.hpp"

namespace mtlod::fuzz {
namespace {

namespace net = boost::asio;

constexpr std::size_t kChunkHeaderBytes = 3;

class MessageClient final : public FuzzConnection {
 public:
  MessageClient(ConnectionArgs&& args, std::span<const std::uint8_t> input)
      : FuzzConnection(std::move(args)), input_(input) {}

 private:
  std::shared_ptr<MessageClient> shared_self() {
    return std::static_pointer_cast<MessageClient>(shared_from_this());
  }

  void read() override {
    if (!may_read_next()) return;
    net::post(strand(),
              [self = shared_self()] { self->guarded("websocket read", [&] { self->on_message(); }); });
  }

  void on_message() {
    if (transport_closed_ || input_.size() < kChunkHeaderBytes) return on_read_end();
    const bool binary = (input_[0] & 1) != 0;
    const std::size_t size =
        std::min<std::size_t>(input_[1] | std::size_t{input_[2]} << 8, input_.size() - kChunkHeaderBytes);
    // A buffer of the message's own size, so that a read past its end is one ASan sees.
    const std::vector<char> message(input_.begin() + kChunkHeaderBytes,
                                    input_.begin() + kChunkHeaderBytes + size);
    input_ = input_.subspan(kChunkHeaderBytes + size);
    // Beast fails a read over read_message_max (close 1009). It also fails text messages that are
    // not UTF-8; those are passed on here, since a binary frame brings any bytes to the same parser.
    if (size > std::size_t{server_.config.limits.max_frame_bytes} + protocol::kFrameHeaderBytes) {
      return on_read_end();
    }
    server_.metrics.bytes_in(size);
    if (ending()) return;  // draining: nothing new is taken
    const std::string_view text(message.data(), message.size());
    const bool more = handle_message(!binary, text, now_ns());
    if (!more) return transcript_.expect_bad_frame();
    // A binary message that went through is a whole frame; its JSON part is the request.
    transcript_.expect_request(
        binary ? text.substr(protocol::kFrameHeaderBytes,
                             protocol::read_u32_le(reinterpret_cast<const std::uint8_t*>(message.data())))
               : text);
    read();
  }

  // A WebSocket does not half-close (WebSocketSession::stop_reading): reads go on and are dropped.
  void stop_reading() override {}

  std::span<const std::uint8_t> input_;
};

}  // namespace
}  // namespace mtlod::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mtlod;
  fuzz::FuzzServer::get().run([&](fuzz::ConnectionArgs&& args) {
    return std::make_shared<fuzz::MessageClient>(std::move(args), std::span<const std::uint8_t>(data, size));
  });
  return 0;
}

// libFuzzer target: the bytes a TCP client sends, through the server's whole request path
// (server_harness.hpp: framing, parsing, the model, real extractions, replies). The input is read
// as TcpSession reads its socket: an 8-byte header through Connection::frame_header, then the
// body, then handle_frame with its JSON part; the input's end is the client closing its side,
// wherever it falls.
#include <boost/asio/post.hpp>

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

class StreamClient final : public FuzzConnection {
 public:
  StreamClient(ConnectionArgs&& args, std::span<const std::uint8_t> input)
      : FuzzConnection(std::move(args)), input_(input) {}

 private:
  std::shared_ptr<StreamClient> shared_self() {
    return std::static_pointer_cast<StreamClient>(shared_from_this());
  }

  void read() override {
    if (!may_read_next()) return;
    net::post(strand(), [self = shared_self()] { self->guarded("read header", [&] { self->on_header(); }); });
  }

  void on_header() {
    // A header cut short ends the read as EOF does on a socket.
    if (at_end_ || transport_closed_ || input_.size() < protocol::kFrameHeaderBytes) return on_read_end();
    if (ending()) return on_read_end();
    const auto header = frame_header(input_.first<protocol::kFrameHeaderBytes>());
    input_ = input_.subspan(protocol::kFrameHeaderBytes);
    if (!header) return transcript_.expect_bad_frame();
    net::post(strand(), [self = shared_self(), header = *header] {
      self->guarded("read body", [&] { self->on_body(header); });
    });
  }

  void on_body(const protocol::FrameHeader& header) {
    if (at_end_ || transport_closed_ || input_.size() < header.body_bytes()) return on_read_end();
    server_.metrics.bytes_in(header.body_bytes());
    // The JSON in a buffer of its own size, so that a read past its end is one ASan sees.
    const std::vector<char> json(input_.begin(), input_.begin() + header.json_bytes);
    input_ = input_.subspan(header.body_bytes());
    const std::string_view text(json.data(), json.size());
    transcript_.expect_request(text);
    handle_frame(text, now_ns());
    read();
  }

  // As shutdown(receive) does to a socket: the pending read ends.
  void stop_reading() override { at_end_ = true; }

  std::span<const std::uint8_t> input_;
  bool at_end_ = false;
};

}  // namespace
}  // namespace mtlod::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mtlod;
  fuzz::FuzzServer::get().run([&](fuzz::ConnectionArgs&& args) {
    return std::make_shared<fuzz::StreamClient>(std::move(args), std::span<const std::uint8_t>(data, size));
  });
  return 0;
}

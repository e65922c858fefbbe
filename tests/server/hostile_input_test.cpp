// Client bytes that are not text: request frames holding invalid UTF-8 or control bytes, over TCP,
// over the WebSocket (binary and text messages) and in plain HTTP requests. Each gets an error
// reply that is itself valid JSON text, and the server then serves a normal extract on every
// transport. (A reply quoting such bytes once made serialisation throw and ended the process.)
#include <gtest/gtest.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>

#include <random>

#include "clients/common/server_connection.hpp"
#include "core/codec/draco_decode.hpp"
#include "protocol/camera.hpp"
#include "protocol/frame.hpp"
#include "protocol/parse.hpp"
#include "protocol/text.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/server/http_client.hpp"
#include "tests/server/server_process.hpp"
#include "tests/server/test_requests.hpp"

namespace mtlod {
namespace {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = beast::websocket;
using clients::ReplyFrame;

// A request the server serves when intact: an extract of the bunny framed by its bounds. Set up
// with the suite, from the server's model_info.
std::string g_extract;

// Requests whose bytes are not valid UTF-8 or hold control characters, each with the codes a
// correct server may answer (what matters is that it answers, in valid text, and keeps serving).
std::vector<std::string> hostile_requests() {
  std::vector<std::string> out = {
      "{\"type\":\"model_info\",\"id\":1,\"model\":\"\xff\xfe\"}",
      "{\"type\":\"model_info\",\"id\":2,\"model\":\"bunny\xc3\"}",               // truncated sequence
      "{\"type\":\"model_info\",\"id\":3,\"model\":\"\xed\xa0\x80\"}",            // a surrogate
      "{\"type\":\"model_info\",\"id\":4,\"model\":\"\xc0\xaf\"}",                // overlong '/'
      "{\"type\":\"model_info\",\"id\":5,\"model\":\"a\\u0000\\n\\u001b[31m\"}",  // escaped controls
      "{\"type\":\"\xf4\x90\x80\x80\",\"id\":6}",                                 // above U+10FFFF
      "\xff{\"type\":\"ping\",\"id\":8}",
      "{\"type\":\"ping\",\"id\":9}\x80",
      // Long values are quoted in part: the cut must not split a character.
      R"({"type":"ping","id":"aéééééééééééééééééééééééééééééé"})",
      R"({"type":"ping","id":10,"x":"éééééééééééééééééééééééééééééé"})",
  };
  // A valid extract with one byte >= 0x80 written over each of several positions.
  std::mt19937 rng(21);
  for (int i = 0; i < 24; ++i) {
    std::string s(g_extract);
    s[rng() % s.size()] = static_cast<char>(0x80 + rng() % 0x80);
    out.push_back(std::move(s));
  }
  return out;
}

std::vector<std::uint8_t> frame_of(std::string_view json) {
  std::vector<std::uint8_t> frame;
  protocol::append_frame(json, {}, frame);
  return frame;
}

class HostileInputTest : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto dir = test::scratch_dir("hostile");
    const auto bunny = test::models_dir() / "bunny.ply";
    if (!std::filesystem::exists(bunny)) GTEST_SKIP() << "no " << bunny;
    server_ = new test::ServerProcess(
        {"--mesh", bunny.string(), "--cache-dir", dir.string(), "--http-port", "0", "--log-level", "debug"},
        dir);
    if (!server_->running()) return;
    auto c = clients::ServerConnection::open("127.0.0.1", server_->port());
    ASSERT_TRUE(c.ok()) << c.error().message;
    auto info = c->call(protocol::ModelInfo{"bunny"}, 1);
    ASSERT_TRUE(info.ok()) << info.error().message;
    const protocol::Extract e =
        test::framing_extract("bunny", std::get<protocol::ModelInfoReply>(info->header.reply), {64, 48}, 2);
    g_extract = protocol::to_json(protocol::Request{e}, 7);
  }
  static void TearDownTestSuite() {
    delete server_;
    server_ = nullptr;
  }
  void SetUp() override {
    if (!server_) GTEST_SKIP();
    ASSERT_TRUE(server_->running()) << server_->log();
  }

  static clients::ServerConnection connect() {
    auto c = clients::ServerConnection::open("127.0.0.1", server_->port());
    EXPECT_TRUE(c.ok()) << c.error().message;
    return std::move(*c);
  }

  // The server still serves: a fresh TCP connection gets a mesh that decodes.
  static void expect_extract_served() {
    clients::ServerConnection c = connect();
    ASSERT_TRUE(c.send_raw(frame_of(g_extract)).ok());
    auto reply = c.receive(std::chrono::seconds(60));
    ASSERT_TRUE(reply.ok()) << reply.error().message << "\n" << server_->log();
    ASSERT_TRUE(std::holds_alternative<protocol::MeshReply>(reply->header.reply)) << reply->json;
    EXPECT_TRUE(core::codec::decode_draco(reply->payload).ok());
  }

  static test::ServerProcess* server_;
};

test::ServerProcess* HostileInputTest::server_ = nullptr;

// A reply's JSON text must be valid UTF-8 without raw control characters.
void expect_text(const std::string& json) {
  EXPECT_EQ(protocol::printable(json), json) << json;
}

TEST_F(HostileInputTest, InvalidUtf8OverTcpGetsErrorRepliesInValidText) {
  clients::ServerConnection c = connect();
  for (const std::string& request : hostile_requests()) {
    ASSERT_TRUE(c.send_raw(frame_of(request)).ok());
    auto reply = c.receive(std::chrono::seconds(60));
    ASSERT_TRUE(reply.ok()) << protocol::printable(request) << ": " << reply.error().message << "\n"
                            << server_->log();
    expect_text(reply->json);
    // Some mutated extracts still parse (a byte inside a number's digits may not); all others are errors.
    if (!std::holds_alternative<protocol::MeshReply>(reply->header.reply)) {
      const auto* error = std::get_if<protocol::ErrorReply>(&reply->header.reply);
      ASSERT_NE(error, nullptr) << reply->json;
      EXPECT_FALSE(error->message.empty());
    }
  }
  // The same connection is served afterwards.
  ASSERT_TRUE(c.send_raw(frame_of(g_extract)).ok());
  auto reply = c.receive(std::chrono::seconds(60));
  ASSERT_TRUE(reply.ok()) << reply.error().message;
  EXPECT_TRUE(std::holds_alternative<protocol::MeshReply>(reply->header.reply)) << reply->json;
  expect_extract_served();
}

TEST_F(HostileInputTest, TheReportedFrameGetsBadJsonQuotingNoRawBytes) {
  clients::ServerConnection c = connect();
  ASSERT_TRUE(c.send_raw(frame_of("{\"type\":\"model_info\",\"id\":1,\"model\":\"\xff\xfe\"}")).ok());
  auto reply = c.receive(std::chrono::seconds(60));
  ASSERT_TRUE(reply.ok()) << reply.error().message << "\n" << server_->log();
  const auto* error = std::get_if<protocol::ErrorReply>(&reply->header.reply);
  ASSERT_NE(error, nullptr) << reply->json;
  EXPECT_EQ(error->code, protocol::ErrorKind::kBadJson);
  EXPECT_NE(error->message.find("\xEF\xBF\xBD"), std::string::npos) << error->message;  // U+FFFD in place
  expect_extract_served();
}

// A minimal WebSocket client (Beast, synchronous) for the server's /ws endpoint.
class WebSocketClient {
 public:
  explicit WebSocketClient(std::uint16_t port) : ws_(ioc_) {
    net::ip::tcp::resolver resolver(ioc_);
    net::connect(ws_.next_layer(), resolver.resolve("127.0.0.1", std::to_string(port)));
    ws_.handshake("127.0.0.1", "/ws");
  }
  void send_text(std::string_view text) {
    ws_.text(true);
    ws_.write(net::buffer(text));
  }
  void send_frame(std::string_view json) {
    ws_.binary(true);
    ws_.write(net::buffer(frame_of(json)));
  }
  // The next message as a reply frame (text: JSON only; binary: a whole frame).
  Result<ReplyFrame> receive() {
    beast::flat_buffer buffer;
    beast::error_code ec;
    ws_.read(buffer, ec);
    if (ec) return make_error(ErrorCode::kIoError, ec.message());
    return test::reply_from_message(ws_.got_text(), beast::buffers_to_string(buffer.data()));
  }

 private:
  net::io_context ioc_;
  websocket::stream<net::ip::tcp::socket> ws_;
};

TEST_F(HostileInputTest, InvalidUtf8OverWebSocketGetsErrorRepliesAndAnExtractFollows) {
  ASSERT_NE(server_->http_port(), 0);
  WebSocketClient ws(server_->http_port());
  for (const std::string& request : hostile_requests()) {
    ws.send_frame(request);  // binary messages carry any bytes
    auto reply = ws.receive();
    ASSERT_TRUE(reply.ok()) << protocol::printable(request) << ": " << reply.error().message << "\n"
                            << server_->log();
    expect_text(reply->json);
  }
  ws.send_text(g_extract);
  auto mesh = ws.receive();
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  ASSERT_TRUE(std::holds_alternative<protocol::MeshReply>(mesh->header.reply)) << mesh->json;
  EXPECT_TRUE(core::codec::decode_draco(mesh->payload).ok());

  // A text message that is not UTF-8 breaks the WebSocket protocol: that connection ends, no other.
  WebSocketClient broken(server_->http_port());
  broken.send_text("{\"type\":\"ping\",\"id\":1,\"x\":\"\xff\"}");
  EXPECT_FALSE(broken.receive().ok());
  expect_extract_served();
}

TEST_F(HostileInputTest, HttpRequestsWithRawBytesAreAnsweredInText) {
  ASSERT_NE(server_->http_port(), 0);
  const test::HttpReply reply =
      test::http_request(server_->http_port(),
                         "GET /\xff\xfe\x1b[2J.js HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
  EXPECT_NE(reply.status, 200);
  EXPECT_EQ(protocol::printable(reply.body), reply.body);
  static constexpr char kGarbage[] = "\x80\xff\x00\x01 / HTTP/1.1\r\n\r\n";
  const test::HttpReply garbage =
      test::http_request(server_->http_port(), std::string(kGarbage, sizeof kGarbage - 1));
  EXPECT_NE(garbage.status, 200);
  EXPECT_EQ(test::http_get(server_->http_port(), "/health").status, 200);
  expect_extract_served();
}

}  // namespace
}  // namespace mtlod

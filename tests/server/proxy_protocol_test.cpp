// PROXY protocol v2 against the real server (--proxy-protocol-from): a trusted peer's header names
// the client, and the per-address cap then counts that client, on the protocol port and on the
// WebSocket port, in plain TCP and under TLS; LOCAL is the balancer's own connection; a malformed,
// partial or late header is refused with its reason in the log while everyone else is served; an
// untrusted peer is served on its own address and may not send a header at all. Headers are
// written byte by byte here from HAProxy's doc/proxy-protocol.txt, not by the server's parser.
// Client addresses are played with sources in 127.0.0.0/8.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <openssl/x509v3.h>
#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/read.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>

#include <cerrno>
#include <cstring>
#include <thread>

#include "core/codec/draco_decode.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/server/raw_client.hpp"
#include "tests/server/raw_websocket.hpp"
#include "tests/server/server_process.hpp"
#include "tests/server/test_requests.hpp"
#include "tests/server/tls_support.hpp"

namespace mtlod {
namespace {

using test::RawClient;
using namespace std::chrono_literals;

// ---- Headers, from the specification ----

const std::string kSignature("\x0D\x0A\x0D\x0A\x00\x0D\x0A\x51\x55\x49\x54\x0A", 12);

// Signature, version and command, family and transport, the block's length (big-endian), the block.
std::string proxy_header(std::uint8_t version_command, std::uint8_t family_transport,
                         const std::string& block) {
  std::string out = kSignature;
  out += static_cast<char>(version_command);
  out += static_cast<char>(family_transport);
  out += static_cast<char>(block.size() >> 8);
  out += static_cast<char>(block.size() & 0xFF);
  return out + block;
}
std::string port_bytes(std::uint16_t port) {
  return {static_cast<char>(port >> 8), static_cast<char>(port & 0xFF)};
}
// PROXY, TCP over IPv4, from `source` (the client the balancer speaks for) to 127.0.0.1:7878.
std::string proxy_v4(const std::string& source, std::uint16_t source_port = 40000) {
  in_addr from{}, to{};
  ::inet_pton(AF_INET, source.c_str(), &from);
  ::inet_pton(AF_INET, "127.0.0.1", &to);
  return proxy_header(0x21, 0x11,
                      std::string(reinterpret_cast<const char*>(&from), 4) +
                          std::string(reinterpret_cast<const char*>(&to), 4) + port_bytes(source_port) +
                          port_bytes(7878));
}
// PROXY, TCP over IPv6, from `source` to [::1]:7878.
std::string proxy_v6(const std::string& source) {
  in6_addr from{}, to{};
  ::inet_pton(AF_INET6, source.c_str(), &from);
  ::inet_pton(AF_INET6, "::1", &to);
  return proxy_header(0x21, 0x21,
                      std::string(reinterpret_cast<const char*>(&from), 16) +
                          std::string(reinterpret_cast<const char*>(&to), 16) + port_bytes(40000) +
                          port_bytes(7878));
}
// LOCAL, as HAProxy's health checks send it (check-send-proxy).
std::string proxy_local() {
  return proxy_header(0x20, 0x00, "");
}

std::string hello_frame(std::uint64_t id = 1) {
  return RawClient::frame(
      protocol::to_json(protocol::Hello{protocol::kProtocolVersion, "proxy-test", ""}, id));
}
std::string hello_json() {
  return protocol::to_json(protocol::Hello{protocol::kProtocolVersion, "proxy-test", ""}, 1);
}

// Whether the next reply is a hello reply.
bool hello_answered(const RawClient& c) {
  const auto reply = c.receive();
  return reply && std::holds_alternative<protocol::HelloReply>(reply->parsed.reply);
}
// The message of the limit_exceeded error that refuses a connection, or "" for anything else.
std::string refusal(const RawClient& c) {
  const auto reply = c.receive();
  if (!reply) return "";
  const auto* error = std::get_if<protocol::ErrorReply>(&reply->parsed.reply);
  return error && error->code == protocol::ErrorKind::kLimitExceeded ? error->message : "";
}

// Waits (up to 20 s) for `text` to appear in the server's log.
bool log_shows(const test::ServerProcess& server, const std::string& text) {
  for (int i = 0; i < 200; ++i) {
    if (server.log().find(text) != std::string::npos) return true;
    std::this_thread::sleep_for(100ms);
  }
  return false;
}

// ---- One server: bunny, HTTP on, balancers in 127.0.0.0/29, two connections per address ----

// Trusted peers are 127.0.0.0 to 127.0.0.7; each test uses its own so that slots a test releases
// asynchronously cannot touch another's counts. Untrusted peers are 127.0.0.9 and above.
constexpr char kBalancer[] = "127.0.0.1";

class ProxyProtocolTest : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto bunny = test::models_dir() / "bunny.ply";
    if (!std::filesystem::exists(bunny)) return;
    dir_ = new std::filesystem::path(test::scratch_dir("proxy-protocol"));
    server_ =
        new test::ServerProcess({"--mesh", bunny.string(), "--cache-dir", dir_->string(), "--http-port", "0",
                                 "--proxy-protocol-from", "127.0.0.0/29", "--max-connections-per-address",
                                 "2", "--first-frame-timeout-ms", "1500", "--log-level", "info"},
                                *dir_);
  }
  static void TearDownTestSuite() {
    delete server_;
    server_ = nullptr;
  }
  void SetUp() override {
    if (!server_) GTEST_SKIP() << "no built-in bunny";
    ASSERT_TRUE(server_->running()) << server_->log();
    ASSERT_NE(server_->http_port(), 0);
  }
  static std::uint16_t port() { return server_->port(); }
  static std::uint16_t http_port() { return server_->http_port(); }

  static test::ServerProcess* server_;
  static std::filesystem::path* dir_;
};

test::ServerProcess* ProxyProtocolTest::server_ = nullptr;
std::filesystem::path* ProxyProtocolTest::dir_ = nullptr;

TEST_F(ProxyProtocolTest, TheHeadersSourceIsTheAddressTheCapCounts) {
  RawClient a(kBalancer, port()), b(kBalancer, port());
  ASSERT_TRUE(a.send(proxy_v4("203.0.113.7") + hello_frame()));
  ASSERT_TRUE(hello_answered(a));
  ASSERT_TRUE(b.send(proxy_v4("203.0.113.7", 40001) + hello_frame()));
  ASSERT_TRUE(hello_answered(b));
  // A third connection claiming the same client is over its cap of 2...
  // (Only the header: a refused socket closed with unread bytes in it would be reset, which may
  // overtake the refusal frame.)
  RawClient c(kBalancer, port());
  ASSERT_TRUE(c.send(proxy_v4("203.0.113.7", 40002)));
  const std::string why = refusal(c);
  EXPECT_NE(why.find("203.0.113.7 holds 2 connections"), std::string::npos) << why;
  EXPECT_TRUE(c.closed_by_server(10s));
  // ...while another client behind the same balancer is served, though the balancer's own address
  // now holds more connections than the cap.
  RawClient d(kBalancer, port());
  ASSERT_TRUE(d.send(proxy_v4("198.51.100.9") + hello_frame()));
  EXPECT_TRUE(hello_answered(d));
  EXPECT_TRUE(a.send_request(protocol::Ping{}, 2));
  const auto pong = a.receive();
  ASSERT_TRUE(pong);
  EXPECT_TRUE(std::holds_alternative<protocol::Pong>(pong->parsed.reply)) << pong->json;
  EXPECT_TRUE(log_shows(*server_, "from 203.0.113.7 refused: 203.0.113.7 holds 2 connections"));
  EXPECT_EQ(server_->log().find("127.0.0.1 holds"), std::string::npos) << server_->log();
}

TEST_F(ProxyProtocolTest, Ipv6SourcesCountAndMappedIpv4IsIpv4) {
  RawClient a("127.0.0.2", port()), b("127.0.0.2", port()), c("127.0.0.2", port());
  ASSERT_TRUE(a.send(proxy_v6("2001:db8::7") + hello_frame()));
  ASSERT_TRUE(b.send(proxy_v6("2001:db8::7") + hello_frame()));
  ASSERT_TRUE(hello_answered(a));
  ASSERT_TRUE(hello_answered(b));
  ASSERT_TRUE(c.send(proxy_v6("2001:db8::7")));
  const std::string why = refusal(c);
  EXPECT_NE(why.find("2001:db8::7 holds 2 connections"), std::string::npos) << why;

  // ::ffff:203.0.113.8 is the client 203.0.113.8, whichever way the balancer writes it.
  RawClient mapped("127.0.0.2", port()), plain("127.0.0.2", port()), third("127.0.0.2", port());
  ASSERT_TRUE(mapped.send(proxy_v6("::ffff:203.0.113.8") + hello_frame()));
  ASSERT_TRUE(hello_answered(mapped));
  ASSERT_TRUE(plain.send(proxy_v4("203.0.113.8") + hello_frame()));
  ASSERT_TRUE(hello_answered(plain));
  ASSERT_TRUE(third.send(proxy_v4("203.0.113.8")));
  const std::string why_mapped = refusal(third);
  EXPECT_NE(why_mapped.find("203.0.113.8 holds 2 connections"), std::string::npos) << why_mapped;
}

TEST_F(ProxyProtocolTest, ReadsExactlyTheHeaderHoweverItArrives) {
  // Header, hello and a ping in one write: the frames right after the header are the client's.
  {
    RawClient c("127.0.0.3", port());
    ASSERT_TRUE(c.send(proxy_v4("203.0.113.20") + hello_frame(1) +
                       RawClient::frame(protocol::to_json(protocol::Ping{}, 2))));
    EXPECT_TRUE(hello_answered(c));
    const auto pong = c.receive();
    ASSERT_TRUE(pong);
    EXPECT_TRUE(std::holds_alternative<protocol::Pong>(pong->parsed.reply)) << pong->json;
  }
  // Split at every byte of the header (each connection a client of its own, so that the ones
  // closing meanwhile hold no slot that matters).
  const std::string header_template = proxy_v4("203.0.113.21");
  for (std::size_t split = 1; split < header_template.size(); ++split) {
    const std::string header = proxy_v4("203.0.113." + std::to_string(100 + split));
    RawClient c("127.0.0.3", port());
    ASSERT_TRUE(c.send(header.substr(0, split)));
    std::this_thread::sleep_for(5ms);  // makes a separate segment likely; either way must work
    ASSERT_TRUE(c.send(header.substr(split) + hello_frame()));
    EXPECT_TRUE(hello_answered(c)) << "split at " << split;
  }
  // TLVs after the address block are skipped, however long.
  std::string with_tlvs = proxy_v4("203.0.113.22").substr(16);
  with_tlvs += std::string("\x01\x00\x02h2", 5) + std::string("\x04\x00\x40", 3) + std::string(64, '\0');
  RawClient tlv("127.0.0.3", port());
  ASSERT_TRUE(tlv.send(proxy_header(0x21, 0x11, with_tlvs) + hello_frame()));
  EXPECT_TRUE(hello_answered(tlv));

  // And a proxied connection is served as any other: an extraction, decoded.
  RawClient e("127.0.0.3", port());
  ASSERT_TRUE(e.send(proxy_v4("203.0.113.23")));
  ASSERT_TRUE(e.send_request(protocol::ModelInfo{"bunny"}, 1));
  const auto info = e.receive();
  ASSERT_TRUE(info);
  const auto* model = std::get_if<protocol::ModelInfoReply>(&info->parsed.reply);
  ASSERT_NE(model, nullptr) << info->json;
  ASSERT_TRUE(e.send_request(test::framing_extract("bunny", *model, {64, 48}, 2), 2));
  const auto mesh = e.receive(60s);
  ASSERT_TRUE(mesh);
  ASSERT_TRUE(std::holds_alternative<protocol::MeshReply>(mesh->parsed.reply)) << mesh->json;
  const auto decoded = core::codec::decode_draco(mesh->payload);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  EXPECT_EQ(decoded->mesh.triangle_count(), std::get<protocol::MeshReply>(mesh->parsed.reply).triangles);
}

TEST_F(ProxyProtocolTest, MalformedOrPartialHeadersAreRefusedWithTheirReason) {
  std::string version1 = proxy_v4("203.0.113.30"), command3 = version1, udp = version1;
  version1[12] = 0x11;
  command3[12] = 0x23;
  udp[13] = 0x12;
  struct Case {
    std::string bytes, logged;
  };
  const std::vector<Case> cases{
      {hello_frame(), "PROXY header: no PROXY protocol v2 signature: byte 0 is 0x"},
      {"PROXY TCP4 203.0.113.30 127.0.0.1 40000 7878\r\n", "no PROXY protocol v2 signature: byte 0 is 0x50"},
      {version1, "PROXY header version 1: only version 2 is accepted"},
      {command3, "PROXY header command 0x3 is unknown"},
      {udp, "transport is UDP over IPv4 (0x12)"},
      {proxy_header(0x21, 0x11, std::string(8, '\1')),
       "8 address bytes, fewer than the 12 that TCP over IPv4 needs"},
      {proxy_header(0x21, 0x11, std::string(4096, '\0')), "length 4096 exceeds the limit of 2048 bytes"},
  };
  for (const Case& c : cases) {
    RawClient client("127.0.0.1", port());
    ASSERT_TRUE(client.send(c.bytes + hello_frame()));
    // Closed without a word: the peer is a balancer that spoke wrongly, not a client to answer.
    EXPECT_EQ(client.read_until_closed(10s), std::optional<std::string>("")) << c.logged;
    EXPECT_TRUE(log_shows(*server_, c.logged)) << c.logged << "\n" << server_->log();
  }
  // A header cut short by the peer, and one that stops coming.
  {
    RawClient client("127.0.0.1", port());
    ASSERT_TRUE(client.send(proxy_v4("203.0.113.31").substr(0, 10)));
    client.close();
    EXPECT_TRUE(log_shows(*server_, "the peer closed after 10 of the header's 16 bytes")) << server_->log();
  }
  {
    RawClient client("127.0.0.1", port());
    ASSERT_TRUE(client.send(proxy_v4("203.0.113.32").substr(0, 20)));
    EXPECT_EQ(client.read_until_closed(30s), std::optional<std::string>(""));
    EXPECT_TRUE(log_shows(*server_, "no complete header within 1500 ms (20 of 28 bytes arrived)"))
        << server_->log();
  }
  // None of it stopped the server serving.
  RawClient after(kBalancer, port());
  ASSERT_TRUE(after.send(proxy_v4("203.0.113.33") + hello_frame()));
  EXPECT_TRUE(hello_answered(after));
  EXPECT_TRUE(server_->running());
}

TEST_F(ProxyProtocolTest, AnUntrustedPeerIsItselfAndCannotSendAHeader) {
  {
    RawClient spoofer("127.0.0.9", port());
    ASSERT_TRUE(spoofer.send(proxy_v4("203.0.113.50") + hello_frame()));
    EXPECT_EQ(spoofer.read_until_closed(10s), std::optional<std::string>(""));
  }
  EXPECT_TRUE(log_shows(*server_,
                        "from 127.0.0.9 refused: a PROXY protocol header from an address outside "
                        "--proxy-protocol-from"));
  {
    // The signature in two writes: the first five bytes could still be anything.
    RawClient spoofer("127.0.0.9", port());
    const std::string header = proxy_v4("203.0.113.51");
    ASSERT_TRUE(spoofer.send(header.substr(0, 5)));
    std::this_thread::sleep_for(50ms);
    ASSERT_TRUE(spoofer.send(header.substr(5) + hello_frame()));
    EXPECT_EQ(spoofer.read_until_closed(10s), std::optional<std::string>(""));
  }
  // The claimed clients were never admitted, nor logged as anyone's address.
  const std::string log = server_->log();
  EXPECT_EQ(log.find("203.0.113.50"), std::string::npos) << log;
  EXPECT_EQ(log.find("203.0.113.51"), std::string::npos) << log;

  // Without a header, an untrusted peer is served as before, capped on its own address.
  RawClient a("127.0.0.10", port()), b("127.0.0.10", port()), c("127.0.0.10", port());
  ASSERT_TRUE(a.send(hello_frame()));
  ASSERT_TRUE(b.send(hello_frame()));
  EXPECT_TRUE(hello_answered(a));
  EXPECT_TRUE(hello_answered(b));
  const std::string why = refusal(c);
  EXPECT_NE(why.find("127.0.0.10 holds 2 connections"), std::string::npos) << why;
}

TEST_F(ProxyProtocolTest, LocalIsTheBalancersOwnConnection) {
  // LOCAL carries no client: the balancer's own address is counted, whatever block follows.
  RawClient bare("127.0.0.4", port()), with_block("127.0.0.4", port());
  ASSERT_TRUE(bare.send(proxy_local() + hello_frame()));
  EXPECT_TRUE(hello_answered(bare));
  std::string local_with_block = proxy_v4("203.0.113.70");
  local_with_block[12] = 0x20;
  ASSERT_TRUE(with_block.send(local_with_block + hello_frame()));
  EXPECT_TRUE(hello_answered(with_block));
  // 203.0.113.70 was not counted, 127.0.0.4 was, twice.
  RawClient claimed("127.0.0.4", port()), third_local("127.0.0.4", port());
  ASSERT_TRUE(claimed.send(proxy_v4("203.0.113.70") + hello_frame()));
  EXPECT_TRUE(hello_answered(claimed));
  ASSERT_TRUE(third_local.send(proxy_local()));
  const std::string why = refusal(third_local);
  EXPECT_NE(why.find("127.0.0.4 holds 2 connections"), std::string::npos) << why;

  // PROXY with the UNSPEC family likewise names no client.
  RawClient u1("127.0.0.6", port()), u2("127.0.0.6", port()), u3("127.0.0.6", port());
  for (const RawClient* u : {&u1, &u2}) {
    ASSERT_TRUE(u->send(proxy_header(0x21, 0x00, "") + hello_frame()));
    EXPECT_TRUE(hello_answered(*u));
  }
  ASSERT_TRUE(u3.send(proxy_header(0x21, 0x00, "")));
  const std::string why_unspec = refusal(u3);
  EXPECT_NE(why_unspec.find("127.0.0.6 holds 2 connections"), std::string::npos) << why_unspec;
}

TEST_F(ProxyProtocolTest, TheWebSocketPortReadsTheHeaderToo) {
  // Two viewers of one client behind the balancer are upgraded and served; the third is refused.
  std::vector<test::RawWebSocket> viewers;
  for (int i = 0; i < 2; ++i) {
    viewers.emplace_back(kBalancer, http_port());
    test::RawWebSocket& ws = viewers.back();
    ASSERT_TRUE(ws.send_raw(proxy_v4("203.0.113.80", static_cast<std::uint16_t>(41000 + i))));
    ASSERT_EQ(ws.upgrade("/ws?model=bunny"), 101) << ws.head();
    ASSERT_TRUE(ws.send_text(hello_json()));
    const auto message = ws.receive();
    ASSERT_TRUE(message && message->text);
    const auto reply = protocol::parse_reply(message->payload);
    ASSERT_TRUE(reply.ok()) << message->payload;
    EXPECT_TRUE(std::holds_alternative<protocol::HelloReply>(reply->reply)) << message->payload;
  }
  test::RawWebSocket third(kBalancer, http_port());
  ASSERT_TRUE(third.send_raw(proxy_v4("203.0.113.80", 41002)));
  EXPECT_EQ(third.upgrade("/ws?model=bunny"), 503) << third.head();
  test::RawWebSocket other(kBalancer, http_port());
  ASSERT_TRUE(other.send_raw(proxy_v4("203.0.113.81")));
  EXPECT_EQ(other.upgrade("/ws"), 101) << other.head();

  // A health check as HAProxy sends it: LOCAL, then the request.
  const std::string health = "GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
  RawClient check("127.0.0.5", http_port());
  ASSERT_TRUE(check.send(proxy_local() + health));
  const auto answer = check.read_until_closed(10s);
  ASSERT_TRUE(answer);
  EXPECT_EQ(answer->rfind("HTTP/1.1 200", 0), 0u) << *answer;
  // A trusted peer without a header, and an untrusted one with a header, are closed unanswered.
  RawClient bare("127.0.0.5", http_port());
  ASSERT_TRUE(bare.send(health));
  EXPECT_EQ(bare.read_until_closed(10s), std::optional<std::string>(""));
  EXPECT_TRUE(
      log_shows(*server_, "http from 127.0.0.5 refused: PROXY header: no PROXY protocol v2 signature"));
  RawClient spoofer("127.0.0.11", http_port());
  ASSERT_TRUE(spoofer.send(proxy_v4("203.0.113.82") + health));
  EXPECT_EQ(spoofer.read_until_closed(10s), std::optional<std::string>(""));
  EXPECT_TRUE(log_shows(*server_, "http from 127.0.0.11 refused: a PROXY protocol header"));
  // The untrusted peer without one is served as always.
  RawClient plain("127.0.0.11", http_port());
  ASSERT_TRUE(plain.send(health));
  const auto plain_answer = plain.read_until_closed(10s);
  ASSERT_TRUE(plain_answer);
  EXPECT_EQ(plain_answer->rfind("HTTP/1.1 200", 0), 0u) << *plain_answer;
}

// ---- Other servers ----

std::filesystem::path cached_bunny_dir(const std::string& name) {
  return test::scratch_dir("proxy-protocol-" + name);
}

TEST(ProxyProtocol, TlsFollowsTheHeaderOnBothPorts) {
  namespace net = boost::asio;
  namespace http = boost::beast::http;
  using tcp = net::ip::tcp;
  const auto bunny = test::models_dir() / "bunny.ply";
  if (!std::filesystem::exists(bunny)) GTEST_SKIP() << "no built-in bunny";
  const auto dir = cached_bunny_dir("tls");
  const test::Certificate certificate = test::make_certificate(dir);
  test::ServerProcess server(
      {"--mesh", bunny.string(), "--cache-dir", dir.string(), "--http-port", "0", "--tls-cert",
       certificate.cert.string(), "--tls-key", certificate.key.string(), "--proxy-protocol-from", "127.0.0.1",
       "--max-connections-per-address", "1", "--log-level", "info"},
      dir);
  ASSERT_TRUE(server.running()) << server.log();

  net::io_context ioc;
  net::ssl::context context(net::ssl::context::tls_client);
  context.load_verify_file(certificate.cert.string());
  context.set_verify_mode(net::ssl::verify_peer);
  // A TLS stream over a socket from 127.0.0.1 that has sent `header` first; null when the
  // connection or the handshake failed.
  auto open = [&](std::uint16_t port,
                  const std::string& header) -> std::unique_ptr<net::ssl::stream<tcp::socket>> {
    auto stream = std::make_unique<net::ssl::stream<tcp::socket>>(ioc, context);
    boost::system::error_code ec;
    tcp::socket& socket = stream->next_layer();
    socket.connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), port), ec);
    if (ec) return nullptr;
    net::write(socket, net::buffer(header), ec);
    if (ec) return nullptr;
    X509_VERIFY_PARAM_set1_ip_asc(SSL_get0_param(stream->native_handle()), "127.0.0.1");
    stream->handshake(net::ssl::stream_base::client, ec);
    if (ec) return nullptr;
    return stream;
  };
  auto hello_over = [&](net::ssl::stream<tcp::socket>& stream) {
    boost::system::error_code ec;
    net::write(stream, net::buffer(hello_frame()), ec);
    std::array<std::uint8_t, protocol::kFrameHeaderBytes> head{};
    net::read(stream, net::buffer(head), ec);
    if (ec) return false;
    const auto decoded = protocol::decode_frame_header(head, 1 << 20);
    if (!decoded) return false;
    std::string body(decoded->body_bytes(), '\0');
    net::read(stream, net::buffer(body), ec);
    const auto reply = protocol::parse_reply(body.substr(0, decoded->json_bytes));
    return !ec && reply.ok() && std::holds_alternative<protocol::HelloReply>(reply->reply);
  };

  auto first = open(server.port(), proxy_v4("203.0.113.90"));
  ASSERT_TRUE(first) << server.log();
  EXPECT_TRUE(hello_over(*first));
  // Over TLS a refusal is a closed connection: the cap of 1 is the claimed client's.
  EXPECT_FALSE(open(server.port(), proxy_v4("203.0.113.90", 40001)));
  auto second = open(server.port(), proxy_v4("203.0.113.91"));
  ASSERT_TRUE(second) << server.log();
  EXPECT_TRUE(hello_over(*second));
  EXPECT_TRUE(log_shows(server, "from 203.0.113.90 refused: 203.0.113.90 holds 1 connections"));

  // HTTPS: the header, then TLS, then the request.
  auto https = open(server.http_port(), proxy_v4("203.0.113.92"));
  ASSERT_TRUE(https) << server.log();
  http::request<http::empty_body> request{http::verb::get, "/health", 11};
  request.set(http::field::host, "127.0.0.1");
  http::write(*https, request);
  boost::beast::flat_buffer buffer;
  http::response<http::string_body> response;
  http::read(*https, buffer, response);
  EXPECT_EQ(response.result_int(), 200);
  EXPECT_NE(response.body().find("\"status\": \"ok\""), std::string::npos) << response.body();
}

TEST(ProxyProtocol, AnIpv4MappedPeerMatchesIpv4NetworksOnADualStackListener) {
  const auto bunny = test::models_dir() / "bunny.ply";
  if (!std::filesystem::exists(bunny)) GTEST_SKIP() << "no built-in bunny";
  const auto dir = cached_bunny_dir("dual-stack");
  test::ServerProcess server(
      {"--mesh", bunny.string(), "--cache-dir", dir.string(), "--host", "::", "--proxy-protocol-from",
       "127.0.0.0/8", "--max-connections-per-address", "1", "--log-level", "info"},
      dir);
  ASSERT_TRUE(server.running()) << server.log();
  // The listener sees ::ffff:127.0.0.1, which the IPv4 network holds.
  RawClient a("127.0.0.1", server.port()), b("127.0.0.1", server.port());
  ASSERT_TRUE(a.send(proxy_v4("203.0.113.95") + hello_frame()));
  EXPECT_TRUE(hello_answered(a));
  ASSERT_TRUE(b.send(proxy_v4("203.0.113.95")));
  const std::string why = refusal(b);
  EXPECT_NE(why.find("203.0.113.95 holds 1 connections"), std::string::npos) << why;
  // ::1 is in no trusted network: its header is refused.
  const int fd = ::socket(AF_INET6, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in6 to{};
  to.sin6_family = AF_INET6;
  to.sin6_port = htons(server.port());
  to.sin6_addr = in6addr_loopback;
  ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof to), 0);
  const std::string spoof = proxy_v4("203.0.113.96") + hello_frame();
  ASSERT_EQ(::send(fd, spoof.data(), spoof.size(), MSG_NOSIGNAL), static_cast<ssize_t>(spoof.size()));
  timeval timeout{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  // Closed without a reply: an end of stream, or a reset for the bytes left unread.
  char byte;
  const ssize_t n = ::recv(fd, &byte, 1, 0);
  EXPECT_TRUE(n == 0 || (n < 0 && errno == ECONNRESET)) << n << " " << std::strerror(errno);
  ::close(fd);
  EXPECT_TRUE(log_shows(server, "from ::1 refused: a PROXY protocol header from an address outside"));
}

TEST(ProxyProtocol, ABadNetworkStopsTheServerWithItsReason) {
  const auto bunny = test::models_dir() / "bunny.ply";
  if (!std::filesystem::exists(bunny)) GTEST_SKIP() << "no built-in bunny";
  const auto dir = cached_bunny_dir("bad-network");
  struct Case {
    std::string network, reason;
  };
  for (const Case& c : {Case{"10.0.0.1/8", "'10.0.0.1/8': the address has bits set past the /8 prefix"},
                        Case{"banana", "'banana': not an IPv4 or IPv6 address"},
                        Case{"::1/129", "'::1/129': the prefix length must be 0 to 128"}}) {
    test::ServerProcess server({"--mesh", bunny.string(), "--cache-dir", dir.string(),
                                "--proxy-protocol-from", c.network, "--log-level", "info"},
                               dir);
    EXPECT_FALSE(server.running()) << c.network;
    EXPECT_NE(server.log().find(c.reason), std::string::npos) << server.log();
    std::filesystem::remove(dir / "server.log");
  }
}

}  // namespace
}  // namespace mtlod

// TLS and access tokens against the real server (README, "TLS and access tokens"): mtlod-server with
// --tls-cert, --tls-key and --auth-tokens, a certificate made by openssl for this run, and two
// models ("bunny", and the same mesh as "hare"). Clients over TLS with a token are served; plain
// clients fail their handshake and nothing else notices; requests before a valid token are all
// `unauthorized`; a token limited to one model sees no other; the WebSocket checks its token in
// the upgrade (401 otherwise). Bad certificate, key and tokens files stop the server at start.
#include <gtest/gtest.h>

#include <openssl/x509v3.h>
#include <boost/asio/connect.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/ssl.hpp>
#include <boost/beast/websocket.hpp>
#include <boost/beast/websocket/ssl.hpp>

#include "clients/common/retry.hpp"
#include "clients/common/server_connection.hpp"
#include "core/codec/draco_decode.hpp"
#include "protocol/camera.hpp"
#include "protocol/frame.hpp"
#include "protocol/parse.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/server/http_client.hpp"
#include "tests/server/https_client.hpp"
#include "tests/server/raw_client.hpp"
#include "tests/server/server_process.hpp"
#include "tests/server/test_requests.hpp"
#include "tests/server/tls_support.hpp"

namespace mtlod {
namespace {

namespace net = boost::asio;
namespace ssl = net::ssl;
namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
using clients::ReplyFrame;
using namespace std::chrono_literals;

constexpr std::uint32_t kFirstFrameTimeoutMs = 1500;

struct Fixture {
  std::filesystem::path dir;
  test::Certificate certificate;
  std::unique_ptr<test::ServerProcess> server;
};
Fixture* g_fixture = nullptr;

class TlsTest : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto bunny = test::models_dir() / "bunny.ply";
    if (!std::filesystem::exists(bunny)) GTEST_SKIP() << "no " << bunny;
    g_fixture = new Fixture;
    g_fixture->dir = test::scratch_dir("tls");
    const auto& dir = g_fixture->dir;
    std::filesystem::copy_file(bunny, dir / "bunny.ply");
    std::filesystem::copy_file(bunny, dir / "hare.ply");
    g_fixture->certificate = test::make_certificate(dir);
    g_fixture->server = std::make_unique<test::ServerProcess>(
        std::vector<std::string>{
            "--mesh", (dir / "bunny.ply").string(), (dir / "hare.ply").string(), "--cache-dir", dir.string(),
            "--http-port", "0", "--tls-cert", g_fixture->certificate.cert.string(), "--tls-key",
            g_fixture->certificate.key.string(), "--auth-tokens", test::write_tokens(dir).string(),
            "--first-frame-timeout-ms", std::to_string(kFirstFrameTimeoutMs), "--log-level", "debug"},
        dir);
  }
  static void TearDownTestSuite() {
    delete g_fixture;
    g_fixture = nullptr;
  }
  void SetUp() override {
    if (!g_fixture) GTEST_SKIP();
    ASSERT_TRUE(server().running()) << server().log();
  }

  static test::ServerProcess& server() { return *g_fixture->server; }
  static clients::TlsOptions tls() { return {true, g_fixture->certificate.cert.string()}; }

  // A TLS connection that has said hello with `token` (empty: no hello at all).
  static clients::ServerConnection open(const std::string& token) {
    auto c = clients::ServerConnection::open("127.0.0.1", server().port(), 5s, tls());
    EXPECT_TRUE(c.ok()) << c.error().message << "\n" << server().log();
    if (!c.ok()) return {};
    if (!token.empty()) {
      auto hello = c->call(protocol::Hello{protocol::kProtocolVersion, "tls-test", token}, 0);
      EXPECT_TRUE(hello.ok() && std::holds_alternative<protocol::HelloReply>(hello->header.reply))
          << (hello.ok() ? hello->json : hello.error().message);
    }
    return std::move(*c);
  }

  // An extract of `model` framed by its bounds, as the connection's token allows it to ask.
  static protocol::Extract extract_of(clients::ServerConnection& c, const std::string& model) {
    auto info = c.call(protocol::ModelInfo{model}, 100);
    EXPECT_TRUE(info.ok()) << info.error().message;
    const auto* m = info.ok() ? std::get_if<protocol::ModelInfoReply>(&info->header.reply) : nullptr;
    EXPECT_NE(m, nullptr) << (info.ok() ? info->json : "");
    return test::framing_extract(model, m ? *m : protocol::ModelInfoReply{}, {64, 48}, 2);
  }

  static void expect_mesh(const Result<ReplyFrame>& reply) {
    ASSERT_TRUE(reply.ok()) << reply.error().message << "\n" << server().log();
    const auto* mesh = std::get_if<protocol::MeshReply>(&reply->header.reply);
    ASSERT_NE(mesh, nullptr) << reply->json;
    EXPECT_GT(mesh->triangles, 0u);
    auto decoded = core::codec::decode_draco(reply->payload);
    ASSERT_TRUE(decoded.ok()) << decoded.error().message;
    EXPECT_EQ(decoded->mesh.triangle_count(), mesh->triangles);
  }

  static void expect_error(const Result<ReplyFrame>& reply, protocol::ErrorKind code,
                           const std::string& text) {
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    const auto* error = std::get_if<protocol::ErrorReply>(&reply->header.reply);
    ASSERT_NE(error, nullptr) << reply->json;
    EXPECT_EQ(error->code, code) << reply->json;
    EXPECT_NE(error->message.find(text), std::string::npos) << error->message;
  }

  // The server still serves a TLS client with a token.
  static void expect_served() {
    clients::ServerConnection c = open(test::kEveryModelToken);
    expect_mesh(c.call(extract_of(c, "bunny"), 1, 60s));
  }
};

TEST_F(TlsTest, ClientOverTlsWithATokenGetsAnExtractThatDecodes) {
  clients::ServerConnection c = open("");
  auto hello = c.call(protocol::Hello{protocol::kProtocolVersion, "tls-test", test::kEveryModelToken}, 1);
  ASSERT_TRUE(hello.ok()) << hello.error().message;
  const auto* reply = std::get_if<protocol::HelloReply>(&hello->header.reply);
  ASSERT_NE(reply, nullptr) << hello->json;
  EXPECT_TRUE(reply->auth_required);
  expect_mesh(c.call(extract_of(c, "bunny"), 2, 60s));
}

TEST_F(TlsTest, ASessionOpensWithTheEndpointsTokenAndAWrongOneFailsAtOnce) {
  std::mt19937_64 rng(1);
  clients::RetryPolicy policy;
  policy.attempts = 5;
  clients::Endpoint endpoint{"127.0.0.1", server().port(), tls(), test::kEveryModelToken};
  unsigned tries = 0;
  auto session = clients::open_session(endpoint, "tls-test", policy, rng, &tries);
  ASSERT_TRUE(session.ok()) << session.error().message;
  EXPECT_TRUE(session->hello.auth_required);
  EXPECT_EQ(tries, 1u);

  endpoint.token = "not-the-token-0123456789";
  auto refused = clients::open_session(endpoint, "tls-test", policy, rng, &tries);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(tries, 1u);  // a refused token is not tried again
  EXPECT_EQ(refused.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(refused.error().message.find("unauthorized"), std::string::npos) << refused.error().message;
}

TEST_F(TlsTest, WithoutATokenEveryRequestIsUnauthorized) {
  clients::ServerConnection c = open("");
  protocol::Extract extract;
  extract.model = "bunny";
  protocol::look_at_camera(protocol::frame_bounds({-1, -1, -1}, {1, 1, 1}), 4.0 / 3.0, extract.view,
                           extract.projection);
  extract.error = 1;
  const std::vector<protocol::Request> requests = {
      protocol::ListModels{},
      protocol::ModelInfo{"bunny"},
      extract,
      protocol::Gaze{},
      protocol::Cancel{1},
      protocol::Stats{},
      protocol::Ping{},
      protocol::Hello{},
  };
  std::uint64_t id = 1;
  for (const protocol::Request& request : requests) {
    expect_error(c.call(request, id++), protocol::ErrorKind::kUnauthorized, "access token");
  }
  // Nothing else is looked at either: a request that would be malformed is unauthorized too.
  ASSERT_TRUE(c.send_raw([] {
                 std::vector<std::uint8_t> frame;
                 protocol::append_frame(R"({"type":"extract","id":50,"grid":[99999,1]})", {}, frame);
                 return frame;
               }())
                  .ok());
  expect_error(c.receive(), protocol::ErrorKind::kUnauthorized, "access token");
  // The same connection is served once it shows a token.
  auto hello = c.call(protocol::Hello{protocol::kProtocolVersion, "tls-test", test::kEveryModelToken}, id++);
  ASSERT_TRUE(hello.ok() && std::holds_alternative<protocol::HelloReply>(hello->header.reply))
      << (hello.ok() ? hello->json : hello.error().message);
  auto models = c.call(protocol::ListModels{}, id++);
  ASSERT_TRUE(models.ok()) << models.error().message;
  EXPECT_EQ(std::get<protocol::ModelsReply>(models->header.reply).models.size(), 2u) << models->json;
}

TEST_F(TlsTest, AWrongTokenIsUnauthorizedAndRevokesAnEarlierOne) {
  clients::ServerConnection c = open("");
  expect_error(c.call(protocol::Hello{protocol::kProtocolVersion, "tls-test", "wrong-token-0123456789"}, 1),
               protocol::ErrorKind::kUnauthorized, "not valid");
  expect_error(c.call(protocol::ListModels{}, 2), protocol::ErrorKind::kUnauthorized, "access token");
  // A valid token, then a wrong one: the wrong one counts.
  auto hello = c.call(protocol::Hello{protocol::kProtocolVersion, "tls-test", test::kEveryModelToken}, 3);
  ASSERT_TRUE(hello.ok() && std::holds_alternative<protocol::HelloReply>(hello->header.reply));
  expect_error(c.call(protocol::Hello{protocol::kProtocolVersion, "tls-test",
                                      std::string(test::kEveryModelToken) + "x"},
                      4),
               protocol::ErrorKind::kUnauthorized, "not valid");
  expect_error(c.call(protocol::Ping{}, 5), protocol::ErrorKind::kUnauthorized, "access token");
}

TEST_F(TlsTest, ATokenForOneModelSeesNoOther) {
  clients::ServerConnection c = open(test::kHareOnlyToken);
  auto models = c.call(protocol::ListModels{}, 1);
  ASSERT_TRUE(models.ok()) << models.error().message;
  const auto& listed = std::get<protocol::ModelsReply>(models->header.reply).models;
  ASSERT_EQ(listed.size(), 1u) << models->json;
  EXPECT_EQ(listed[0].name, "hare");
  // The other model behaves as one that does not exist, and the error names only what this token sees.
  expect_error(c.call(protocol::ModelInfo{"bunny"}, 2), protocol::ErrorKind::kUnknownModel, "loaded: hare");
  protocol::Extract bunny = extract_of(c, "hare");
  bunny.model = "bunny";
  expect_error(c.call(bunny, 3, 60s), protocol::ErrorKind::kUnknownModel,
               "no model named 'bunny'; loaded: hare");
  expect_mesh(c.call(extract_of(c, "hare"), 4, 60s));

  // The token for every model sees both.
  clients::ServerConnection every = open(test::kEveryModelToken);
  auto both = every.call(protocol::ListModels{}, 1);
  ASSERT_TRUE(both.ok());
  EXPECT_EQ(std::get<protocol::ModelsReply>(both->header.reply).models.size(), 2u) << both->json;
  expect_mesh(every.call(extract_of(every, "bunny"), 2, 60s));
}

TEST_F(TlsTest, APlainClientFailsItsHandshakeAndTheServerServesOn) {
  // A plain protocol client: its frame is no TLS record, so it gets no reply and the connection closes.
  test::RawClient plain("127.0.0.1", server().port());
  ASSERT_TRUE(plain.valid());
  ASSERT_TRUE(
      plain.send_request(protocol::Hello{protocol::kProtocolVersion, "plain", test::kEveryModelToken}, 1));
  EXPECT_FALSE(plain.receive(5s).has_value());
  // Plain HTTP to the HTTPS port: no HTTP answer.
  EXPECT_EQ(test::http_get(server().http_port(), "/health").status, 0);
  // The mtlod client without --tls says what went wrong.
  auto c = clients::ServerConnection::open("127.0.0.1", server().port(), 5s);
  ASSERT_TRUE(c.ok());
  EXPECT_FALSE(c->call(protocol::Ping{}, 1, 5s).ok());
  expect_served();
  EXPECT_NE(server().log().find("TLS handshake failed"), std::string::npos);
}

TEST_F(TlsTest, AConnectionThatNeverHandshakesIsClosedAtTheFirstFrameDeadline) {
  test::RawClient silent("127.0.0.1", server().port());
  ASSERT_TRUE(silent.valid());
  const auto start = std::chrono::steady_clock::now();
  EXPECT_TRUE(silent.closed_by_server(std::chrono::milliseconds(4 * kFirstFrameTimeoutMs)));
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(3 * kFirstFrameTimeoutMs));
  // Half a ClientHello, then nothing: the same.
  test::RawClient half("127.0.0.1", server().port());
  ASSERT_TRUE(half.send(std::string("\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03", 11)));
  EXPECT_TRUE(half.closed_by_server(std::chrono::milliseconds(4 * kFirstFrameTimeoutMs)));
  expect_served();
}

TEST_F(TlsTest, AClientThatDoesNotTrustTheCertificateRefusesTheServer) {
  // Another self-signed certificate as the only trusted one: the server's does not chain to it.
  const test::Certificate other = test::make_certificate(g_fixture->dir, "other");
  auto c = clients::ServerConnection::open("127.0.0.1", server().port(), 5s, {true, other.cert.string()});
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().message.find("not trusted"), std::string::npos) << c.error().message;
  // The certificate names 127.0.0.1, not localhost: a client that dialled "localhost" refuses it.
  auto named = clients::ServerConnection::open("localhost", server().port(), 5s, tls());
  if (named.ok()) {
    ADD_FAILURE() << "a certificate for 127.0.0.1 was accepted for localhost";
  } else {
    EXPECT_NE(named.error().message.find("not trusted"), std::string::npos) << named.error().message;
  }
  expect_served();
}

// A WebSocket client over TLS (Beast, synchronous) that trusts the test certificate.
class WssClient {
 public:
  WssClient() : context_(ssl::context::tls_client), ws_(ioc_, context_) {
    context_.load_verify_file(g_fixture->certificate.cert.string());
    context_.set_verify_mode(ssl::verify_peer);
    beast::get_lowest_layer(ws_).connect(
        net::ip::tcp::endpoint(net::ip::make_address("127.0.0.1"), g_fixture->server->http_port()));
    X509_VERIFY_PARAM_set1_ip_asc(SSL_get0_param(ws_.next_layer().native_handle()), "127.0.0.1");
    ws_.next_layer().handshake(ssl::stream_base::client);
  }
  // Upgrades to a WebSocket at `target`, sending `authorization` as the Authorization header when
  // given; false when the server declined.
  bool upgrade(const std::string& target, const std::string& authorization = "") {
    if (!authorization.empty()) {
      ws_.set_option(websocket::stream_base::decorator([authorization](websocket::request_type& request) {
        request.set(http::field::authorization, authorization);
      }));
    }
    beast::error_code ec;
    ws_.handshake("127.0.0.1", target, ec);
    return !ec;
  }
  Result<ReplyFrame> call(const protocol::Request& request, std::uint64_t id) {
    ws_.text(true);
    ws_.write(net::buffer(protocol::to_json(request, id)));
    beast::flat_buffer buffer;
    beast::error_code ec;
    ws_.read(buffer, ec);
    if (ec) return make_error(ErrorCode::kIoError, ec.message());
    return test::reply_from_message(ws_.got_text(), beast::buffers_to_string(buffer.data()));
  }

 private:
  net::io_context ioc_;
  ssl::context context_;
  websocket::stream<beast::ssl_stream<beast::tcp_stream>> ws_;
};

TEST_F(TlsTest, WebSocketOverTlsWithATokenGetsAnExtract) {
  // The viewer's way: the token in the query, next to ?model= (routing only).
  WssClient ws;
  ASSERT_TRUE(ws.upgrade(std::string("/ws?model=bunny&token=") + test::kEveryModelToken));
  auto hello = ws.call(protocol::Hello{protocol::kProtocolVersion, "wss-test", ""}, 1);
  ASSERT_TRUE(hello.ok()) << hello.error().message;
  ASSERT_TRUE(std::holds_alternative<protocol::HelloReply>(hello->header.reply)) << hello->json;
  clients::ServerConnection tcp = open(test::kEveryModelToken);
  expect_mesh(ws.call(extract_of(tcp, "bunny"), 2));

  // A program's way: Authorization: Bearer, with the token limited to the hare.
  WssClient hare;
  ASSERT_TRUE(hare.upgrade("/ws", std::string("Bearer ") + test::kHareOnlyToken));
  auto models = hare.call(protocol::ListModels{}, 1);
  ASSERT_TRUE(models.ok()) << models.error().message;
  ASSERT_EQ(std::get<protocol::ModelsReply>(models->header.reply).models.size(), 1u) << models->json;
  expect_error(hare.call(extract_of(tcp, "bunny"), 2), protocol::ErrorKind::kUnknownModel, "loaded: hare");
}

TEST_F(TlsTest, AWebSocketUpgradeWithoutAValidTokenGets401AndHealthStaysOpen) {
  const std::uint16_t port = server().http_port();
  const auto& ca = g_fixture->certificate.cert;
  EXPECT_EQ(test::upgrade_status(port, ca, "/ws?token=wrong-token-0123456789"), 401);
  EXPECT_EQ(test::upgrade_status(port, ca, "/ws"), 401);
  EXPECT_EQ(test::upgrade_status(port, ca, std::string("/ws?token=") + test::kEveryModelToken + "x"), 401);
  EXPECT_EQ(test::upgrade_status(port, ca, "/ws", "Bearer wrong-token-0123456789"), 401);
  const test::HttpReply refused = test::https_get(port, ca, "/ws?model=bunny",
                                                  {{"Upgrade", "websocket"},
                                                   {"Connection", "upgrade"},
                                                   {"Sec-WebSocket-Key", "dGhlIHNhbXBsZSBub25jZQ=="},
                                                   {"Sec-WebSocket-Version", "13"}});
  EXPECT_EQ(refused.status, 401);
  EXPECT_NE(refused.head.find("WWW-Authenticate: Bearer"), std::string::npos) << refused.head;
  EXPECT_NE(refused.body.find("access token"), std::string::npos) << refused.body;
  // The right token in the query, after another parameter, upgrades.
  EXPECT_EQ(test::upgrade_status(port, ca, std::string("/ws?model=bunny&token=") + test::kHareOnlyToken),
            101);

  // /health and the viewer's files answer without a token (load balancers probe /health).
  const test::HttpReply health = test::https_get(port, ca, "/health");
  EXPECT_EQ(health.status, 200);
  EXPECT_NE(health.body.find("\"status\": \"ok\""), std::string::npos) << health.body;
  EXPECT_EQ(test::https_get(port, ca, "/").status, 200);
  expect_served();
}

// ---- Start-up errors ----

// Runs the server with `args` (and a model); it must exit at once with `message` in its log.
void expect_start_fails(const std::filesystem::path& dir, std::vector<std::string> args,
                        const std::string& message) {
  const auto bunny = test::models_dir() / "bunny.ply";
  if (!std::filesystem::exists(bunny)) GTEST_SKIP() << "no " << bunny;
  args.insert(args.end(), {"--mesh", bunny.string(), "--cache-dir", dir.string()});
  test::ServerProcess server(args, dir);
  EXPECT_FALSE(server.running()) << "the server started with a bad configuration";
  EXPECT_NE(server.log().find(message), std::string::npos) << server.log();
}

TEST(TlsStartup, BadCertificateKeyOrTokensFilesStopTheServerWithAClearMessage) {
  const auto dir = test::scratch_dir("tls-startup");
  const test::Certificate good = test::make_certificate(dir, "good");
  const test::Certificate other = test::make_certificate(dir, "other");
  std::ofstream(dir / "garbage.pem") << "not a certificate\n";
  expect_start_fails(dir, {"--tls-cert", (dir / "missing.pem").string(), "--tls-key", good.key.string()},
                     "missing.pem: cannot read");
  expect_start_fails(dir, {"--tls-cert", (dir / "garbage.pem").string(), "--tls-key", good.key.string()},
                     "garbage.pem: not a PEM certificate chain");
  expect_start_fails(dir, {"--tls-cert", good.cert.string(), "--tls-key", (dir / "garbage.pem").string()},
                     "garbage.pem: not an unencrypted PEM private key");
  expect_start_fails(dir, {"--tls-cert", good.cert.string(), "--tls-key", other.key.string()},
                     "other-key.pem is not the private key of the certificate in");
  expect_start_fails(dir, {"--tls-cert", good.cert.string()}, "TLS needs both --tls-cert and --tls-key");
  std::ofstream(dir / "tokens.txt") << "too-short\n";
  expect_start_fails(dir, {"--auth-tokens", (dir / "tokens.txt").string()},
                     "tokens.txt:1: a token is 16 to 256 characters");
}

}  // namespace
}  // namespace mtlod

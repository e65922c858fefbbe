// docker/haproxy.cfg's two TLS layouts, run: HAProxy in front of one replica (both of the file's
// server lines point at it) on loopback ports, and clients that speak TLS to HAProxy with an
// access token. MTLOD_TLS=terminate: HAProxy holds the certificate and the replica is plain;
// MTLOD_TLS=passthrough: the replica holds it and HAProxy forwards the bytes (and checks /health
// over TLS). In both the protocol client and a wss client get served, and the replica checks the
// token.
#include <gtest/gtest.h>

#include <fstream>
#include <thread>

#include "clients/common/server_connection.hpp"
#include "core/codec/draco_decode.hpp"
#include "protocol/camera.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/deploy/deploy_support.hpp"
#include "tests/server/https_client.hpp"
#include "tests/server/server_process.hpp"
#include "tests/server/test_requests.hpp"
#include "tests/server/tls_support.hpp"

namespace mtlod {
namespace {

using namespace std::chrono_literals;

void run_layout(const std::string& mode) {
  const auto bunny = test::models_dir() / "bunny.ply";
  if (!std::filesystem::exists(bunny)) GTEST_SKIP() << "no " << bunny;
#ifndef MTLOD_HAPROXY_BINARY
  GTEST_SKIP() << "built without HAProxy (tests/server/tls.cmake)";
#else
  const auto dir = test::scratch_dir("tls-proxy-" + mode);
  std::filesystem::copy_file(bunny, dir / "bunny.ply");
  const test::Certificate certificate = test::make_certificate(dir);
  const bool passthrough = mode == "passthrough";

  std::vector<std::string> args = {
      "--mesh",        (dir / "bunny.ply").string(),    "--cache-dir", dir.string(), "--http-port", "0",
      "--auth-tokens", test::write_tokens(dir).string()};
  // HAProxy sends its PROXY v2 header on every connection, health checks included (haproxy.cfg).
  args.insert(args.end(), test::kBehindHaproxy.begin(), test::kBehindHaproxy.end());
  if (passthrough) {
    args.insert(args.end(), {"--tls-cert", certificate.cert.string(), "--tls-key", certificate.key.string()});
  }
  test::ServerProcess replica(args, dir);
  ASSERT_TRUE(replica.running()) << replica.log();

  // HAProxy wants the key in the certificate's file (or beside it as <file>.key).
  const auto pem = dir / "haproxy.pem";
  {
    std::ofstream out(pem);
    out << std::ifstream(certificate.cert).rdbuf() << std::ifstream(certificate.key).rdbuf();
  }
  const std::uint16_t lb_port = test::free_port(), lb_http_port = test::free_port(),
                      stats_port = test::free_port();
  auto environment = test::haproxy_environment(
      {lb_port,
       lb_http_port,
       stats_port,
       {{{replica.port(), replica.http_port()}, {replica.port(), replica.http_port()}}}});
  environment["MTLOD_TLS"] = mode;
  environment["MTLOD_TLS_CERT"] = pem.string();
  test::Child haproxy({MTLOD_HAPROXY_BINARY, "-db", "-f", MTLOD_SOURCE_DIR "/docker/haproxy.cfg"},
                      environment, dir / "haproxy.log");

  // The protocol through HAProxy, over TLS, once it listens and has checked the replica.
  const clients::TlsOptions tls{true, certificate.cert.string()};
  Result<clients::ServerConnection> c = make_error(ErrorCode::kIoError, "not tried");
  Result<clients::ReplyFrame> hello = make_error(ErrorCode::kIoError, "not tried");
  for (auto deadline = std::chrono::steady_clock::now() + 20s; std::chrono::steady_clock::now() < deadline;) {
    c = clients::ServerConnection::open("127.0.0.1", lb_port, 2s, tls);
    if (c.ok())
      hello =
          c->call(protocol::Hello{protocol::kProtocolVersion, "proxy-test", test::kEveryModelToken}, 1, 5s);
    if (c.ok() && hello.ok()) break;
    std::this_thread::sleep_for(200ms);
  }
  ASSERT_TRUE(c.ok() && hello.ok()) << (c.ok() ? hello.error().message : c.error().message) << "\n"
                                    << haproxy.log() << replica.log();
  ASSERT_TRUE(std::holds_alternative<protocol::HelloReply>(hello->header.reply)) << hello->json;
  auto info = c->call(protocol::ModelInfo{"bunny"}, 2);
  ASSERT_TRUE(info.ok()) << info.error().message;
  const protocol::Extract e =
      test::framing_extract("bunny", std::get<protocol::ModelInfoReply>(info->header.reply), {64, 48}, 2);
  auto mesh = c->call(e, 3, 60s);
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  ASSERT_TRUE(std::holds_alternative<protocol::MeshReply>(mesh->header.reply)) << mesh->json;
  EXPECT_TRUE(core::codec::decode_draco(mesh->payload).ok());

  // The token is the replica's to check, whichever side holds the certificate.
  auto stranger = clients::ServerConnection::open("127.0.0.1", lb_port, 5s, tls);
  ASSERT_TRUE(stranger.ok()) << stranger.error().message;
  auto refused = stranger->call(protocol::ListModels{}, 1);
  ASSERT_TRUE(refused.ok()) << refused.error().message;
  const auto* error = std::get_if<protocol::ErrorReply>(&refused->header.reply);
  ASSERT_NE(error, nullptr) << refused->json;
  EXPECT_EQ(error->code, protocol::ErrorKind::kUnauthorized);

  // The viewer's side: wss through HAProxy, with and without the token.
  EXPECT_EQ(test::upgrade_status(lb_http_port, certificate.cert,
                                 std::string("/ws?model=bunny&token=") + test::kEveryModelToken),
            101)
      << haproxy.log();
  EXPECT_EQ(
      test::upgrade_status(lb_http_port, certificate.cert, "/ws?model=bunny&token=wrong-token-0123456789"),
      401u);
  // HAProxy's log keeps the path and leaves the token out (HTTP mode: terminate).
  if (!passthrough) EXPECT_EQ(haproxy.log().find(test::kEveryModelToken), std::string::npos) << haproxy.log();
#endif
}

TEST(TlsProxy, HaproxyTerminatesTlsInFrontOfAPlainReplica) {
  run_layout("terminate");
}

TEST(TlsProxy, HaproxyPassesTlsThroughToAReplicaThatTerminatesIt) {
  run_layout("passthrough");
}

}  // namespace
}  // namespace mtlod

// The HTTP side of the web transport against the real server: which files are served (and which
// never are), their content types, the health endpoint, and refusals. The WebSocket itself is
// driven by the browser test (tests/clients/viewer_test.mjs).
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <fstream>

#include "tests/core/test_meshes.hpp"
#include "tests/server/http_client.hpp"
#include "tests/server/server_process.hpp"

namespace mtlod {
namespace {

using test::http_get;
using test::http_request;
using test::HttpReply;

std::string file_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class WebTest : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto dir = test::scratch_dir("web");
    const auto bunny = test::models_dir() / "bunny.ply";
    if (!std::filesystem::exists(bunny)) GTEST_SKIP() << "no " << bunny;
    server_ = new test::ServerProcess({"--mesh", bunny.string(), "--cache-dir", dir.string(), "--http-port",
                                       "0", "--max-connections", "1", "--log-level", "warn"},
                                      dir);
  }
  static void TearDownTestSuite() {
    delete server_;
    server_ = nullptr;
  }
  void SetUp() override {
    if (!server_) GTEST_SKIP();
    ASSERT_TRUE(server_->running()) << server_->log();
    ASSERT_NE(server_->http_port(), 0) << "no HTTP port in the port file";
  }
  static test::ServerProcess* server_;
};

test::ServerProcess* WebTest::server_ = nullptr;

TEST_F(WebTest, ServesTheViewerAndThreeJsFromTheSourceTree) {
  const std::string root = MTLOD_SOURCE_DIR;
  const HttpReply index = http_get(server_->http_port(), "/");
  EXPECT_EQ(index.status, 200);
  EXPECT_NE(index.head.find("Content-Type: text/html"), std::string::npos) << index.head;
  EXPECT_EQ(index.body, file_text(root + "/clients/web/index.html"));

  const HttpReply viewer = http_get(server_->http_port(), "/viewer.js?v=2");  // a query string is ignored
  EXPECT_EQ(viewer.status, 200);
  EXPECT_NE(viewer.head.find("Content-Type: text/javascript"), std::string::npos) << viewer.head;
  EXPECT_EQ(viewer.body, file_text(root + "/clients/web/viewer.js"));

  const std::string wasm = "/three/examples/jsm/libs/draco/draco_decoder.wasm";
  const HttpReply decoder = http_get(server_->http_port(), wasm);
  if (std::filesystem::exists(root + "/scripts/node_modules" + wasm)) {
    EXPECT_EQ(decoder.status, 200);
    // WebAssembly.instantiateStreaming refuses any other type.
    EXPECT_NE(decoder.head.find("Content-Type: application/wasm"), std::string::npos) << decoder.head;
    EXPECT_EQ(decoder.body, file_text(root + "/scripts/node_modules" + wasm));
  }
}

TEST_F(WebTest, HealthAnswersOkWithTheInstance) {
  const HttpReply health = http_get(server_->http_port(), "/health");
  EXPECT_EQ(health.status, 200);
  EXPECT_EQ(health.body.rfind(R"({"status": "ok", "instance": ")", 0), 0u) << health.body;
}

TEST_F(WebTest, NothingOutsideTheTwoFoldersIsServed) {
  // Each of these exists on disk relative to some folder the server reads from, or escapes it.
  for (const char* target : {"/../README.md", "/..%2fREADME.md", "/three/package.json",
                             "/three/../../README.md", "/three/examples/../package.json", "//etc/passwd",
                             "/%2e%2e/README.md", "/no-such-file.js", "/three/build", "relative.html"}) {
    EXPECT_EQ(http_get(server_->http_port(), target).status, 404) << target;
  }
}

TEST_F(WebTest, OnlyGetIsServed) {
  const HttpReply post =
      http_request(server_->http_port(),
                   "POST /health HTTP/1.1\r\nHost: x\r\nContent-Length: 2\r\nConnection: close\r\n\r\nhi");
  EXPECT_EQ(post.status, 405);
}

TEST_F(WebTest, WebSocketUpgradeOnlyAtWs) {
  const std::string upgrade =
      " HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
      "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n";
  EXPECT_EQ(http_request(server_->http_port(), "GET /elsewhere" + upgrade).status, 404);
  // At /ws the handshake succeeds: 101 with the accept key of RFC 6455's own example.
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(server_->http_port());
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  const std::string request = "GET /ws" + upgrade;
  (void)::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
  timeval timeout{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  std::string head;
  char buffer[4096];
  while (head.find("\r\n\r\n") == std::string::npos) {
    const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
    if (n <= 0) break;
    head.append(buffer, static_cast<std::size_t>(n));
  }
  EXPECT_EQ(head.substr(0, 12), "HTTP/1.1 101") << head;
  EXPECT_NE(head.find("s3pPLMBiTxaQ9kYGzzhZRbK+xOo="), std::string::npos) << head;
  // With --max-connections 1 that WebSocket is the one connection: another upgrade is refused.
  EXPECT_EQ(http_request(server_->http_port(), "GET /ws" + upgrade).status, 503);
  // A query after /ws is the same endpoint (load balancers route on ?model=): refused by the limit
  // too, not as an unknown path; /wsx is another path.
  EXPECT_EQ(http_request(server_->http_port(), "GET /ws?model=bunny" + upgrade).status, 503);
  EXPECT_EQ(http_request(server_->http_port(), "GET /wsx?model=bunny" + upgrade).status, 404);
  ::close(fd);
}

}  // namespace
}  // namespace mtlod

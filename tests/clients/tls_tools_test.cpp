// mtlod-client, mtlod-load and mtlod-gaze over TLS with an access token (--tls-ca, --token), run as a
// user would against the real server with --tls-cert, --tls-key and --auth-tokens; and what they
// say when the token is wrong.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <fstream>

#include "core/io/mesh_io.hpp"
#include "fmt/format.h"
#include "nlohmann/json.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/server/server_process.hpp"
#include "tests/server/tls_support.hpp"

namespace mtlod {
namespace {

using nlohmann::json;

class TlsToolsTest : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto bunny = test::models_dir() / "bunny.ply";
    if (!std::filesystem::exists(bunny)) GTEST_SKIP() << "no " << bunny;
    dir_ = new std::filesystem::path(test::scratch_dir("clients-tls"));
    std::filesystem::copy_file(bunny, *dir_ / "bunny.ply");
    certificate_ = new test::Certificate(test::make_certificate(*dir_));
    server_ = new test::ServerProcess(
        {"--mesh", (*dir_ / "bunny.ply").string(), "--cache-dir", dir_->string(), "--workers", "2",
         "--tls-cert", certificate_->cert.string(), "--tls-key", certificate_->key.string(), "--auth-tokens",
         test::write_tokens(*dir_).string(), "--log-level", "warn"},
        *dir_);
  }
  static void TearDownTestSuite() {
    delete server_;
    delete certificate_;
    delete dir_;
    server_ = nullptr;
  }
  void SetUp() override {
    if (!server_) GTEST_SKIP();
    ASSERT_TRUE(server_->running()) << server_->log();
  }

  struct Run {
    int status;
    std::string output;
  };
  // Runs `binary` against the server with `args` after --port.
  static Run run(const std::string& binary, const std::string& args, const std::string& environment = "") {
    const auto log = *dir_ / "tool.log";
    const std::string command =
        fmt::format("{} {} --port {} {} > {} 2>&1", environment, binary, server_->port(), args, log.string());
    const int status = std::system(command.c_str());
    std::ifstream in(log);
    return {
        WIFEXITED(status) ? WEXITSTATUS(status) : -1,
        command + "\n" + std::string{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()}};
  }
  static std::string tls_flags() { return "--tls-ca " + certificate_->cert.string(); }

  static std::filesystem::path* dir_;
  static test::Certificate* certificate_;
  static test::ServerProcess* server_;
};

std::filesystem::path* TlsToolsTest::dir_ = nullptr;
test::Certificate* TlsToolsTest::certificate_ = nullptr;
test::ServerProcess* TlsToolsTest::server_ = nullptr;

TEST_F(TlsToolsTest, ClientExtractsOverTlsWithATokenAndTheMeshDecodes) {
  const auto out = *dir_ / "bunny-tls.ply";
  const Run r =
      run(MTLOD_CLIENT_BINARY, fmt::format("{} --token {} extract bunny --error-px 2 --grid 64 -o {}",
                                           tls_flags(), test::kEveryModelToken, out.string()));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("served by"), std::string::npos) << r.output;
  auto mesh = core::io::load_mesh(out);
  ASSERT_TRUE(mesh.ok()) << mesh.error().message;
  EXPECT_GT(mesh->mesh.triangle_count(), 0u);

  // The token from the environment instead of the command line (where other users could read it).
  const Run listed =
      run(MTLOD_CLIENT_BINARY, tls_flags() + " list", fmt::format("MTLOD_TOKEN={}", test::kHareOnlyToken));
  ASSERT_EQ(listed.status, 0) << listed.output;
  EXPECT_EQ(listed.output.find("bunny "), std::string::npos) << "the hare's token sees no bunny\n"
                                                             << listed.output;
}

TEST_F(TlsToolsTest, LoadAndGazeRunOverTlsWithAToken) {
  const auto report = *dir_ / "load.json";
  const Run load = run(MTLOD_LOAD_BINARY,
                       fmt::format("{} --token {} --model bunny --connections 2 --requests 20 --duration 20 "
                                   "--budget 1500 --quiet --json {}",
                                   tls_flags(), test::kEveryModelToken, report.string()));
  ASSERT_EQ(load.status, 0) << load.output;
  const json l = json::parse(std::ifstream(report));
  EXPECT_EQ(l.at("ok"), 20) << l.dump(2);
  EXPECT_EQ(l.at("errors"), 0) << l.dump(2);

  const auto gaze_report = *dir_ / "gaze.json";
  const Run gaze = run(MTLOD_GAZE_BINARY,
                       fmt::format("{} --token {} --model bunny --streams 2 --hz 40 --duration 500 --delta "
                                   "--quiet --json {}",
                                   tls_flags(), test::kEveryModelToken, gaze_report.string()));
  ASSERT_EQ(gaze.status, 0) << gaze.output;
  const json g = json::parse(std::ifstream(gaze_report));
  EXPECT_GT(g.at("meshes").get<int>(), 0) << g.dump(2);
  EXPECT_EQ(g.at("errors"), 0) << g.dump(2);
  EXPECT_EQ(g.at("delta_errors"), 0) << g.dump(2);
}

TEST_F(TlsToolsTest, AWrongTokenIsReportedAtOnceAndAPlainClientFails) {
  const auto start = std::chrono::steady_clock::now();
  const Run wrong =
      run(MTLOD_CLIENT_BINARY, tls_flags() + " --token not-the-token-0123456789 --attempts 5 list");
  EXPECT_EQ(wrong.status, 1) << wrong.output;
  EXPECT_NE(wrong.output.find("unauthorized"), std::string::npos) << wrong.output;
  // No backing off and trying again: the same token would be refused again.
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(3));

  const Run none = run(MTLOD_LOAD_BINARY, tls_flags() + " --model bunny --requests 1 --quiet --attempts 1");
  EXPECT_EQ(none.status, 1) << none.output;
  EXPECT_NE(none.output.find("unauthorized"), std::string::npos) << none.output;

  const Run plain =
      run(MTLOD_CLIENT_BINARY, fmt::format("--token {} --attempts 1 list", test::kEveryModelToken));
  EXPECT_EQ(plain.status, 1) << plain.output;
}

}  // namespace
}  // namespace mtlod

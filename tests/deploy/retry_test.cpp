// Clients that outlive their server: mtlod-client waits for a server that is still starting, and
// a mtlod-gaze stream reconnects to a restarted server and carries on. Plus the backoff schedule.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "clients/common/retry.hpp"
#include "core/build/mt_builder.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mt_file.hpp"
#include "nlohmann/json.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/deploy/deploy_support.hpp"
#include "tests/server/server_process.hpp"

namespace mtlod {
namespace {

using namespace std::chrono_literals;

std::filesystem::path write_sphere(const std::filesystem::path& dir) {
  core::eval::GenerateOptions o;
  o.target_triangles = 4000;
  auto mt = core::build::build_mt(core::eval::generate_mesh(o));
  EXPECT_TRUE(mt.ok());
  EXPECT_TRUE(core::io::write_mt_file(dir / "sphere.mt", *mt).ok());
  return dir / "sphere.mt";
}

TEST(Backoff, GrowsGeometricallyUpToItsCapWithBoundedJitter) {
  clients::Backoff b;
  b.initial = 40ms;
  b.max = 1000ms;
  b.factor = 2;
  b.jitter = 0.25;
  std::mt19937_64 rng(7);
  for (unsigned attempt = 0; attempt < 12; ++attempt) {
    const double full = std::min(40.0 * std::pow(2.0, attempt), 1000.0);
    for (int k = 0; k < 50; ++k) {
      const auto d = b.delay(attempt, rng).count();
      EXPECT_LE(d, std::llround(full)) << attempt;
      EXPECT_GE(d, std::llround(0.75 * full) - 1) << attempt;
    }
  }
  b.jitter = 0;
  EXPECT_EQ(b.delay(0, rng).count(), 40);
  EXPECT_EQ(b.delay(3, rng).count(), 320);
  EXPECT_EQ(b.delay(30, rng).count(), 1000);
}

TEST(Retry, OpenSessionGivesUpAfterItsAttemptsWithTheReason) {
  const std::uint16_t port = test::free_port();  // nothing listens there
  clients::RetryPolicy policy;
  policy.attempts = 3;
  policy.backoff.initial = 10ms;
  std::mt19937_64 rng(1);
  unsigned tries = 0;
  auto session = clients::open_session("127.0.0.1", port, "test", policy, rng, &tries);
  ASSERT_FALSE(session.ok());
  EXPECT_EQ(tries, 3u);
  EXPECT_NE(session.error().message.find("after 3 attempts"), std::string::npos) << session.error().message;
  EXPECT_NE(session.error().message.find(std::to_string(port)), std::string::npos) << session.error().message;
}

TEST(Retry, ClientWaitsForAServerThatIsStillStarting) {
  const auto dir = test::scratch_dir("retry-client");
  const auto model = write_sphere(dir);
  const std::uint16_t port = test::free_port();
  test::Child client({MTLOD_CLIENT_BINARY, "--port", std::to_string(port), "--attempts", "30", "list"}, {},
                     dir / "client.log");
  std::this_thread::sleep_for(1500ms);
  ASSERT_TRUE(client.running()) << "the client is still trying\n" << client.log();
  test::ServerProcess server({model.string(), "--log-level", "warn"}, dir, port);
  ASSERT_TRUE(server.running()) << server.log();
  EXPECT_EQ(client.wait(30s), 0) << client.log();
  EXPECT_NE(client.log().find("sphere"), std::string::npos) << client.log();
}

// One mtlod-gaze stream on the model "sphere" at 60 Hz for `duration_ms`, patient with its server
// (40 attempts); its report goes to DIR/gaze.json, its output to DIR/gaze.log.
test::Child gaze_stream(std::uint16_t port, const std::string& duration_ms,
                        const std::filesystem::path& dir) {
  return test::Child({MTLOD_GAZE_BINARY, "--port", std::to_string(port), "--model", "sphere", "--hz", "60",
                      "--duration", duration_ms, "--attempts", "40", "--budget", "1000", "--quiet", "--json",
                      (dir / "gaze.json").string()},
                     {}, dir / "gaze.log");
}

TEST(Retry, GazeStreamReconnectsAfterItsServerIsKilledAndRestarted) {
  const auto dir = test::scratch_dir("retry-gaze");
  const auto model = write_sphere(dir);
  const std::uint16_t port = test::free_port();
  auto server = std::make_unique<test::ServerProcess>(
      std::vector<std::string>{model.string(), "--log-level", "warn"}, dir, port);
  ASSERT_TRUE(server->running()) << server->log();
  const auto report = dir / "gaze.json";
  test::Child gaze = gaze_stream(port, "6000", dir);
  std::this_thread::sleep_for(2s);
  const int status = server->stop(SIGKILL);
  EXPECT_TRUE(WIFSIGNALED(status)) << status;
  std::this_thread::sleep_for(500ms);
  server = std::make_unique<test::ServerProcess>(
      std::vector<std::string>{model.string(), "--log-level", "warn"}, dir, port);
  ASSERT_TRUE(server->running()) << server->log();
  ASSERT_EQ(gaze.wait(60s), 0) << gaze.log();
  std::ifstream in(report);
  ASSERT_TRUE(in) << gaze.log();
  const auto r = nlohmann::json::parse(in);
  // 6 s at 60 Hz: 360 samples, those where the synthetic tracker lost the eye (blinks) not sent.
  EXPECT_EQ(r.at("samples").get<int>() + r.at("tracker_lost_samples").get<int>(), 360) << r.dump(2);
  EXPECT_GE(r.at("reconnects").get<int>(), 1) << r.dump(2);
  EXPECT_EQ(r.at("lost"), 0) << r.dump(2);
  EXPECT_EQ(r.at("errors"), 0) << r.dump(2);
  EXPECT_EQ(r.at("focus_mismatches"), 0) << r.dump(2);
  // Meshes kept coming after the restart: every sample, the last one included, is shown by a mesh
  // (its own or a newer sample's).
  EXPECT_EQ(r.at("sample_latency_ms").at("count"), r.at("samples")) << r.dump(2);
}

TEST(Retry, GazeStreamSendsItsViewAgainOnceTheRestartedServerHasTheModel) {
  // The server comes back without the stream's model (its file is added 3 s after the server
  // listens, longer than the stream's longest wait between reconnection attempts, 2 s): the view's
  // extract sent on reconnecting is refused, so the stream's gazes find no view. The stream sends the
  // view again when a gaze is answered `no_view`, and meshes come back once the model is served.
  namespace fs = std::filesystem;
  const auto dir = test::scratch_dir("retry-gaze-view");
  const auto kept = write_sphere(dir);
  const auto models = dir / "models";
  fs::create_directories(models);
  fs::copy_file(kept, models / "sphere.mt");
  fs::copy_file(kept, models / "other.mt");
  const std::uint16_t port = test::free_port();
  const std::vector<std::string> args{"--models", models.string(), "--log-level", "warn"};
  auto server = std::make_unique<test::ServerProcess>(args, dir, port);
  ASSERT_TRUE(server->running()) << server->log();
  const auto report = dir / "gaze.json";
  test::Child gaze = gaze_stream(port, "10000", dir);
  std::this_thread::sleep_for(2s);
  server->stop(SIGKILL);
  fs::remove(models / "sphere.mt");
  server = std::make_unique<test::ServerProcess>(args, dir, port);
  ASSERT_TRUE(server->running()) << server->log();
  std::this_thread::sleep_for(3s);
  fs::copy_file(kept, dir / "sphere.mt.new");
  fs::rename(dir / "sphere.mt.new", models / "sphere.mt");  // added whole
  ASSERT_EQ(gaze.wait(60s), 0) << gaze.log();
  std::ifstream in(report);
  ASSERT_TRUE(in) << gaze.log();
  const auto r = nlohmann::json::parse(in);
  EXPECT_GE(r.at("reconnects").get<int>(), 1) << r.dump(2);
  EXPECT_EQ(r.at("lost"), 0) << r.dump(2);
  // The gazes of the seconds without the model, and only those, found no view. A gaze replaced by
  // a newer one before it ran (`superseded`, a slow host's normal answer) is not an error.
  for (const auto& [code, count] : r.at("errors_by_code").items()) {
    if (code != "superseded") EXPECT_EQ(code, "no_view") << count.dump();
  }
  EXPECT_GT(r.at("errors_by_code").value("no_view", 0), 0) << r.dump(2);
  // Every sample, the last one included, is shown by a mesh (its own or a newer sample's).
  EXPECT_EQ(r.at("sample_latency_ms").at("count"), r.at("samples")) << r.dump(2);
}

}  // namespace
}  // namespace mtlod

// SIGTERM drain, as an orchestrator sends it before SIGKILL: the server stops accepting at once,
// finishes the extraction in flight and writes its reply, and exits within --drain-timeout-ms even
// when a client stops reading.
#include <gtest/gtest.h>

#include <atomic>

#include "clients/common/server_connection.hpp"
#include "core/build/mt_builder.hpp"
#include "core/codec/draco_decode.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mt_file.hpp"
#include "protocol/camera.hpp"
#include "protocol/frame.hpp"
#include "protocol/parse.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/server/server_process.hpp"

namespace mtlod {
namespace {

using clients::ServerConnection;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

std::filesystem::path write_sphere(const std::filesystem::path& dir, std::size_t triangles) {
  core::eval::GenerateOptions o;
  o.target_triangles = triangles;
  auto mt = core::build::build_mt(core::eval::generate_mesh(o));
  EXPECT_TRUE(mt.ok());
  EXPECT_TRUE(core::io::write_mt_file(dir / "sphere.mt", *mt).ok());
  return dir / "sphere.mt";
}

protocol::Extract full_resolution() {
  protocol::Extract e;
  e.model = "sphere";
  protocol::look_at_camera(protocol::LookAt{}, 1.0, e.view, e.projection);
  e.error = 0;  // the whole mesh: long enough to be running when the signal comes
  return e;
}

bool log_has(const test::ServerProcess& server, const std::string& text, std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  while (Clock::now() < deadline) {
    if (server.log().find(text) != std::string::npos) return true;
    std::this_thread::sleep_for(10ms);
  }
  return server.log().find(text) != std::string::npos;
}

TEST(Drain, SigtermRefusesNewConnectionsFinishesInFlightAndExitsWithinTheBound) {
  const auto dir = test::scratch_dir("drain");
  const auto model = write_sphere(dir, 60'000);
  constexpr int kDrainMs = 3000;
  test::ServerProcess server({model.string(), "--workers", "1", "--drain-timeout-ms",
                              std::to_string(kDrainMs), "--log-level", "info"},
                             dir);
  ASSERT_TRUE(server.running()) << server.log();

  // A client that stops reading: its replies (model_info, a few hundred bytes each) fill the socket
  // buffers, so the server can never finish writing to it and only the drain bound ends it.
  auto stuck = ServerConnection::open("127.0.0.1", server.port());
  ASSERT_TRUE(stuck.ok());
  std::vector<std::uint8_t> flood;
  constexpr std::uint64_t kFlood = 100'000;  // ~40 MB of replies: far more than socket buffers hold
  for (std::uint64_t i = 1; i <= kFlood; ++i) {
    protocol::append_frame(protocol::to_json(protocol::Request{protocol::ModelInfo{"sphere"}}, i), {}, flood);
  }
  std::thread flooder([&] { (void)stuck->send_raw(flood); });
  // Stuck means the server has stopped reading from it (its replies cannot be written): the count
  // of model_info requests stands still before the whole flood is read.
  double read = -1;
  for (int i = 0; i < 300; ++i) {
    std::this_thread::sleep_for(200ms);
    auto probe = ServerConnection::open("127.0.0.1", server.port());
    ASSERT_TRUE(probe.ok());
    auto stats = probe->call(protocol::Stats{}, 1);
    ASSERT_TRUE(stats.ok());
    double now = 0;
    for (const auto& [name, value] : std::get<protocol::StatsReply>(stats->header.reply).counters) {
      if (name == "requests_model_info") now = value;
    }
    if (now > 0 && now == read) break;
    read = now;
  }
  ASSERT_GT(read, 0);
  ASSERT_LT(read, static_cast<double>(kFlood)) << "the server read the whole flood: nothing is stuck";

  auto working = ServerConnection::open("127.0.0.1", server.port());
  ASSERT_TRUE(working.ok());
  ASSERT_TRUE(working->send(full_resolution(), 1).ok());
  std::this_thread::sleep_for(50ms);
  const auto signalled = Clock::now();
  ::kill(server.pid(), SIGTERM);
  ASSERT_TRUE(log_has(server, "shutting down", 5s)) << server.log();

  // New connections are refused while the server still drains.
  std::this_thread::sleep_for(100ms);
  EXPECT_FALSE(ServerConnection::open("127.0.0.1", server.port(), 500ms).ok())
      << "a draining server accepts nothing new";
  EXPECT_TRUE(server.running()) << "the stuck client keeps the drain going until its bound\n" << server.log();

  // The extraction in flight finishes and its reply arrives whole.
  auto reply = working->receive(60s);
  ASSERT_TRUE(reply.ok()) << reply.error().message;
  const auto* mesh = std::get_if<protocol::MeshReply>(&reply->header.reply);
  ASSERT_NE(mesh, nullptr) << reply->json;
  auto decoded = core::codec::decode_draco(reply->payload);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  EXPECT_EQ(decoded->mesh.triangle_count(), mesh->triangles);

  // Exit within the bound: not before it (the stuck client owes replies), not long after.
  const int status = server.stop(0, 30s);  // signal 0: only wait
  const double exit_ms = std::chrono::duration<double, std::milli>(Clock::now() - signalled).count();
  ASSERT_TRUE(WIFEXITED(status)) << status << "\n" << server.log();
  EXPECT_EQ(WEXITSTATUS(status), 0) << server.log();
  EXPECT_GE(exit_ms, kDrainMs - 100) << server.log();
  EXPECT_LE(exit_ms, kDrainMs + 5000) << server.log();
  EXPECT_NE(server.log().find("drain timeout"), std::string::npos) << server.log();
  stuck->interrupt();
  flooder.join();
}

TEST(Drain, IdleConnectionsAreClosedAndTheServerExitsAtOnce) {
  const auto dir = test::scratch_dir("drain-idle");
  const auto model = write_sphere(dir, 2000);
  test::ServerProcess server({model.string(), "--drain-timeout-ms", "20000", "--log-level", "info"}, dir);
  ASSERT_TRUE(server.running()) << server.log();
  std::vector<ServerConnection> idle;
  for (int i = 0; i < 3; ++i) {
    auto c = ServerConnection::open("127.0.0.1", server.port());
    ASSERT_TRUE(c.ok());
    ASSERT_TRUE(c->call(protocol::Ping{}, 1).ok());
    idle.push_back(std::move(*c));
  }
  const auto signalled = Clock::now();
  const int status = server.stop(SIGTERM, 30s);
  const double exit_ms = std::chrono::duration<double, std::milli>(Clock::now() - signalled).count();
  ASSERT_TRUE(WIFEXITED(status)) << server.log();
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_LT(exit_ms, 5000) << "nothing was owed, so nothing waits for the 20 s bound\n" << server.log();
  for (ServerConnection& c : idle) EXPECT_FALSE(c.receive(2s).ok()) << "the server closed every connection";
}

}  // namespace
}  // namespace mtlod

// The fleet soak's pass/fail parts in half a minute (scripts/soak-fleet.sh runs them for 30): two
// replicas sharing one model folder behind HAProxy with docker/haproxy.cfg (PROXY protocol v2),
// gaze streams with delta replies through it on two models, while one model's file is rewritten
// in place by cp, overwritten with random bytes, restored and renamed over, and one replica is
// killed and started again. The surviving replica never stops; every delta reply applies (its
// Draco part decodes and the kept mesh matches the server's cut); no request is lost; the steady
// model's streams see no error; the changing model's see only `unavailable` or `unknown_model`
// (and `superseded`, as any gaze stream).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <memory>

#include "core/build/mt_builder.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mt_file.hpp"
#include "nlohmann/json.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/deploy/deploy_support.hpp"
#include "tests/server/http_client.hpp"
#include "tests/server/server_process.hpp"

namespace mtlod {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using namespace std::chrono_literals;

void write_model(const fs::path& path, core::eval::Shape shape, std::size_t triangles) {
  core::eval::GenerateOptions o;
  o.shape = shape;
  o.target_triangles = triangles;
  auto mt = core::build::build_mt(core::eval::generate_mesh(o));
  ASSERT_TRUE(mt.ok());
  ASSERT_TRUE(core::io::write_mt_file(path, *mt).ok());
}

bool replica_up(std::uint16_t stats_port, const std::string& server) {
  std::istringstream csv(test::http_get(stats_port, "/stats;csv").body);
  for (std::string line; std::getline(csv, line);) {
    if (line.rfind("replicas," + server + ",", 0) == 0) return line.find(",UP,") != std::string::npos;
  }
  return false;
}

template <class F>
bool eventually(F done, std::chrono::seconds limit) {
  for (const auto until = std::chrono::steady_clock::now() + limit;
       std::chrono::steady_clock::now() < until;) {
    if (done()) return true;
    std::this_thread::sleep_for(50ms);
  }
  return false;
}

json read_json(const fs::path& path) {
  std::ifstream in(path);
  return in ? json::parse(in, nullptr, false) : json::object();
}

int shell(const std::string& command) {
  return std::system(command.c_str());
}

TEST(FleetChange, ReplicasBehindHaproxySurviveFileChangesAndAKill) {
  const fs::path dir = test::scratch_dir("fleet-change");
  const fs::path models = dir / "models";
  fs::create_directories(models);
  write_model(dir / "a.mt", core::eval::Shape::kSphere, 20000);
  write_model(dir / "b.mt", core::eval::Shape::kShell, 20000);
  write_model(models / "steady.mt", core::eval::Shape::kTerrain, 20000);
  fs::copy_file(dir / "a.mt", models / "changing.mt");

  struct Replica {
    std::string name;
    std::uint16_t port, http_port;
    std::unique_ptr<test::ServerProcess> process;
  };
  std::vector<Replica> replicas;
  auto start = [&](Replica& r) {
    std::vector<std::string> args{"--models",    models.string(),
                                  "--name",      r.name,
                                  "--http-port", std::to_string(r.http_port),
                                  "--workers",   "1"};
    args.insert(args.end(), test::kBehindHaproxy.begin(), test::kBehindHaproxy.end());
    fs::create_directories(dir / r.name);
    r.process = std::make_unique<test::ServerProcess>(args, dir / r.name, r.port);
  };
  for (const char* name : {"replica-1", "replica-2"}) {
    replicas.push_back({name, test::free_port(), test::free_port(), nullptr});
    start(replicas.back());
    ASSERT_TRUE(replicas.back().process->running()) << replicas.back().process->log();
  }
  const std::uint16_t lb = test::free_port(), lb_http = test::free_port(), stats = test::free_port();
  test::Child haproxy({MTLOD_HAPROXY_BINARY, "-db", "-f", MTLOD_SOURCE_DIR "/docker/haproxy.cfg"},
                      test::haproxy_environment({lb,
                                                 lb_http,
                                                 stats,
                                                 {{{replicas[0].port, replicas[0].http_port},
                                                   {replicas[1].port, replicas[1].http_port}}}}),
                      dir / "haproxy.log");
  ASSERT_TRUE(
      eventually([&] { return replica_up(stats, "replica-1") && replica_up(stats, "replica-2"); }, 30s))
      << haproxy.log();

  auto gaze = [&](const std::string& model, const std::string& streams) {
    return std::make_unique<test::Child>(
        std::vector<std::string>{MTLOD_GAZE_BINARY, "--port", std::to_string(lb), "--model", model,
                                 "--streams", streams, "--hz", "60", "--duration", "16000", "--delta",
                                 "--json", (dir / (model + ".json")).string()},
        std::map<std::string, std::string>{}, dir / (model + ".log"));
  };
  auto changing = gaze("changing", "6");
  auto steady = gaze("steady", "4");
  std::this_thread::sleep_for(2s);

  const std::string file = (models / "changing.mt").string();
  ASSERT_EQ(shell("cp " + (dir / "b.mt").string() + " " + file), 0);
  std::this_thread::sleep_for(2s);
  ASSERT_EQ(shell("dd if=/dev/urandom of=" + file + " bs=4096 count=" +
                  std::to_string(fs::file_size(file) / 4096 + 1) + " conv=notrunc status=none"),
            0);
  std::this_thread::sleep_for(2s);
  ASSERT_EQ(shell("cp " + (dir / "a.mt").string() + " " + file), 0);
  std::this_thread::sleep_for(1s);
  // A replica killed mid-stream, started again.
  replicas[0].process->stop(SIGKILL);
  std::this_thread::sleep_for(2s);
  start(replicas[0]);
  ASSERT_TRUE(replicas[0].process->running()) << replicas[0].process->log();
  ASSERT_EQ(shell("cp " + (dir / "b.mt").string() + " " + file + ".tmp && mv " + file + ".tmp " + file), 0);

  EXPECT_EQ(changing->wait(60s), 0) << changing->log();
  EXPECT_EQ(steady->wait(60s), 0) << steady->log();
  EXPECT_TRUE(replicas[1].process->running()) << "the replica nobody killed must live\n"
                                              << replicas[1].process->log();
  EXPECT_TRUE(replicas[0].process->running()) << replicas[0].process->log();

  const json c = read_json(dir / "changing.json"), s = read_json(dir / "steady.json");
  ASSERT_TRUE(c.contains("meshes") && s.contains("meshes")) << c.dump() << s.dump();
  for (const json* r : {&c, &s}) {
    EXPECT_GT(r->at("meshes").get<std::uint64_t>(), 0u) << r->dump(2);
    EXPECT_EQ(r->at("delta_errors"), 0) << "every delta reply decodes and applies\n" << r->dump(2);
    EXPECT_EQ(r->at("lost"), 0) << r->dump(2);
  }
  EXPECT_EQ(s.at("errors"), 0) << s.dump(2);
  // Gazes a newer one replaced are answered `superseded`, as on any stream. A stream that
  // reconnects while the model is being replaced may have its view's extract refused: its gazes
  // are answered `no_view` until it has sent the view again, a few of them, not the rest of the run.
  for (const auto& [code, count] : c.at("errors_by_code").items()) {
    EXPECT_TRUE(code == "unavailable" || code == "unknown_model" || code == "superseded" || code == "no_view")
        << code << " × " << count.dump();
  }
  const std::uint64_t no_view = c.at("errors_by_code").value("no_view", std::uint64_t{0});
  EXPECT_LT(no_view, c.at("samples").get<std::uint64_t>() / 50) << c.dump(2);
}

}  // namespace
}  // namespace mtlod

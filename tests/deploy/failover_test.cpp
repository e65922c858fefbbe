// The deployment of docker/compose.yaml without Docker: two mtlod-server replicas sharing one model
// folder behind HAProxy running docker/haproxy.cfg itself, all on loopback ports. mtlod-load runs
// through HAProxy while one replica is killed (SIGKILL) and restarted, or drained (SIGTERM); its
// JSON report must show every request answered (the dropped ones retried, none lost) and traffic on
// the replicas left, and its count of meshes per replica must equal what each replica says it sent
// (nothing lost, nothing served twice). Also: /health, and clients that reconnect to a restarted
// server.
#include <gtest/gtest.h>

#include <fstream>
#include <memory>
#include <sstream>

#include "clients/common/server_connection.hpp"
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

using nlohmann::json;
using namespace std::chrono_literals;

// A generated sphere's MT in dir/models, the folder the replicas share.
std::filesystem::path write_model(const std::filesystem::path& dir, std::size_t triangles) {
  core::eval::GenerateOptions o;
  o.target_triangles = triangles;
  auto mt = core::build::build_mt(core::eval::generate_mesh(o));
  EXPECT_TRUE(mt.ok());
  std::filesystem::create_directories(dir / "models");
  EXPECT_TRUE(core::io::write_mt_file(dir / "models" / "sphere.mt", *mt).ok());
  return dir / "models";
}

// The instance a replica behind HAProxy reports on /health ("" when it does not answer), asked as
// HAProxy's checks ask: from 127.0.0.1, after a LOCAL PROXY header.
std::string health_instance(std::uint16_t http_port) {
  const test::HttpReply reply = test::http_get(http_port, "/health", test::kProxyLocalHeader);
  if (reply.status != 200) return "";
  return json::parse(reply.body).value("instance", "");
}

// Whether HAProxy's status CSV shows `server` of backend `backend` UP.
bool haproxy_says_up(std::uint16_t stats_port, const std::string& backend, const std::string& server) {
  std::istringstream csv(test::http_get(stats_port, "/stats;csv").body);
  for (std::string line; std::getline(csv, line);) {
    if (line.rfind(backend + "," + server + ",", 0) == 0) return line.find(",UP,") != std::string::npos;
  }
  return false;
}

// Current sessions (the CSV's scur column) HAProxy has open to `server` of `backend`, or -1.
int haproxy_sessions(std::uint16_t stats_port, const std::string& backend, const std::string& server) {
  std::istringstream csv(test::http_get(stats_port, "/stats;csv").body);
  for (std::string line; std::getline(csv, line);) {
    if (line.rfind(backend + "," + server + ",", 0) != 0) continue;
    std::istringstream fields(line);
    std::string field;
    for (int column = 0; std::getline(fields, field, ','); ++column) {
      if (column == 4) return field.empty() ? -1 : std::stoi(field);  // pxname,svname,qcur,qmax,scur
    }
  }
  return -1;
}

bool wait_until(const std::function<bool()>& condition, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (condition()) return true;
    std::this_thread::sleep_for(100ms);
  }
  return condition();
}

struct Replica {
  std::string name;
  std::uint16_t port, http_port;
  std::filesystem::path dir;
  std::unique_ptr<test::ServerProcess> process;

  void start(const std::filesystem::path& models, const std::string& log_level = "warn") {
    std::vector<std::string> args{
        "--models", models.string(), "--name", name, "--http-port", std::to_string(http_port), "--workers",
        "1",        "--log-level",   log_level};
    args.insert(args.end(), test::kBehindHaproxy.begin(), test::kBehindHaproxy.end());
    process = std::make_unique<test::ServerProcess>(args, dir, port);
  }
};

// The meshes a replica behind HAProxy says it has written whole (its /metrics), or -1.
double meshes_sent(std::uint16_t http_port) {
  const test::HttpReply reply = test::http_get(http_port, "/metrics", test::kProxyLocalHeader);
  const std::string name = "\nmtlod_sent_meshes_total ";
  const auto at = reply.body.find(name);
  if (reply.status != 200 || at == std::string::npos) return -1;
  return std::stod(reply.body.substr(at + name.size()));
}

// meshes_sent, given up to 2 s to reach `expected`: a write's completion is counted a moment after
// the client may already hold its bytes.
double settled_meshes_sent(std::uint16_t http_port, double expected) {
  double last = meshes_sent(http_port);
  for (int i = 0; i < 20 && last != expected; ++i) {
    std::this_thread::sleep_for(100ms);
    last = meshes_sent(http_port);
  }
  return last;
}

// The meshes a stopped replica's last log line says it sent, or -1.
double meshes_sent_at_exit(const std::string& log) {
  const std::string line = "stopped: ";
  const auto at = log.rfind(line);
  if (at == std::string::npos) return -1;
  return std::stod(log.substr(at + line.size()));
}

// mtlod-load's report `r` says every request it sent was answered with a mesh: none lost, none
// given up, none left unsent.
void expect_every_request_answered(const json& r) {
  EXPECT_GT(r.at("sent").get<std::uint64_t>(), 0u);
  EXPECT_EQ(r.at("ok"), r.at("sent")) << r.dump(2);
  EXPECT_EQ(r.at("errors"), 0) << r.dump(2);
  EXPECT_EQ(r.at("lost"), 0) << r.dump(2);
  EXPECT_EQ(r.at("unsent"), 0) << r.dump(2);
  EXPECT_EQ(r.at("gave_up"), 0) << r.dump(2);
}

// Two replicas sharing `models` (logging at `log_level`) behind HAProxy running
// docker/haproxy.cfg, on loopback ports, once HAProxy sees both up.
struct Fleet {
  std::vector<Replica> replicas;
  std::uint16_t lb_port = test::free_port(), lb_http_port = test::free_port(), stats_port = test::free_port();
  std::unique_ptr<test::Child> haproxy;

  void start(const std::filesystem::path& dir, const std::filesystem::path& models,
             const std::string& log_level = "warn") {
    for (const char* name : {"replica-1", "replica-2"}) {
      replicas.push_back(Replica{name, test::free_port(), test::free_port(), dir / name, nullptr});
      std::filesystem::create_directories(replicas.back().dir);
      replicas.back().start(models, log_level);
      ASSERT_TRUE(replicas.back().process->running()) << replicas.back().process->log();
    }
    const auto environment = test::haproxy_environment(
        {lb_port,
         lb_http_port,
         stats_port,
         {{{replicas[0].port, replicas[0].http_port}, {replicas[1].port, replicas[1].http_port}}}});
    haproxy = std::make_unique<test::Child>(
        std::vector<std::string>{MTLOD_HAPROXY_BINARY, "-db", "-f", MTLOD_SOURCE_DIR "/docker/haproxy.cfg"},
        environment, dir / "haproxy.log");
    ASSERT_TRUE(wait_until(
        [&] {
          return haproxy_says_up(stats_port, "replicas", "replica-1") &&
                 haproxy_says_up(stats_port, "replicas", "replica-2");
        },
        30s))
        << "HAProxy never saw both replicas up\n"
        << haproxy->log();
  }

  // mtlod-load through HAProxy for `seconds`, closed loop on 4 connections recycled every 10
  // requests, its JSON report to `report`; returns once replica-1 serves one of them.
  void start_load(const std::filesystem::path& dir, int seconds, const std::filesystem::path& report,
                  std::unique_ptr<test::Child>& load) {
    load = std::make_unique<test::Child>(
        std::vector<std::string>{MTLOD_LOAD_BINARY, "--port", std::to_string(lb_port), "--model", "sphere",
                                 "--connections", "4", "--duration", std::to_string(seconds), "--budget",
                                 "2000", "--reconnect-after", "10", "--attempts", "40", "--quiet", "--json",
                                 report.string()},
        std::map<std::string, std::string>{}, dir / "load.log");
    std::this_thread::sleep_for(2s);
    ASSERT_TRUE(load->running()) << load->log();
    ASSERT_TRUE(wait_until([&] { return haproxy_sessions(stats_port, "replicas", "replica-1") >= 1; }, 10s))
        << "no connection reached replica-1\n"
        << haproxy->log();
  }
};

json read_json(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) return json::object();
  return json::parse(in, nullptr, false);
}

TEST(Failover, LoadThroughHaproxySurvivesAKilledReplicaAndComesBackToItsRestart) {
  const auto dir = test::scratch_dir("failover");
  const auto models = write_model(dir, 8000);
  Fleet fleet;
  ASSERT_NO_FATAL_FAILURE(fleet.start(dir, models));
  std::vector<Replica>& replicas = fleet.replicas;
  const std::uint16_t stats_port = fleet.stats_port;
  test::Child& haproxy = *fleet.haproxy;
  const std::string first_instance = health_instance(replicas[0].http_port);
  ASSERT_FALSE(first_instance.empty());

  // Connections are recycled every 10 requests so that the balancer can place them on the
  // restarted replica.
  const auto report = dir / "load.json";
  std::unique_ptr<test::Child> loading;
  ASSERT_NO_FATAL_FAILURE(fleet.start_load(dir, 14, report, loading));
  test::Child& load = *loading;
  // Kill it while it serves: a closed-loop connection always has a request in flight.
  const int status = replicas[0].process->stop(SIGKILL);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << status;
  std::this_thread::sleep_for(1500ms);
  replicas[0].start(models);
  ASSERT_TRUE(replicas[0].process->running()) << replicas[0].process->log();
  const std::string restarted_instance = health_instance(replicas[0].http_port);
  ASSERT_FALSE(restarted_instance.empty());
  EXPECT_NE(restarted_instance, first_instance) << "a restart is a new instance";
  EXPECT_TRUE(wait_until([&] { return haproxy_says_up(stats_port, "replicas", "replica-1"); }, 10s))
      << haproxy.log();

  ASSERT_EQ(load.wait(90s), 0) << load.log();
  const json r = read_json(report);
  ASSERT_TRUE(r.contains("instances")) << r.dump(2) << load.log();
  // Every request answered: the ones on the killed replica were sent again, none lost.
  expect_every_request_answered(r);
  EXPECT_GE(r.at("retried").get<std::uint64_t>(), 1u) << "the kill caught requests in flight\n" << r.dump(2);
  EXPECT_GE(r.at("reconnects").get<std::uint64_t>(), 1u) << r.dump(2);
  // Both replicas served before the kill, and the restarted one served again afterwards.
  const json& instances = r.at("instances");
  ASSERT_TRUE(instances.contains(first_instance)) << instances.dump(2);
  ASSERT_TRUE(instances.contains(restarted_instance)) << "no traffic came back\n" << instances.dump(2);
  EXPECT_GT(instances.at(restarted_instance).at("ok").get<std::uint64_t>(), 0u);
  EXPECT_GT(instances.at(restarted_instance).at("first_reply_s").get<double>(),
            instances.at(first_instance).at("last_reply_s").get<double>())
      << "the restarted replica answered after the killed one stopped";
  std::uint64_t total = 0;
  bool second = false;
  for (const auto& [name, counts] : instances.items()) {
    total += counts.at("ok").get<std::uint64_t>();
    second = second || name.rfind("replica-2@", 0) == 0;
  }
  EXPECT_TRUE(second) << instances.dump(2);
  EXPECT_EQ(total, r.at("ok").get<std::uint64_t>()) << "every reply is counted on one instance";
  // Counted on both sides: the replicas that lived to the end sent exactly the meshes the client
  // received from them (a mesh the killed one wrote just before the kill may never have arrived).
  for (const Replica& replica : replicas) {
    const std::string instance = health_instance(replica.http_port);
    ASSERT_TRUE(instances.contains(instance)) << instance << instances.dump(2);
    EXPECT_EQ(settled_meshes_sent(replica.http_port, instances.at(instance).at("ok").get<double>()),
              instances.at(instance).at("ok").get<double>())
        << replica.name;
  }
}

TEST(Drain, ALoadedReplicaBehindHaproxyDrainsWithNothingLostOrServedTwice) {
  const auto dir = test::scratch_dir("drain-behind-haproxy");
  const auto models = write_model(dir, 8000);
  Fleet fleet;
  ASSERT_NO_FATAL_FAILURE(fleet.start(dir, models, "info"));  // info: the exit line with the meshes sent
  std::vector<Replica>& replicas = fleet.replicas;
  const std::string drained = health_instance(replicas[0].http_port);
  const std::string kept = health_instance(replicas[1].http_port);
  ASSERT_FALSE(drained.empty());
  ASSERT_FALSE(kept.empty());

  const auto report = dir / "load.json";
  std::unique_ptr<test::Child> loading;
  ASSERT_NO_FATAL_FAILURE(fleet.start_load(dir, 8, report, loading));
  test::Child& load = *loading;
  // What an orchestrator does to a replica it retires: SIGTERM, then wait. Its connections each
  // have a request in flight, which it finishes and answers before closing them.
  const int status = replicas[0].process->stop(SIGTERM, 30s);
  ASSERT_TRUE(WIFEXITED(status)) << status << "\n" << replicas[0].process->log();
  EXPECT_EQ(WEXITSTATUS(status), 0) << replicas[0].process->log();
  const double sent_by_drained = meshes_sent_at_exit(replicas[0].process->log());
  ASSERT_GT(sent_by_drained, 0) << replicas[0].process->log();

  ASSERT_EQ(load.wait(90s), 0) << load.log();
  const json r = read_json(report);
  ASSERT_TRUE(r.contains("instances")) << r.dump(2) << load.log();
  expect_every_request_answered(r);
  const json& instances = r.at("instances");
  ASSERT_TRUE(instances.contains(drained)) << instances.dump(2);
  ASSERT_TRUE(instances.contains(kept)) << "the other replica took the load\n" << instances.dump(2);
  EXPECT_EQ(instances.size(), 2u) << instances.dump(2);
  EXPECT_GT(instances.at(kept).at("last_reply_s").get<double>(),
            instances.at(drained).at("last_reply_s").get<double>());
  // Both sides agree, replica by replica: every mesh a replica wrote reached the client once, and
  // the client got none that no replica wrote.
  EXPECT_EQ(instances.at(drained).at("ok").get<double>(), sent_by_drained) << instances.dump(2);
  EXPECT_EQ(settled_meshes_sent(replicas[1].http_port, instances.at(kept).at("ok").get<double>()),
            instances.at(kept).at("ok").get<double>())
      << instances.dump(2);
}

TEST(Health, ReportsTheInstanceTheProtocolReports) {
  const auto dir = test::scratch_dir("health");
  const auto models = write_model(dir, 2000);
  const std::uint16_t http_port = test::free_port();
  test::ServerProcess server({"--models", models.string(), "--name", "probe-me", "--http-port",
                              std::to_string(http_port), "--log-level", "warn"},
                             dir);
  ASSERT_TRUE(server.running()) << server.log();
  const test::HttpReply response = test::http_get(http_port, "/health");
  ASSERT_EQ(response.status, 200) << response.head;
  EXPECT_NE(response.head.find("application/json"), std::string::npos) << response.head;
  const json health = json::parse(response.body);
  EXPECT_EQ(health.at("status"), "ok");
  EXPECT_EQ(health.at("models"), 1);
  auto c = clients::ServerConnection::open("127.0.0.1", server.port());
  ASSERT_TRUE(c.ok());
  auto hello = c->call(protocol::Hello{protocol::kProtocolVersion, "test"}, 1);
  ASSERT_TRUE(hello.ok());
  const std::string instance = std::get<protocol::HelloReply>(hello->header.reply).instance;
  EXPECT_EQ(health.at("instance"), instance);
  EXPECT_EQ(instance.rfind("probe-me@", 0), 0u) << instance;
  EXPECT_EQ(instance.size(), std::string("probe-me@").size() + 8);
  // The open protocol connection is counted.
  const test::HttpReply again = test::http_get(http_port, "/health");
  EXPECT_EQ(json::parse(again.body).at("connections"), 1) << again.body;
}

}  // namespace
}  // namespace mtlod

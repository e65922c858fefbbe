// Real client addresses behind the shipped balancer: HAProxy running docker/haproxy.cfg itself
// (send-proxy-v2 on every server line, LOCAL headers on its health checks) in front of two
// mtlod-server replicas that trust it (--proxy-protocol-from 127.0.0.1/32). Over a thousand
// clients from eight loopback addresses, viewers over WebSocket through the HTTP frontend and
// protocol connections through the TCP frontend (some with an extract and a gaze, decoded), are
// all served at once, although together they hold far more connections per replica than the
// per-address cap: the replicas count each client, not HAProxy. Then one address opens more
// viewers than its cap on the replica its model hashes to and is refused exactly the excess, while
// every other address stays served, there too.
#include <gtest/gtest.h>

#include <sys/resource.h>

#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <sstream>
#include <thread>

#include "core/build/mt_builder.hpp"
#include "core/codec/draco_decode.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mt_file.hpp"
#include "nlohmann/json.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/deploy/deploy_support.hpp"
#include "tests/server/http_client.hpp"
#include "tests/server/raw_client.hpp"
#include "tests/server/raw_websocket.hpp"
#include "tests/server/server_process.hpp"
#include "tests/server/test_requests.hpp"

namespace mtlod {
namespace {

using nlohmann::json;
using test::RawClient;
using test::RawWebSocket;
using namespace std::chrono_literals;

constexpr int kAddresses = 8;              // clients from 127.0.0.2 to 127.0.0.9
constexpr int kProtocolPerAddress = 70;    // through the TCP frontend (leastconn)
constexpr int kViewersPerAddress = 60;     // through the HTTP frontend, /ws without a model (round robin)
constexpr int kExtractionsPerAddress = 2;  // connections with an extract and a gaze, decoded
constexpr int kClients = kAddresses * (kProtocolPerAddress + kViewersPerAddress);  // 1040
// Above what one address ever holds on a replica (130, should all of them land on one), and far
// below what each replica holds in all (about 520): were HAProxy's own address counted, most
// connections would be refused.
constexpr int kCap = 200;
constexpr int kGreedyExcess = 30;
const std::string kGreedy = "127.0.0.10";

std::string source(int address) {
  return "127.0.0." + std::to_string(2 + address);
}

std::string hello_json(std::uint64_t id) {
  return protocol::to_json(protocol::Hello{protocol::kProtocolVersion, "proxy-deploy-test", ""}, id);
}
std::string ping_json(std::uint64_t id) {
  return protocol::to_json(protocol::Ping{}, id);
}

// The replica that answered a hello (its instance, "replica-N@hex"), or "" for any other reply.
std::string hello_instance(const protocol::Reply& reply) {
  const auto* hello = std::get_if<protocol::HelloReply>(&reply);
  return hello ? hello->instance : "";
}

bool is_pong(const protocol::Reply& reply) {
  return std::holds_alternative<protocol::Pong>(reply);
}

// A viewer's next reply, parsed (text messages hold a reply's JSON).
std::optional<protocol::Reply> viewer_reply(RawWebSocket& ws) {
  const auto message = ws.receive();
  if (!message) return std::nullopt;
  const auto reply = test::reply_from_message(message->text, message->payload);
  if (!reply.ok()) return std::nullopt;
  return reply->header.reply;
}

// Opens a viewer from `from` through HAProxy's HTTP frontend and says hello. Returns the upgrade's
// HTTP status and, when upgraded and greeted, the replica that answered.
std::pair<int, std::string> open_viewer(RawWebSocket& ws, const std::string& target, std::uint64_t id) {
  if (!ws.valid()) return {0, ""};
  const int status = ws.upgrade(target);
  if (status != 101 || !ws.send_text(hello_json(id))) return {status, ""};
  const auto reply = viewer_reply(ws);
  return {status, reply ? hello_instance(*reply) : ""};
}

// The replica's /health or /metrics, asked as HAProxy's checks ask (127.0.0.1, a LOCAL header).
std::string replica_get(std::uint16_t http_port, const std::string& target) {
  return test::http_get(http_port, target, test::kProxyLocalHeader).body;
}

// One Prometheus sample's value, or -1.
double metric(const std::string& text, const std::string& name) {
  std::istringstream lines(text);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind(name + " ", 0) == 0) return std::stod(line.substr(name.size() + 1));
  }
  return -1;
}

bool haproxy_says_up(std::uint16_t stats_port, const std::string& backend, const std::string& server) {
  std::istringstream csv(test::http_get(stats_port, "/stats;csv").body);
  for (std::string line; std::getline(csv, line);) {
    if (line.rfind(backend + "," + server + ",", 0) == 0) return line.find(",UP,") != std::string::npos;
  }
  return false;
}

// Everything one client address holds, and what happened to it.
struct AddressClients {
  std::string source;
  std::vector<RawClient> protocol;
  std::vector<RawWebSocket> viewers;
  int served_protocol = 0, served_viewers = 0, decoded = 0, pongs = 0;
  std::map<std::string, int> by_replica;  // hello replies by answering instance name prefix
  std::vector<std::string> failures;
};

void open_all(AddressClients& a, std::uint16_t lb_port, std::uint16_t lb_http_port) {
  for (int i = 0; i < kProtocolPerAddress; ++i) {
    RawClient c(a.source, lb_port);
    if (!c.valid() || !c.send(RawClient::frame(hello_json(1)))) {
      a.failures.push_back("protocol connection " + std::to_string(i) + " could not connect");
      continue;
    }
    const auto reply = c.receive();
    const std::string instance = reply ? hello_instance(reply->parsed.reply) : "";
    if (instance.empty()) {
      a.failures.push_back("protocol connection " + std::to_string(i) + ": no hello reply" +
                           (reply ? ": " + reply->json : ""));
      continue;
    }
    ++a.served_protocol;
    ++a.by_replica[instance.substr(0, instance.find('@'))];
    if (i < kExtractionsPerAddress) {
      // An extract, then a gaze that moves its focus, through the balancer: served and decoded as
      // for any client.
      c.send_request(protocol::ModelInfo{"sphere"}, 2);
      const auto info = c.receive();
      const auto* model = info ? std::get_if<protocol::ModelInfoReply>(&info->parsed.reply) : nullptr;
      const protocol::Request requests[] = {
          model ? test::framing_extract("sphere", *model, {64, 48}, 2) : protocol::Extract{},
          protocol::Gaze{0.4, 0.5, 20, 0.2}};
      int meshes = 0;
      for (std::uint64_t id = 3; model && id < 5; ++id) {
        if (!c.send_request(requests[id - 3], id)) break;
        const auto mesh = c.receive(60s);
        const auto* m = mesh ? std::get_if<protocol::MeshReply>(&mesh->parsed.reply) : nullptr;
        const auto decoded =
            m ? core::codec::decode_draco(mesh->payload) : make_error(ErrorCode::kCorrupt, "no mesh");
        meshes += decoded.ok() && m->triangles > 0 && decoded->mesh.triangle_count() == m->triangles;
      }
      if (meshes == 2) {
        ++a.decoded;
      } else {
        a.failures.push_back("protocol connection " + std::to_string(i) + ": " + std::to_string(meshes) +
                             " of an extract and a gaze decoded");
      }
    }
    a.protocol.push_back(std::move(c));
  }
  for (int i = 0; i < kViewersPerAddress; ++i) {
    RawWebSocket ws(a.source, lb_http_port);
    const auto [status, instance] = open_viewer(ws, "/ws", 1);
    if (instance.empty()) {
      a.failures.push_back("viewer " + std::to_string(i) + ": upgrade status " + std::to_string(status) +
                           (status == 101 ? ", no hello reply" : ""));
      continue;
    }
    ++a.served_viewers;
    ++a.by_replica[instance.substr(0, instance.find('@'))];
    a.viewers.push_back(std::move(ws));
  }
}

// A ping on every connection the address holds; counts the pongs.
void ping_all(AddressClients& a, std::uint64_t id) {
  a.pongs = 0;
  for (RawClient& c : a.protocol) {
    if (!c.send(RawClient::frame(ping_json(id)))) continue;
    const auto reply = c.receive();
    if (reply && is_pong(reply->parsed.reply)) ++a.pongs;
  }
  for (RawWebSocket& ws : a.viewers) {
    if (!ws.send_text(ping_json(id))) continue;
    const auto reply = viewer_reply(ws);
    if (reply && is_pong(*reply)) ++a.pongs;
  }
}

std::filesystem::path write_model(const std::filesystem::path& dir) {
  core::eval::GenerateOptions o;
  o.target_triangles = 2000;
  auto mt = core::build::build_mt(core::eval::generate_mesh(o));
  EXPECT_TRUE(mt.ok());
  std::filesystem::create_directories(dir / "models");
  EXPECT_TRUE(core::io::write_mt_file(dir / "models" / "sphere.mt", *mt).ok());
  return dir / "models";
}

TEST(ProxyDeploy, ThousandClientsBehindHaproxyAreCappedByTheirOwnAddresses) {
  // Each client connection is a descriptor here, two in HAProxy and one in a replica, all
  // inheriting this process's limit.
  rlimit files{};
  ASSERT_EQ(::getrlimit(RLIMIT_NOFILE, &files), 0);
  files.rlim_cur = files.rlim_max;
  ASSERT_EQ(::setrlimit(RLIMIT_NOFILE, &files), 0);
  const rlim_t needed = 2 * (kClients + kCap + kGreedyExcess) + 512;
  if (files.rlim_cur < needed)
    GTEST_SKIP() << "RLIMIT_NOFILE hard limit " << files.rlim_max << " < " << needed;

  const auto dir = test::scratch_dir("proxy-deploy");
  const auto models = write_model(dir);
  struct Replica {
    std::uint16_t port, http_port;
    std::unique_ptr<test::ServerProcess> process;
  };
  std::vector<Replica> replicas;
  for (const char* name : {"replica-1", "replica-2"}) {
    const std::uint16_t port = test::free_port(), http_port = test::free_port();
    std::filesystem::create_directories(dir / name);
    std::vector<std::string> args{"--models",
                                  models.string(),
                                  "--name",
                                  name,
                                  "--http-port",
                                  std::to_string(http_port),
                                  "--workers",
                                  "1",
                                  "--max-connections",
                                  "4000",
                                  "--max-connections-per-address",
                                  std::to_string(kCap),
                                  "--log-level",
                                  "warn"};
    args.insert(args.end(), test::kBehindHaproxy.begin(), test::kBehindHaproxy.end());
    replicas.push_back({port, http_port, std::make_unique<test::ServerProcess>(args, dir / name, port)});
    ASSERT_TRUE(replicas.back().process->running()) << replicas.back().process->log();
  }
  const std::uint16_t lb_port = test::free_port(), lb_http_port = test::free_port(),
                      stats_port = test::free_port();
  test::Child haproxy({MTLOD_HAPROXY_BINARY, "-db", "-f", MTLOD_SOURCE_DIR "/docker/haproxy.cfg"},
                      test::haproxy_environment({lb_port,
                                                 lb_http_port,
                                                 stats_port,
                                                 {{{replicas[0].port, replicas[0].http_port},
                                                   {replicas[1].port, replicas[1].http_port}}}}),
                      dir / "haproxy.log");
  // Up in both backends: their checks went through the replicas' PROXY header reading (LOCAL).
  bool up = false;
  for (auto deadline = std::chrono::steady_clock::now() + 30s;
       !up && std::chrono::steady_clock::now() < deadline;) {
    up = true;
    for (const char* backend : {"replicas", "viewer"}) {
      for (const char* server : {"replica-1", "replica-2"})
        up = up && haproxy_says_up(stats_port, backend, server);
    }
    if (!up) std::this_thread::sleep_for(100ms);
  }
  ASSERT_TRUE(up) << "HAProxy never saw both replicas up in both backends\n"
                  << haproxy.log() << replicas[0].process->log();

  // ---- Over a thousand clients from eight addresses, all at once ----
  std::vector<AddressClients> clients(kAddresses);
  {
    std::vector<std::thread> threads;
    for (int i = 0; i < kAddresses; ++i) {
      clients[i].source = source(i);
      threads.emplace_back([&, i] { open_all(clients[i], lb_port, lb_http_port); });
    }
    for (auto& t : threads) t.join();
  }
  std::map<std::string, int> by_replica;
  for (const AddressClients& a : clients) {
    EXPECT_EQ(a.served_protocol, kProtocolPerAddress) << a.source;
    EXPECT_EQ(a.served_viewers, kViewersPerAddress) << a.source;
    EXPECT_EQ(a.decoded, kExtractionsPerAddress) << a.source;
    for (const std::string& failure : a.failures) ADD_FAILURE() << a.source << ": " << failure;
    for (const auto& [replica, count] : a.by_replica) by_replica[replica] += count;
  }
  ASSERT_FALSE(HasFailure()) << replicas[0].process->log() << replicas[1].process->log();
  // Both replicas took their share, and between them they hold every client connection now.
  EXPECT_GT(by_replica["replica-1"], 0);
  EXPECT_GT(by_replica["replica-2"], 0);
  int held = 0;
  for (const Replica& r : replicas)
    held += json::parse(replica_get(r.http_port, "/health")).at("connections").get<int>();
  EXPECT_EQ(held, kClients);
  // Each replica holds more connections from HAProxy than the cap would allow one address.
  EXPECT_GT(std::max(by_replica["replica-1"], by_replica["replica-2"]), kCap);

  // ---- One address over its cap ----
  // Its viewers name a model, so HAProxy sends them all to one replica (url_param, consistent
  // hashing): that replica admits kCap of them and refuses the rest.
  std::vector<RawWebSocket> greedy;
  std::set<std::string> greedy_replicas;
  std::map<int, int> greedy_statuses;
  for (int i = 0; i < kCap + kGreedyExcess; ++i) {
    RawWebSocket ws(kGreedy, lb_http_port);
    const auto [status, instance] = open_viewer(ws, "/ws?model=sphere", 1);
    ++greedy_statuses[status];
    if (status == 101) {
      EXPECT_FALSE(instance.empty()) << "upgraded viewer " << i << " got no hello reply";
      greedy_replicas.insert(instance.substr(0, instance.find('@')));
      greedy.push_back(std::move(ws));
    }
  }
  EXPECT_EQ(greedy_statuses[101], kCap);
  EXPECT_EQ(greedy_statuses[503], kGreedyExcess) << "statuses: " << json(greedy_statuses).dump();
  EXPECT_EQ(greedy_replicas.size(), 1u);
  // The refusals are the replicas' connection-limit refusals, and there are no others.
  double refused = 0;
  for (const Replica& r : replicas)
    refused += metric(replica_get(r.http_port, "/metrics"), "mtlod_connections_refused_total");
  EXPECT_EQ(refused, kGreedyExcess);

  // Everyone else is still served: every connection held answers a ping, and each address gets a
  // viewer of the same model on the same replica that refuses the greedy one.
  {
    std::vector<std::thread> threads;
    for (auto& a : clients) threads.emplace_back([&a] { ping_all(a, 7); });
    for (auto& t : threads) t.join();
  }
  for (AddressClients& a : clients) {
    EXPECT_EQ(a.pongs, kProtocolPerAddress + kViewersPerAddress) << a.source;
    RawWebSocket ws(a.source, lb_http_port);
    const auto [status, instance] = open_viewer(ws, "/ws?model=sphere", 1);
    EXPECT_EQ(status, 101) << a.source;
    EXPECT_EQ(greedy_replicas.count(instance.substr(0, instance.find('@'))), 1u) << instance;
  }
  // And the greedy address's admitted viewers are served too.
  int greedy_pongs = 0;
  for (RawWebSocket& ws : greedy) {
    if (!ws.send_text(ping_json(9))) continue;
    const auto reply = viewer_reply(ws);
    greedy_pongs += reply && is_pong(*reply);
  }
  EXPECT_EQ(greedy_pongs, kCap);
}

}  // namespace
}  // namespace mtlod

// Abuse against the real server process: idle sockets, floods from one client address, a client
// that queues far more work than the others, requests that would pass the memory ceiling, and a
// mix of hostile traffic beside a normal load. Each test checks that a legitimate client is
// served throughout and that nothing is lost. Client addresses are played with sources in
// 127.0.0.0/8 (all of it reaches the loopback server).
#include <gtest/gtest.h>

#include <dirent.h>

#include <atomic>
#include <fstream>
#include <map>
#include <random>
#include <thread>

#include "clients/common/server_connection.hpp"
#include "core/codec/draco_decode.hpp"
#include "protocol/camera.hpp"
#include "protocol/text.hpp"
#include "server/engine.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/server/http_client.hpp"
#include "tests/server/raw_client.hpp"
#include "tests/server/server_process.hpp"
#include "tests/server/test_requests.hpp"

namespace mtlod {
namespace {

using test::RawClient;
using namespace std::chrono_literals;

// A server on the built-in bunny with the given flags, and an extract request that frames it.
struct Served {
  std::unique_ptr<test::ServerProcess> server;
  protocol::Extract extract;

  explicit Served(const std::string& name, std::vector<std::string> flags) {
    const auto dir = test::scratch_dir("abuse-" + name);
    const auto bunny = test::models_dir() / "bunny.ply";
    if (!std::filesystem::exists(bunny)) return;
    std::vector<std::string> args = {"--mesh",     bunny.string(), "--cache-dir",
                                     dir.string(), "--log-level",  "warn"};
    args.insert(args.end(), flags.begin(), flags.end());
    server = std::make_unique<test::ServerProcess>(args, dir);
    if (!server->running()) return;
    auto c = clients::ServerConnection::open("127.0.0.1", server->port());
    if (!c) return;
    auto info = c->call(protocol::ModelInfo{"bunny"}, 1);
    if (!info) return;
    extract =
        test::framing_extract("bunny", std::get<protocol::ModelInfoReply>(info->header.reply), {128, 96}, 1);
    extract.criteria.regions[core::view::Criterion::kSilhouette] = protocol::Region{2, 0, {}};
  }
  bool ok() const { return server && server->running() && server->port() != 0; }
  std::uint16_t port() const { return server->port(); }

  std::map<std::string, double> stats() const {
    std::map<std::string, double> out;
    auto c = clients::ServerConnection::open("127.0.0.1", server->port());
    if (!c) return out;
    auto reply = c->call(protocol::Stats{}, 1);
    if (!reply) return out;
    for (const auto& [name, value] : std::get<protocol::StatsReply>(reply->header.reply).counters)
      out[name] = value;
    return out;
  }
};

#define SKIP_WITHOUT_SERVER(served)                                                                    \
  if (!std::filesystem::exists(test::models_dir() / "bunny.ply")) GTEST_SKIP() << "no built-in bunny"; \
  ASSERT_TRUE((served).ok()) << ((served).server ? (served).server->log() : std::string())

const protocol::ErrorReply* as_error(const RawClient::Reply& r) {
  return std::get_if<protocol::ErrorReply>(&r.parsed.reply);
}
const protocol::MeshReply* as_mesh(const RawClient::Reply& r) {
  return std::get_if<protocol::MeshReply>(&r.parsed.reply);
}

// One extract on a fresh connection from `source`: true when a mesh that decodes comes back.
bool served_from(const Served& s, const std::string& source) {
  RawClient c(source, s.port());
  if (!c.send_request(s.extract, 1)) return false;
  auto reply = c.receive(60s);
  return reply && as_mesh(*reply) && core::codec::decode_draco(reply->payload).ok();
}

TEST(Abuse, IdleSocketsFromOneAddressNeitherLockOthersOutNorStay) {
  Served s("idle", {"--max-connections", "16", "--max-connections-per-address", "4",
                    "--first-frame-timeout-ms", "1000", "--http-port", "0"});
  SKIP_WITHOUT_SERVER(s);
  // 127.0.0.2 opens ten connections and sends nothing: four are held, six refused by name.
  std::vector<RawClient> idle;
  int refused = 0;
  for (int i = 0; i < 10; ++i) {
    RawClient c("127.0.0.2", s.port());
    ASSERT_TRUE(c.valid());
    if (i >= 4) {
      auto reply = c.receive(10s);
      ASSERT_TRUE(reply.has_value()) << "connection " << i << " was neither refused nor answered";
      const auto* error = as_error(*reply);
      ASSERT_NE(error, nullptr) << reply->json;
      EXPECT_EQ(error->code, protocol::ErrorKind::kLimitExceeded);
      EXPECT_NE(error->message.find("per client address"), std::string::npos) << error->message;
      ++refused;
    } else {
      idle.push_back(std::move(c));
    }
  }
  EXPECT_EQ(refused, 6);
  // Meanwhile other addresses are served, and hold their own four slots.
  EXPECT_TRUE(served_from(s, "127.0.0.1"));
  std::vector<RawClient> others;
  for (int i = 0; i < 4; ++i) others.emplace_back("127.0.0.3", s.port());
  EXPECT_TRUE(served_from(s, "127.0.0.1"));
  // Idle HTTP connections count too, and are closed by the same deadline.
  RawClient http_idle("127.0.0.4", s.server->http_port());
  ASSERT_TRUE(http_idle.valid());
  // The first-frame deadline closes every idle socket, which frees its address's slots.
  for (auto& c : idle) EXPECT_TRUE(c.closed_by_server(10s));
  for (auto& c : others) EXPECT_TRUE(c.closed_by_server(10s));
  EXPECT_TRUE(http_idle.closed_by_server(10s));
  EXPECT_TRUE(served_from(s, "127.0.0.2"));
}

TEST(Abuse, ConnectionCapPerAddressAppliesToTheHttpPort) {
  Served s("http-cap", {"--max-connections-per-address", "2", "--http-port", "0"});
  SKIP_WITHOUT_SERVER(s);
  RawClient a("127.0.0.5", s.server->http_port()), b("127.0.0.5", s.server->http_port());
  ASSERT_TRUE(a.valid() && b.valid());
  // The third is answered 503 and closed at once (the other two wait for their first-frame
  // deadline); another address is served the health page.
  RawClient c("127.0.0.5", s.server->http_port());
  ASSERT_TRUE(c.valid());
  const std::optional<std::string> refusal = c.read_until_closed(10s);
  ASSERT_TRUE(refusal.has_value());
  EXPECT_EQ(refusal->rfind("HTTP/1.1 503", 0), 0u) << *refusal;
  EXPECT_EQ(test::http_get(s.server->http_port(), "/health").status, 200);
}

TEST(Abuse, OneAddressQueueingMuchWorkDoesNotHoldEveryWorker) {
  // One worker, so the order in which extractions run is the scheduler's alone.
  Served s("fair", {"--workers", "1"});
  SKIP_WITHOUT_SERVER(s);
  protocol::Extract heavy = s.extract;
  heavy.grid = {1024, 768};
  heavy.error = 0;  // the whole model
  constexpr int kConnections = 10, kPerConnection = 6;
  std::atomic<int> heavy_replies{0}, heavy_meshes{0};
  std::vector<std::thread> flood;
  for (int c = 0; c < kConnections; ++c) {
    flood.emplace_back([&] {
      RawClient client("127.0.0.2", s.port());
      for (int i = 0; i < kPerConnection; ++i) client.send_request(heavy, 100 + i);
      for (int i = 0; i < kPerConnection; ++i) {
        auto reply = client.receive(120s);
        if (!reply) return;
        if (as_mesh(*reply)) ++heavy_meshes;
        ++heavy_replies;
      }
    });
  }
  // Once the flood's work is running, a client from another address asks for one extraction.
  while (heavy_replies.load() < 1) std::this_thread::sleep_for(1ms);
  RawClient light("127.0.0.1", s.port());
  const int before = heavy_replies.load();
  ASSERT_TRUE(light.send_request(s.extract, 1));
  auto reply = light.receive(120s);
  const int during = heavy_replies.load() - before;
  for (auto& t : flood) t.join();
  ASSERT_TRUE(reply.has_value());
  EXPECT_NE(as_mesh(*reply), nullptr) << reply->json;
  // First come, first served would run one extraction of each of the flood's ten connections
  // first; taking turns by address runs the light client's next, after the running one.
  EXPECT_LE(during, 3) << "flood extractions finished while the light client waited";
  EXPECT_EQ(heavy_meshes.load(), kConnections * kPerConnection);  // the flood lost nothing either
}

TEST(Abuse, MemoryCeilingRefusesWorkThatWouldPassItAndFreesClosedSessions) {
  Served s("memory", {"--workers", "1", "--max-memory", "48M"});
  SKIP_WITHOUT_SERVER(s);
  {
    auto c = clients::ServerConnection::open("127.0.0.1", s.port());
    ASSERT_TRUE(c.ok());
    auto hello = c->call(protocol::Hello{1, "test"}, 1);
    ASSERT_TRUE(hello.ok());
    EXPECT_EQ(std::get<protocol::HelloReply>(hello->header.reply).limits.max_memory_bytes, 48u << 20);
  }
  // A 4096² grid needs more than the whole ceiling: refused, naming the limit.
  protocol::Extract huge = s.extract;
  huge.grid = {4096, 4096};
  RawClient c("127.0.0.1", s.port());
  ASSERT_TRUE(c.send_request(huge, 1));
  auto refused = c.receive();
  ASSERT_TRUE(refused.has_value());
  const auto* error = as_error(*refused);
  ASSERT_NE(error, nullptr) << refused->json;
  EXPECT_EQ(error->code, protocol::ErrorKind::kLimitExceeded);
  EXPECT_NE(error->message.find("memory limit"), std::string::npos) << error->message;
  EXPECT_TRUE(served_from(s, "127.0.0.1"));

  // Sessions holding 1024² views fill the ceiling: the server refuses more rather than pass it.
  protocol::Extract big = s.extract;
  big.grid = {1024, 1024};
  std::vector<RawClient> sessions;
  int held = 0, limited = 0;
  for (int i = 0; i < 12 && limited == 0; ++i) {
    RawClient session("127.0.0.1", s.port());
    ASSERT_TRUE(session.send_request(big, 1));
    auto reply = session.receive(60s);
    ASSERT_TRUE(reply.has_value()) << s.server->log();
    if (as_mesh(*reply)) {
      ++held;
      sessions.push_back(std::move(session));
    } else {
      ASSERT_NE(as_error(*reply), nullptr) << reply->json;
      EXPECT_EQ(as_error(*reply)->code, protocol::ErrorKind::kLimitExceeded);
      ++limited;
    }
    const auto counters = s.stats();
    EXPECT_LE(counters.at("memory_held_bytes"), counters.at("memory_limit_bytes"));
  }
  EXPECT_GE(held, 1);
  EXPECT_EQ(limited, 1) << "12 sessions of 1024² views fit in 48 MiB";
  // Closing the sessions gives their memory back: the same request is served again.
  const double before_close = s.stats().at("memory_held_bytes");
  for (auto& session : sessions) session.close();
  double after_close = before_close;
  for (int i = 0; i < 100 && after_close >= before_close; ++i) {
    std::this_thread::sleep_for(50ms);
    after_close = s.stats().at("memory_held_bytes");
  }
  EXPECT_LT(after_close, before_close);
  RawClient again("127.0.0.1", s.port());
  ASSERT_TRUE(again.send_request(big, 1));
  auto reply = again.receive(60s);
  ASSERT_TRUE(reply.has_value());
  EXPECT_NE(as_mesh(*reply), nullptr) << reply->json;
}

std::uint64_t rss_bytes(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string key;
  while (in >> key) {
    if (key == "VmRSS:") {
      std::uint64_t kb = 0;
      in >> kb;
      return kb * 1024;
    }
    in.ignore(1 << 16, '\n');
  }
  return 0;
}

// The ceiling counts a request's grid while it runs; a worker keeps modest grids for the next
// request and frees a huge one's once it is done, so clients asking for the largest grid cannot
// leave hundreds of MiB behind in every worker. (The connection's own view of that grid is its
// session's, freed when it closes.)
TEST(Abuse, AHugeGridsScratchIsFreedOnceItsExtractionEnds) {
  Served s("scratch", {"--workers", "1"});
  SKIP_WITHOUT_SERVER(s);
  RawClient c("127.0.0.1", s.port());
  ASSERT_TRUE(c.send_request(s.extract, 1));  // the worker's modest scratch, kept
  auto first = c.receive(60s);
  ASSERT_TRUE(first.has_value() && as_mesh(*first)) << s.server->log();
  const double kept = s.stats().at("worker_scratch_bytes");
  EXPECT_GE(kept, double(as_mesh(*first)->scratch_bytes));
  EXPECT_LE(kept, double(server::Engine::kRetainedScratchBytes));

  protocol::Extract huge = s.extract;
  huge.grid = {4096, 4096};
  ASSERT_TRUE(c.send_request(huge, 2));
  auto reply = c.receive(120s);
  ASSERT_TRUE(reply.has_value()) << s.server->log();
  const auto* mesh = as_mesh(*reply);
  ASSERT_NE(mesh, nullptr) << reply->json;
  ASSERT_GT(mesh->scratch_bytes, server::Engine::kRetainedScratchBytes)
      << "the grid does not exercise the release";
  EXPECT_LE(s.stats().at("worker_scratch_bytes"), double(server::Engine::kRetainedScratchBytes))
      << "the grid's " << mesh->scratch_bytes << " bytes of scratch were kept";
}

// ---- Hostile traffic beside a normal load --------------------------------------------------

int open_fds(pid_t pid) {
  int count = 0;
  if (DIR* dir = ::opendir(("/proc/" + std::to_string(pid) + "/fd").c_str())) {
    while (const dirent* entry = ::readdir(dir)) count += entry->d_name[0] != '.';
    ::closedir(dir);
  }
  return count;
}

// One hostile client's session: what it sends depends on `kind`; it never reads replies it does
// not need and may leave at any point.
void hostile_session(const Served& s, int kind, std::mt19937& rng, const std::string& source) {
  const std::string extract = protocol::to_json(protocol::Request{s.extract}, 5);
  RawClient c(source, s.port());
  switch (kind) {
    case 0: {  // mutated valid requests
      std::string json = extract;
      for (int k = 0, n = 1 + static_cast<int>(rng() % 4); k < n; ++k) {
        json[rng() % json.size()] = static_cast<char>(rng());
      }
      c.send(RawClient::frame(json));
      (void)c.receive(5s);
      break;
    }
    case 1: {  // random bytes
      std::string bytes(rng() % 200, '\0');
      for (char& b : bytes) b = static_cast<char>(rng());
      c.send(bytes);
      break;
    }
    case 2: {  // a header announcing a huge frame
      c.send(std::string("\xff\xff\xff\x7f\xff\xff\xff\x7f", 8));
      (void)c.receive(5s);
      break;
    }
    case 3:  // invalid UTF-8
      c.send(RawClient::frame("{\"type\":\"model_info\",\"id\":1,\"model\":\"\xff\xfe\xc3\"}"));
      (void)c.receive(5s);
      break;
    case 4: {  // half a frame, then gone
      const std::string frame = RawClient::frame(extract);
      c.send(frame.substr(0, 1 + rng() % (frame.size() - 1)));
      break;
    }
    case 5:  // an extraction, then a reset before its reply
      c.send(RawClient::frame(extract));
      c.reset();
      break;
    case 6:  // idle: sends nothing and stays until the server closes it
      (void)c.closed_by_server(10s);
      break;
    default: {  // garbage to the HTTP port
      RawClient h(source, s.server->http_port());
      std::string bytes(rng() % 300, '\0');
      for (char& b : bytes) b = static_cast<char>(rng());
      h.send("GET /" + bytes + " HTTP/1.1\r\n\r\n");
      (void)h.closed_by_server(5s);
    }
  }
}

TEST(Abuse, HostileTrafficBesideANormalLoadLeavesTheServerAsItWas) {
  // Under AddressSanitizer freed memory waits in a quarantine (256 MiB by default) before reuse;
  // a small one keeps the server's RSS a measure of what it holds.
  const char* asan = std::getenv("ASAN_OPTIONS");
  ::setenv("ASAN_OPTIONS", (std::string(asan ? asan : "") + ":quarantine_size_mb=16").c_str(), 1);
  Served s("hostile", {"--workers", "2", "--http-port", "0", "--first-frame-timeout-ms", "500",
                       "--read-timeout-ms", "1000"});
  SKIP_WITHOUT_SERVER(s);
  const pid_t pid = s.server->pid();

  // The normal load: clients each asking extractions and gazes, every reply checked.
  std::atomic<int> meshes{0}, failures{0};
  auto normal_load = [&](int rounds) {
    std::vector<std::thread> clients;
    for (int i = 0; i < 3; ++i) {
      clients.emplace_back([&, i] {
        auto c = clients::ServerConnection::open("127.0.0.1", s.port());
        if (!c) return void(++failures);
        for (int r = 0; r < rounds; ++r) {
          auto mesh = c->call(s.extract, 2 * r);
          if (!mesh || !std::holds_alternative<protocol::MeshReply>(mesh->header.reply))
            return void(++failures);
          auto gaze = c->call(protocol::Gaze{0.3 + 0.1 * i, 0.5, 20, 0.2}, 2 * r + 1);
          if (!gaze || !std::holds_alternative<protocol::MeshReply>(gaze->header.reply))
            return void(++failures);
          meshes += 2;
        }
      });
    }
    for (auto& t : clients) t.join();
  };
  normal_load(5);  // warm-up: every worker has its scratch, the allocator its pools
  const std::uint64_t rss_before = rss_bytes(pid);
  const int fds_before = open_fds(pid);
  const int meshes_before = meshes.load();

  std::atomic<bool> done{false};
  std::vector<std::thread> hostile;
  for (int t = 0; t < 6; ++t) {
    hostile.emplace_back([&, t] {
      std::mt19937 rng(1000 + t);
      const std::string source = "127.0.1." + std::to_string(t + 1);
      for (int i = 0; i < 400 && !done; ++i) hostile_session(s, static_cast<int>(rng() % 8), rng, source);
    });
  }
  normal_load(25);
  done = true;
  for (auto& t : hostile) t.join();
  EXPECT_EQ(failures.load(), 0) << s.server->log();
  EXPECT_EQ(meshes.load() - meshes_before, 3 * 25 * 2);

  // Afterwards: served as before, the counters add up, and nothing is left held.
  EXPECT_TRUE(served_from(s, "127.0.0.1"));
  std::map<std::string, double> counters;
  for (int i = 0; i < 100; ++i) {  // hostile connections end by their deadlines
    counters = s.stats();
    if (counters["connections_open"] == 1 && open_fds(pid) <= fds_before + 1) break;
    std::this_thread::sleep_for(100ms);
  }
  EXPECT_EQ(counters["connections_open"], 1) << "only the connection asking for stats";
  EXPECT_EQ(counters["errors_internal"], 0);
  EXPECT_GT(counters["errors_bad_json"], 0);
  EXPECT_GT(counters["errors_bad_frame"], 0);
  EXPECT_GE(counters["extractions"], meshes.load());
  EXPECT_LE(open_fds(pid), fds_before + 1);  // the stats connection
  // Bound: the heap may keep what the hostile phase's extra connections used, not more.
  EXPECT_LT(rss_bytes(pid), rss_before + (std::uint64_t{96} << 20))
      << "RSS " << rss_bytes(pid) / 1048576.0 << " MiB, was " << rss_before / 1048576.0 << " MiB";
  EXPECT_TRUE(s.server->running());
}

}  // namespace
}  // namespace mtlod

// Model files changed under a running server the way operators change them: with truncate, cp over
// the file, dd of random bytes, rm, mv over it and a directory in its place, while 16 connections
// stream cuts of that model and 4 of another. The process lives through all of it; the other
// model's clients see no error; the changed model's clients get clear errors or cuts whose every
// vertex is a vertex of the old or of the new model, never a mix; each connection is told when
// its model changed; and the new content is served without a restart. Also: SIGHUP and the admin
// `reload` message in --reload signal mode, a corrupt replacement leaving the old version
// serving, and the version in list and /metrics.
#include <gtest/gtest.h>
#include <signal.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <unordered_set>
#include <vector>

#include "clients/common/server_connection.hpp"
#include "core/build/mt_builder.hpp"
#include "core/codec/draco_decode.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mt_file.hpp"
#include "protocol/camera.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/server/http_client.hpp"
#include "tests/server/server_process.hpp"
#include "tests/server/test_requests.hpp"

namespace mtlod {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// One content a model file can have: its bytes and its MT's vertices, hashed on a grid finer than
// Draco's quantisation error is coarse, so a decoded vertex can be looked up.
struct Content {
  std::string name;
  fs::path file;
  std::vector<float> positions;
  std::unordered_set<std::uint64_t> cells;
  static constexpr float kCell = 2e-3f;

  static std::uint64_t key(std::int64_t x, std::int64_t y, std::int64_t z) {
    return (std::uint64_t(x & 0x1fffff) << 42) | (std::uint64_t(y & 0x1fffff) << 21) |
           std::uint64_t(z & 0x1fffff);
  }
  // Whether (x, y, z) lies within a cell of a vertex of this content.
  bool has_vertex_near(float x, float y, float z) const {
    const auto cx = std::int64_t(std::floor(x / kCell)), cy = std::int64_t(std::floor(y / kCell)),
               cz = std::int64_t(std::floor(z / kCell));
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz)
          if (cells.count(key(cx + dx, cy + dy, cz + dz))) return true;
    return false;
  }
};

// A generated shape moved `shift` along x, built and written to dir/NAME.mt.
Content make_content(const fs::path& dir, const std::string& name, core::eval::Shape shape, float shift) {
  core::eval::GenerateOptions options;
  options.shape = shape;
  options.target_triangles = 20000;
  core::model::Mesh mesh = core::eval::generate_mesh(options);
  for (std::size_t i = 0; i < mesh.positions.size(); i += 3) mesh.positions[i] += shift;
  auto mt = core::build::build_mt(mesh);
  EXPECT_TRUE(mt.ok());
  Content c;
  c.name = name;
  c.file = dir / (name + ".mt");
  EXPECT_TRUE(core::io::write_mt_file(c.file, *mt).ok());
  c.positions.assign(mt->positions.begin(), mt->positions.end());
  for (std::size_t i = 0; i < c.positions.size(); i += 3) {
    c.cells.insert(Content::key(std::int64_t(std::floor(c.positions[i] / Content::kCell)),
                                std::int64_t(std::floor(c.positions[i + 1] / Content::kCell)),
                                std::int64_t(std::floor(c.positions[i + 2] / Content::kCell))));
  }
  return c;
}

// A connection streaming cuts of one model (an extract, then gazes) until stopped, checking every
// reply against the contents the model may have.
class Stream {
 public:
  Stream(std::uint16_t port, std::string model, std::vector<const Content*> contents, unsigned seed)
      : port_(port), model_(std::move(model)), contents_(std::move(contents)), seed_(seed) {
    thread_ = std::thread([this] { run(); });
  }
  ~Stream() { stop(); }
  void stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }

  std::uint64_t meshes = 0, changes_seen = 0, reconnects = 0;
  std::map<std::string, std::uint64_t> errors;  // by code
  std::vector<std::string> failures;            // what no client may ever see

 private:
  void fail(std::string what) {
    if (failures.size() < 10) failures.push_back(std::move(what));
  }
  // A mesh reply: it decodes, has the triangles it says, and all its vertices come from one content.
  void check_mesh(const clients::ReplyFrame& frame) {
    const auto& mesh = std::get<protocol::MeshReply>(frame.header.reply);
    ++meshes;
    auto decoded = core::codec::decode_draco(frame.payload);
    if (!decoded) return fail("payload does not decode: " + decoded.error().message);
    if (decoded->mesh.triangle_count() != mesh.triangles)
      return fail("decoded " + std::to_string(decoded->mesh.triangle_count()) + " triangles, reply says " +
                  std::to_string(mesh.triangles));
    const auto& p = decoded->mesh.positions;
    const Content* from = nullptr;
    for (const Content* c : contents_) {
      if (p.size() >= 3 && c->has_vertex_near(p[0], p[1], p[2])) from = c;
    }
    if (!from) return fail("a vertex of no content");
    for (std::size_t i = 0; i < p.size(); i += 3) {
      if (!from->has_vertex_near(p[i], p[i + 1], p[i + 2]))
        return fail("a cut mixing contents, or a vertex of none (" + from->name + ")");
    }
    if (last_version_ != 0 && mesh.model_version != last_version_) {
      ++changes_seen;
      if (!mesh.model_changed) fail("a new version without model_changed");
    } else if (mesh.model_changed) {
      fail("model_changed without a new version");
    }
    last_version_ = mesh.model_version;
  }

  void run() {
    std::mt19937 rng(seed_);
    std::uniform_real_distribution<double> unit(0.05, 0.95);
    std::optional<clients::ServerConnection> c;
    std::uint64_t id = 1;
    while (!stop_) {
      if (!c) {
        auto opened = clients::ServerConnection::open("127.0.0.1", port_);
        if (!opened) {
          fail("cannot connect: " + opened.error().message);
          std::this_thread::sleep_for(50ms);
          continue;
        }
        c.emplace(std::move(*opened));
        last_version_ = 0;
      }
      auto info = c->call(protocol::ModelInfo{model_}, id++);
      if (!info) {
        ++reconnects;
        c.reset();
        continue;
      }
      if (const auto* e = std::get_if<protocol::ErrorReply>(&info->header.reply)) {
        ++errors[protocol::to_string(e->code)];
        std::this_thread::sleep_for(10ms);
        continue;
      }
      const auto& model = std::get<protocol::ModelInfoReply>(info->header.reply);
      protocol::Extract extract = test::framing_extract(model_, model, {128, 128}, 1.0 + 3.0 * unit(rng));
      extract.criteria.regions[core::view::Criterion::kFocus] =
          protocol::Region{20.0, 0.1, {{unit(rng), unit(rng)}}};
      for (int step = 0; step < 4 && !stop_; ++step) {
        protocol::Request request = extract;
        if (step > 0) request = protocol::Gaze{unit(rng), unit(rng), std::nullopt, std::nullopt};
        auto reply = c->call(request, id++);
        if (!reply) {
          ++reconnects;
          c.reset();
          break;
        }
        if (std::holds_alternative<protocol::MeshReply>(reply->header.reply)) {
          check_mesh(*reply);
        } else if (const auto* e = std::get_if<protocol::ErrorReply>(&reply->header.reply)) {
          ++errors[protocol::to_string(e->code)];
          if (e->code == protocol::ErrorKind::kInternal || e->code == protocol::ErrorKind::kBadRequest)
            fail(std::string(protocol::to_string(e->code)) + ": " + e->message);
          break;
        }
      }
    }
  }

  std::uint16_t port_;
  std::string model_;
  std::vector<const Content*> contents_;
  unsigned seed_;
  std::uint64_t last_version_ = 0;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// The model's summary from `list`, or nothing while it is not served.
std::optional<protocol::ModelSummary> listed(clients::ServerConnection& c, const std::string& name) {
  auto reply = c.call(protocol::ListModels{}, 1);
  if (!reply) return std::nullopt;
  for (const auto& m : std::get<protocol::ModelsReply>(reply->header.reply).models) {
    if (m.name == name) return m;
  }
  return std::nullopt;
}

// The lowest x of the model's bounds (which content it serves), or NaN while it is not served.
double served_min_x(clients::ServerConnection& c, const std::string& name) {
  auto reply = c.call(protocol::ModelInfo{name}, 2);
  if (!reply || !std::holds_alternative<protocol::ModelInfoReply>(reply->header.reply)) return NAN;
  return std::get<protocol::ModelInfoReply>(reply->header.reply).bounds_min[0];
}

// Waits (a bound, not a measurement) until `done` holds.
template <class F>
bool eventually(F done, std::chrono::seconds limit = 30s) {
  for (const auto until = std::chrono::steady_clock::now() + limit;
       std::chrono::steady_clock::now() < until;) {
    if (done()) return true;
    std::this_thread::sleep_for(25ms);
  }
  return false;
}

int shell(const std::string& command) {
  return std::system(command.c_str());
}

// Runs `command` until it succeeds: coreutils truncate opens without waiting, so its first try
// meets the server's read lease (which the server then hands over).
bool retried(const std::string& command) {
  return eventually([&] { return shell(command + " 2>/dev/null") == 0; }, 10s);
}

TEST(ModelChange, EveryWayOfChangingAServedFileLeavesTheProcessServing) {
  const fs::path dir = test::scratch_dir("model-change");
  const fs::path contents_dir = dir / "contents", models = dir / "models";
  fs::create_directories(contents_dir);
  fs::create_directories(models);
  const Content a = make_content(contents_dir, "a", core::eval::Shape::kSphere, 0.0f);
  const Content b = make_content(contents_dir, "b", core::eval::Shape::kShell, 10.0f);
  const Content other = make_content(contents_dir, "other", core::eval::Shape::kTerrain, -10.0f);
  const fs::path served = models / "changing.mt";
  fs::copy_file(a.file, served);
  fs::copy_file(other.file, models / "steady.mt");

  test::ServerProcess server({"--models", models.string(), "--workers", "2"}, dir);
  ASSERT_TRUE(server.running()) << server.log();
  auto control = clients::ServerConnection::open("127.0.0.1", server.port());
  ASSERT_TRUE(control.ok());

  std::vector<std::unique_ptr<Stream>> changing, steady;
  for (unsigned i = 0; i < 16; ++i)
    changing.push_back(std::make_unique<Stream>(server.port(), "changing", std::vector{&a, &b}, i));
  for (unsigned i = 0; i < 4; ++i)
    steady.push_back(std::make_unique<Stream>(server.port(), "steady", std::vector{&other}, 100 + i));
  std::this_thread::sleep_for(300ms);

  const std::string path = served.string();
  auto serves = [&](const Content& c) {
    return eventually([&] {
      const double x = served_min_x(*control, "changing");
      return !std::isnan(x) && std::abs(x - c.positions[0]) < 3.0;
    });
  };
  auto gone = [&] { return eventually([&] { return !listed(*control, "changing"); }); };
  std::uint64_t last_version = listed(*control, "changing")->version;
  auto newer = [&] {
    const auto m = listed(*control, "changing");
    const bool is_newer = m && m->version > last_version;
    if (m) last_version = m->version;
    return is_newer;
  };

  // Truncated in place: the version is retired, the empty file refused.
  ASSERT_TRUE(retried("truncate -s 0 " + path));
  EXPECT_TRUE(gone()) << "an empty file is not served";
  // Rewritten in place by cp (the same inode, truncated and written).
  ASSERT_EQ(shell("cp " + b.file.string() + " " + path), 0);
  EXPECT_TRUE(serves(b));
  EXPECT_TRUE(newer());
  std::this_thread::sleep_for(300ms);
  // Overwritten in place with random bytes, its length kept.
  ASSERT_EQ(shell("dd if=/dev/urandom of=" + path + " bs=4096 count=" +
                  std::to_string(fs::file_size(served) / 4096 + 1) + " conv=notrunc status=none"),
            0);
  EXPECT_TRUE(gone()) << "random bytes are not served";
  ASSERT_EQ(shell("cp " + a.file.string() + " " + path), 0);
  EXPECT_TRUE(serves(a));
  std::this_thread::sleep_for(300ms);
  // Deleted.
  ASSERT_EQ(shell("rm " + path), 0);
  EXPECT_TRUE(gone());
  // Renamed over (a new inode), first into the empty place, then over the served file.
  ASSERT_EQ(shell("cp " + b.file.string() + " " + (models / "incoming.tmp").string() + " && mv " +
                  (models / "incoming.tmp").string() + " " + path),
            0);
  EXPECT_TRUE(serves(b));
  std::this_thread::sleep_for(300ms);
  ASSERT_EQ(shell("cp " + a.file.string() + " " + (models / "incoming.tmp").string() + " && mv " +
                  (models / "incoming.tmp").string() + " " + path),
            0);
  EXPECT_TRUE(serves(a));
  std::this_thread::sleep_for(300ms);
  // Replaced by a directory.
  ASSERT_EQ(shell("rm " + path + " && mkdir " + path), 0);
  EXPECT_TRUE(gone());
  ASSERT_EQ(shell("rmdir " + path + " && cp " + b.file.string() + " " + path), 0);
  EXPECT_TRUE(serves(b));
  EXPECT_TRUE(newer());
  std::this_thread::sleep_for(300ms);

  for (auto& s : changing) s->stop();
  for (auto& s : steady) s->stop();
  ASSERT_TRUE(server.running()) << server.log();
  EXPECT_TRUE(listed(*control, "steady").has_value());

  std::uint64_t changing_meshes = 0, changes_seen = 0;
  for (const auto& s : changing) {
    changing_meshes += s->meshes;
    changes_seen += s->changes_seen;
    for (const std::string& f : s->failures) ADD_FAILURE() << "changing model: " << f;
    for (const auto& [code, count] : s->errors) {
      EXPECT_TRUE(code == "unavailable" || code == "unknown_model") << code << " × " << count;
    }
  }
  for (const auto& s : steady) {
    EXPECT_GT(s->meshes, 0u);
    EXPECT_EQ(s->reconnects, 0u);
    EXPECT_TRUE(s->errors.empty()) << s->errors.begin()->first;
    for (const std::string& f : s->failures) ADD_FAILURE() << "steady model: " << f;
  }
  std::map<std::string, std::uint64_t> changing_errors;
  for (const auto& s : changing)
    for (const auto& [code, count] : s->errors) changing_errors[code] += count;
  std::printf("changing model: %llu meshes checked, %llu version changes seen by connections, errors:",
              static_cast<unsigned long long>(changing_meshes),
              static_cast<unsigned long long>(changes_seen));
  for (const auto& [code, count] : changing_errors)
    std::printf(" %s %llu", code.c_str(), static_cast<unsigned long long>(count));
  std::printf("\n");
  EXPECT_GT(changing_meshes, 0u);
  EXPECT_GT(changes_seen, 0u) << "connections must see the model change under them";
  const std::string log = server.log();
  EXPECT_NE(log.find("stops serving"), std::string::npos) << log;
  EXPECT_NE(log.find("no longer served"), std::string::npos) << log;
}

TEST(ModelChange, AServerStartsWhileAModelFileIsBadAndServesItOnceWhole) {
  // As a replica restarted while an operator replaces a model: the file is a directory, then a
  // half-written file, then whole; the others are served throughout.
  const fs::path dir = test::scratch_dir("model-start");
  const fs::path contents_dir = dir / "contents", models = dir / "models";
  fs::create_directories(contents_dir);
  fs::create_directories(models / "changing.mt");
  const Content a = make_content(contents_dir, "a", core::eval::Shape::kSphere, 0.0f);
  fs::copy_file(a.file, models / "steady.mt");

  test::ServerProcess server({"--models", models.string()}, dir);
  ASSERT_TRUE(server.running()) << server.log();
  auto c = clients::ServerConnection::open("127.0.0.1", server.port());
  ASSERT_TRUE(c.ok());
  EXPECT_TRUE(listed(*c, "steady").has_value());
  EXPECT_FALSE(listed(*c, "changing").has_value());
  EXPECT_NE(server.log().find("changing.mt: not a regular file"), std::string::npos) << server.log();

  fs::remove(models / "changing.mt");
  fs::copy_file(a.file, models / "changing.mt");  // the watch loads it
  EXPECT_TRUE(eventually([&] { return listed(*c, "changing").has_value(); })) << server.log();
  EXPECT_TRUE(listed(*c, "steady").has_value());
  ASSERT_TRUE(server.running()) << server.log();
}

TEST(ModelChange, SignalAndAdminMessageReloadInSignalMode) {
  const fs::path dir = test::scratch_dir("model-reload");
  const fs::path contents_dir = dir / "contents", models = dir / "models";
  fs::create_directories(contents_dir);
  fs::create_directories(models);
  const Content a = make_content(contents_dir, "a", core::eval::Shape::kSphere, 0.0f);
  const Content b = make_content(contents_dir, "b", core::eval::Shape::kShell, 10.0f);
  fs::copy_file(a.file, models / "m.mt");
  test::write_file(dir / "admins", "# who may reload\nsecret-admin-token\n");

  test::ServerProcess server({"--models", models.string(), "--reload", "signal", "--admin-tokens",
                              (dir / "admins").string(), "--http-port", "0"},
                             dir);
  ASSERT_TRUE(server.running()) << server.log();
  auto c = clients::ServerConnection::open("127.0.0.1", server.port());
  ASSERT_TRUE(c.ok());
  ASSERT_EQ(listed(*c, "m")->version, 1u);

  // A new file renamed over the served one: not loaded until asked for.
  fs::copy_file(b.file, models / "m.next");
  fs::rename(models / "m.next", models / "m.mt");
  fs::copy_file(b.file, models / "added.mt");
  std::this_thread::sleep_for(1500ms);  // more than the watcher's retry period: nothing may change
  EXPECT_LT(served_min_x(*c, "m"), 3.0);
  EXPECT_FALSE(listed(*c, "added").has_value());

  ::kill(server.pid(), SIGHUP);
  EXPECT_TRUE(eventually([&] { return served_min_x(*c, "m") > 5.0; }));
  EXPECT_EQ(listed(*c, "m")->version, 2u);
  EXPECT_TRUE(listed(*c, "added").has_value()) << "a file added to the folder is served";
  ASSERT_TRUE(server.running()) << "SIGHUP reloads; it does not stop the server";

  // The admin message: refused without the token, obeyed with it.
  auto refused = c->call(protocol::Reload{"wrong"}, 10);
  ASSERT_TRUE(refused.ok());
  ASSERT_TRUE(std::holds_alternative<protocol::ErrorReply>(refused->header.reply)) << refused->json;
  EXPECT_EQ(std::get<protocol::ErrorReply>(refused->header.reply).code, protocol::ErrorKind::kUnauthorized);

  fs::copy_file(a.file, models / "m.next");
  fs::rename(models / "m.next", models / "m.mt");
  fs::remove(models / "added.mt");
  auto reloaded = c->call(protocol::Reload{"secret-admin-token"}, 11);
  ASSERT_TRUE(reloaded.ok());
  ASSERT_TRUE(std::holds_alternative<protocol::ReloadReply>(reloaded->header.reply)) << reloaded->json;
  std::map<std::string, std::string> changes;
  for (const auto& m : std::get<protocol::ReloadReply>(reloaded->header.reply).models)
    changes[m.name] = m.change;
  EXPECT_EQ(changes["m"], "replaced");
  EXPECT_EQ(changes["added"], "removed");
  EXPECT_LT(served_min_x(*c, "m"), 3.0);
  EXPECT_EQ(listed(*c, "m")->version, 3u);

  // A corrupt replacement: the old version keeps serving, and the log says why.
  test::write_file(models / "m.next", "MTLOD but not really an MT file");
  fs::rename(models / "m.next", models / "m.mt");
  reloaded = c->call(protocol::Reload{"secret-admin-token"}, 12);
  ASSERT_TRUE(reloaded.ok());
  changes.clear();
  for (const auto& m : std::get<protocol::ReloadReply>(reloaded->header.reply).models)
    changes[m.name] = m.change;
  EXPECT_EQ(changes["m"], "failed");
  EXPECT_EQ(listed(*c, "m")->version, 3u);
  auto info = c->call(protocol::ModelInfo{"m"}, 13);
  ASSERT_TRUE(info.ok());
  auto mesh = c->call(
      test::framing_extract("m", std::get<protocol::ModelInfoReply>(info->header.reply), {64, 64}, 2.0), 14);
  ASSERT_TRUE(mesh.ok());
  EXPECT_TRUE(std::holds_alternative<protocol::MeshReply>(mesh->header.reply)) << mesh->json;
  EXPECT_NE(server.log().find("version 3 keeps serving"), std::string::npos) << server.log();

  const auto metrics = test::http_get(server.http_port(), "/metrics");
  EXPECT_NE(metrics.body.find("mtlod_model_version{model=\"m\"} 3"), std::string::npos) << metrics.body;
  EXPECT_NE(metrics.body.find("mtlod_model_reloads_total 3"), std::string::npos) << metrics.body;
}

}  // namespace
}  // namespace mtlod

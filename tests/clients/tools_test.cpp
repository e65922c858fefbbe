// End to end: mtlod-load and mtlod-gaze run for a few seconds against the real mtlod-server, and
// their JSON reports are checked against the server's own counters (the `stats` request);
// mtlod-client's .glb output holds the Draco bytes the server sent.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <array>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "clients/common/server_connection.hpp"
#include "core/codec/draco_decode.hpp"
#include "core/codec/meshopt_decode.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mesh_io.hpp"
#include "fmt/format.h"
#include "nlohmann/json.hpp"
#include "tests/clients/served_bunny.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/server/server_process.hpp"

namespace mtlod {
namespace {

using nlohmann::json;

class ToolsTest : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::filesystem::path(test::scratch_dir("clients-tools"));
    test::put_bunny(*dir_);
  }
  static void TearDownTestSuite() { delete dir_; }

  void SetUp() override {
    server_ = std::make_unique<test::ServerProcess>(
        std::vector<std::string>{"--mesh", (*dir_ / "bunny.ply").string(), "--cache-dir", dir_->string(),
                                 "--workers", "2", "--log-level", "warn"},
        *dir_);
    ASSERT_TRUE(server_->running()) << server_->log();
  }

  // `mtlod-client extract bunny` of a 2,000-triangle cut at 0.5 px with `args` on a fresh connection;
  // it must succeed.
  void client_extract(const std::string& args) {
    const std::string command =
        fmt::format("{} --port {} extract bunny --error-px 0.5 --budget 2000 {} > {} 2>&1",
                    MTLOD_CLIENT_BINARY, server_->port(), args, (*dir_ / "client.log").string());
    EXPECT_EQ(std::system(command.c_str()), 0) << command << "\n" << test::read_file(*dir_ / "client.log");
  }

  // Runs a tool with `args` and returns its JSON report.
  json run(const std::string& binary, const std::string& args) {
    const auto report = *dir_ / "report.json";
    std::filesystem::remove(report);
    const std::string command =
        fmt::format("{} --port {} --quiet --json {} {} > {} 2>&1", binary, server_->port(), report.string(),
                    args, (*dir_ / "tool.log").string());
    const int status = std::system(command.c_str());
    std::ifstream log(*dir_ / "tool.log");
    const std::string output{std::istreambuf_iterator<char>(log), std::istreambuf_iterator<char>()};
    EXPECT_EQ(status, 0) << command << "\n" << output;
    std::ifstream in(report);
    if (!in) {
      ADD_FAILURE() << "no report from " << command << "\n" << output;
      return json::object();
    }
    return json::parse(in);
  }

  // The server's counters by name.
  std::map<std::string, double> server_counters() {
    auto c = clients::ServerConnection::open("127.0.0.1", server_->port());
    EXPECT_TRUE(c.ok());
    auto reply = c->call(protocol::Stats{}, 1);
    EXPECT_TRUE(reply.ok());
    std::map<std::string, double> out;
    for (const auto& [name, value] : std::get<protocol::StatsReply>(reply->header.reply).counters)
      out[name] = value;
    return out;
  }

  // Runs a tool with `args` that must fail; returns what it printed.
  std::string run_failing(const std::string& binary, const std::string& args) {
    const std::string command = fmt::format("{} --port {} --quiet {} > {} 2>&1", binary, server_->port(),
                                            args, (*dir_ / "tool.log").string());
    const int status = std::system(command.c_str());
    const std::string output = test::read_file(*dir_ / "tool.log");
    EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) != 0) << command << "\n" << output;
    return output;
  }

  // A scene file of three bunnies, each placed by its own scale, turn and offset; returns its path.
  // Three instances of the bunny: as it is, halved and moved, turned a quarter, enlarged and moved.
  static constexpr std::array<std::array<double, 16>, 3> kThreeBunnies{{
      {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1},
      {0.5, 0, 0, 0, 0, 0.5, 0, 0, 0, 0, 0.5, 0, 12, 0, -4, 1},
      {0, 0, -1.5, 0, 0, 1.5, 0, 0, 1.5, 0, 0, 0, -14, 1, 0, 1},
  }};
  static std::filesystem::path write_three_bunnies(const std::string& name) {
    json scene = {{"instances", json::array()}};
    for (const auto& m : kThreeBunnies) scene["instances"].push_back({{"model", "bunny"}, {"matrix", m}});
    const auto path = *dir_ / name;
    test::write_file(path, scene.dump());
    return path;
  }

  static void expect_ordered_latency(const json& latency) {
    ASSERT_TRUE(latency.is_object());
    const double p50 = latency.at("p50"), p90 = latency.at("p90"), p99 = latency.at("p99"),
                 p999 = latency.at("p999"), max = latency.at("max");
    EXPECT_GT(p50, 0);
    EXPECT_LE(p50, p90);
    EXPECT_LE(p90, p99);
    EXPECT_LE(p99, p999);
    EXPECT_LE(p999, max);
  }

  static std::filesystem::path* dir_;
  std::unique_ptr<test::ServerProcess> server_;
};

std::filesystem::path* ToolsTest::dir_ = nullptr;

TEST_F(ToolsTest, ClosedLoopLoadReportAgreesWithTheServer) {
  const json r = run(MTLOD_LOAD_BINARY, "--model bunny --connections 2 --duration 2 --budget 2000");
  ASSERT_TRUE(r.contains("requests")) << r.dump(2);
  const std::uint64_t requests = r.at("requests");
  EXPECT_GT(requests, 0u);
  EXPECT_EQ(r.at("mode"), "closed");
  EXPECT_EQ(r.at("errors"), 0);
  EXPECT_EQ(r.at("ok"), requests);
  EXPECT_EQ(r.at("sent"), requests);
  EXPECT_EQ(r.at("lost"), 0);
  EXPECT_NEAR(r.at("throughput_rps").get<double>(), requests / r.at("elapsed_s").get<double>(), 1e-6);
  expect_ordered_latency(r.at("latency_ms"));
  const double mean_triangles = r.at("mean_triangles");
  EXPECT_GT(mean_triangles, 0);
  EXPECT_LE(mean_triangles, 2000);

  // Every extract the tool counted reached the server, and nothing else did.
  auto counters = server_counters();
  EXPECT_EQ(counters["requests_extract"], static_cast<double>(requests));
  EXPECT_EQ(counters["requests_gaze"], 0);
  EXPECT_EQ(counters["extractions"], static_cast<double>(requests));
  EXPECT_NEAR(counters["triangles_out"] / counters["extractions"], mean_triangles, 1e-6 * mean_triangles);
  EXPECT_GE(counters["bytes_out"], r.at("bytes").get<double>());
}

TEST_F(ToolsTest, OpenLoopLoadSendsItsScheduleExactly) {
  // 50 requests/s for 2 s: due at 0, 20, ..., 1980 ms, 100 requests whatever the server does; half
  // of them (by weight) gazes, which the server may coalesce.
  const json r = run(MTLOD_LOAD_BINARY,
                     "--model bunny --connections 2 --duration 2 --rate 50 --mix extract=1,gaze=1 "
                     "--budget 1500");
  ASSERT_TRUE(r.contains("sent")) << r.dump(2);
  EXPECT_EQ(r.at("mode"), "open");
  EXPECT_EQ(r.at("sent"), 100);
  EXPECT_EQ(r.at("unsent"), 0);
  EXPECT_EQ(r.at("lost"), 0);
  EXPECT_EQ(r.at("errors"), 0);
  EXPECT_EQ(r.at("requests"), 100);
  EXPECT_EQ(r.at("ok").get<int>() + r.at("superseded").get<int>(), 100);
  expect_ordered_latency(r.at("latency_ms"));
  auto counters = server_counters();
  EXPECT_EQ(counters["requests_extract"] + counters["requests_gaze"], 100);
  EXPECT_GT(counters["requests_gaze"], 0);
  EXPECT_EQ(counters["errors_superseded"], r.at("superseded").get<double>());
  EXPECT_EQ(counters["extractions"], r.at("ok").get<double>());
}

TEST_F(ToolsTest, GazeReplayMeasuresEverySample) {
  // Two streams replay the shipped 3-second trace: every sample is answered by a mesh showing it
  // or as superseded, and the server saw exactly those gazes plus one opening extract per stream.
  const std::string trace = std::string(MTLOD_SOURCE_DIR) + "/clients/gaze/example-trace.csv";
  std::ifstream in(trace);
  std::size_t lines = 0;
  for (std::string line; std::getline(in, line);) lines += !line.empty() && line[0] != 't';
  const json r = run(MTLOD_GAZE_BINARY, "--model bunny --streams 2 --budget 1500 --trace " + trace);
  ASSERT_TRUE(r.contains("samples")) << r.dump(2);
  const std::uint64_t samples = r.at("samples");
  EXPECT_EQ(samples, 2 * lines);
  EXPECT_EQ(r.at("meshes").get<std::uint64_t>() + r.at("superseded").get<std::uint64_t>(), samples);
  EXPECT_EQ(r.at("errors"), 0);
  EXPECT_EQ(r.at("lost"), 0);
  EXPECT_EQ(r.at("focus_mismatches"), 0);
  EXPECT_EQ(r.at("superseded_counted_by_server"), r.at("superseded"));
  expect_ordered_latency(r.at("latency_ms"));
  EXPECT_EQ(r.at("sample_latency_ms").at("count"), samples);
  auto counters = server_counters();
  EXPECT_EQ(counters["requests_gaze"], static_cast<double>(samples));
  EXPECT_EQ(counters["errors_superseded"], r.at("superseded").get<double>());
  EXPECT_EQ(counters["extractions"], r.at("meshes").get<double>() + 2);
}

TEST_F(ToolsTest, GazeStreamsPlayTheirOwnTraces) {
  // A folder of two traces on three streams: streams 0 and 2 play a.csv (30 samples), stream 1
  // b.csv (40 samples, 6 of them lost in one blink, which are not sent). The server must see
  // exactly the tracked samples of that assignment.
  const auto folder = *dir_ / "traces";
  std::filesystem::create_directories(folder);
  std::ofstream a(folder / "a.csv"), b(folder / "b.csv");
  a << "time_ms,x,y\n";
  b << "time_ms,x,y\n";
  for (int i = 0; i < 30; ++i) a << fmt::format("{},{:.3f},0.5\n", 20 * i, 0.2 + 0.02 * i);
  for (int i = 0; i < 40; ++i)
    b << (i >= 10 && i < 16 ? fmt::format("{},,\n", 15 * i)
                            : fmt::format("{},0.5,{:.3f}\n", 15 * i, 0.1 + 0.02 * i));
  a.close(), b.close();
  const json r = run(MTLOD_GAZE_BINARY, "--model bunny --streams 3 --budget 1500 --trace " + folder.string());
  ASSERT_TRUE(r.contains("samples")) << r.dump(2);
  const std::uint64_t samples = r.at("samples");
  EXPECT_EQ(samples, 30u + 34u + 30u);
  EXPECT_EQ(r.at("tracker_lost_samples"), 6);
  EXPECT_EQ(r.at("blinks"), 1);
  EXPECT_EQ(r.at("meshes").get<std::uint64_t>() + r.at("superseded").get<std::uint64_t>(), samples);
  EXPECT_EQ(r.at("errors"), 0);
  EXPECT_EQ(r.at("lost"), 0);
  EXPECT_EQ(r.at("focus_mismatches"), 0);
  EXPECT_EQ(r.at("sample_latency_ms").at("count"), samples);
  EXPECT_EQ(server_counters()["requests_gaze"], static_cast<double>(samples));

  // The same two files as a comma list on two streams.
  const json two =
      run(MTLOD_GAZE_BINARY, fmt::format("--model bunny --streams 2 --budget 1500 --trace {},{}",
                                         (folder / "a.csv").string(), (folder / "b.csv").string()));
  EXPECT_EQ(two.at("samples"), 30 + 34);
  EXPECT_EQ(two.at("tracker_lost_samples"), 6);
}

TEST_F(ToolsTest, GazeReplayWithDeltasKeepsTheServersCutInFewerBytes) {
  // With --delta each stream rebuilds its mesh from the changes; every reply must leave it with the
  // server's triangle count (delta_errors counts any mismatch), in fewer bytes than whole meshes.
  const std::string trace = std::string(MTLOD_SOURCE_DIR) + "/clients/gaze/example-trace.csv";
  const std::string common = "--model bunny --streams 2 --error-px 1 --silhouette 2,0.5 --trace " + trace;
  const json whole = run(MTLOD_GAZE_BINARY, common);
  const json delta = run(MTLOD_GAZE_BINARY, common + " --delta");
  ASSERT_TRUE(delta.contains("delta_errors")) << delta.dump(2);
  EXPECT_EQ(delta.at("delta"), true);
  EXPECT_EQ(delta.at("delta_errors"), 0);
  EXPECT_EQ(delta.at("errors"), 0);
  EXPECT_EQ(delta.at("lost"), 0);
  EXPECT_GT(delta.at("meshes").get<std::uint64_t>(), 0u);
  EXPECT_EQ(delta.at("meshes").get<std::uint64_t>() + delta.at("superseded").get<std::uint64_t>(),
            delta.at("samples").get<std::uint64_t>());
  // Each delta mesh is applied after it arrives: one applied latency per mesh, none shorter.
  const json& applied = delta.at("applied_latency_ms");
  expect_ordered_latency(applied);
  EXPECT_EQ(applied.at("count"), delta.at("meshes"));
  EXPECT_GE(applied.at("p50").get<double>(), delta.at("latency_ms").at("p50").get<double>());
  EXPECT_GE(applied.at("max").get<double>(), delta.at("latency_ms").at("max").get<double>());
  EXPECT_TRUE(whole.at("applied_latency_ms").is_null());
  const double whole_per_mesh = whole.at("bytes").get<double>() / whole.at("meshes").get<double>();
  const double delta_per_mesh = delta.at("bytes").get<double>() / delta.at("meshes").get<double>();
  EXPECT_LT(delta_per_mesh, whole_per_mesh);
  // The same with meshoptimizer's codec: its deltas decode into the server's cut as Draco's do.
  const json meshopt = run(MTLOD_GAZE_BINARY, common + " --delta --codec meshopt");
  ASSERT_TRUE(meshopt.contains("delta_errors")) << meshopt.dump(2);
  EXPECT_EQ(meshopt.at("delta_errors"), 0);
  EXPECT_EQ(meshopt.at("errors"), 0);
  EXPECT_GT(meshopt.at("meshes").get<std::uint64_t>(), 0u);
  EXPECT_EQ(meshopt.at("applied_latency_ms").at("count"), meshopt.at("meshes"));
}

TEST_F(ToolsTest, GazeReplayOfASceneKeepsEveryInstancesMesh) {
  // Two streams gaze at a scene of three bunnies for two seconds with deltas: each stream keeps a
  // mesh per instance, and after every reply each must hold the triangles the reply gives that
  // instance (delta_errors counts any that does not). The server saw exactly the samples as gazes
  // and one opening scene extract per stream.
  const auto scene = write_three_bunnies("gaze-scene.json");
  const json r = run(MTLOD_GAZE_BINARY,
                     "--scene " + scene.string() + " --streams 2 --delta --duration 2000 --budget 3000");
  ASSERT_TRUE(r.contains("samples")) << r.dump(2);
  EXPECT_EQ(r.at("scene"), scene.string());
  EXPECT_EQ(r.at("instances"), 3);
  EXPECT_TRUE(r.at("model").is_null());
  const std::uint64_t samples = r.at("samples"), meshes = r.at("meshes");
  EXPECT_GT(meshes, 0u);
  EXPECT_EQ(r.at("delta"), true);
  EXPECT_EQ(r.at("delta_errors"), 0);
  EXPECT_EQ(r.at("errors"), 0);
  EXPECT_EQ(r.at("lost"), 0);
  EXPECT_EQ(r.at("focus_mismatches"), 0);
  EXPECT_EQ(meshes + r.at("superseded").get<std::uint64_t>(), samples);
  EXPECT_EQ(r.at("superseded_counted_by_server"), r.at("superseded"));
  EXPECT_EQ(r.at("applied_latency_ms").at("count"), meshes);
  auto counters = server_counters();
  EXPECT_EQ(counters["requests_extract"], 2);
  EXPECT_EQ(counters["requests_gaze"], static_cast<double>(samples));
  EXPECT_EQ(counters["errors_superseded"], r.at("superseded").get<double>());
  EXPECT_EQ(counters["extractions"], static_cast<double>(meshes) + 2);
  EXPECT_GE(counters["bytes_out"], r.at("bytes").get<double>());
}

TEST_F(ToolsTest, ClosedLoopLoadOfASceneAgreesWithTheServer) {
  // Two connections replay views of a three-bunny scene, extracts from random orbits around its box
  // and gazes moving its focus: every request is answered by a scene's mesh, within the budget the
  // instances share, and the server counted each request and the triangles the tool reports.
  const auto scene = write_three_bunnies("load-scene.json");
  const json r =
      run(MTLOD_LOAD_BINARY,
          "--scene " + scene.string() + " --connections 2 --duration 2 --budget 2000 --mix extract=1,gaze=1");
  ASSERT_TRUE(r.contains("requests")) << r.dump(2);
  EXPECT_EQ(r.at("scenes"),
            json::parse(fmt::format(R"([{{"file": "{}", "instances": 3}}])", scene.string())));
  EXPECT_EQ(r.at("models"), json::array());
  const std::uint64_t requests = r.at("requests");
  EXPECT_GT(requests, 0u);
  EXPECT_EQ(r.at("ok"), requests);
  EXPECT_EQ(r.at("sent"), requests);
  EXPECT_EQ(r.at("errors"), 0);
  EXPECT_EQ(r.at("superseded"), 0);  // closed loop: a gaze is sent once the previous reply is in
  EXPECT_EQ(r.at("lost"), 0);
  expect_ordered_latency(r.at("latency_ms"));
  const double mean_triangles = r.at("mean_triangles");
  EXPECT_GT(mean_triangles, 0);
  EXPECT_LE(mean_triangles, 2000);
  auto counters = server_counters();
  EXPECT_EQ(counters["requests_extract"] + counters["requests_gaze"], static_cast<double>(requests));
  EXPECT_GT(counters["requests_gaze"], 0);
  EXPECT_GT(counters["requests_extract"], 0);
  EXPECT_EQ(counters["extractions"], static_cast<double>(requests));
  EXPECT_NEAR(counters["triangles_out"] / counters["extractions"], mean_triangles, 1e-6 * mean_triangles);
  EXPECT_GE(counters["bytes_out"], r.at("bytes").get<double>());
}

TEST_F(ToolsTest, LoadDecodesEveryPayloadOfEitherCodec) {
  // With --decode every mesh reply is decoded as a viewer would (whole meshes, deltas, a scene's
  // parts) and checked against its header; a run where one fails exits non-zero.
  const auto scene = write_three_bunnies("decode-scene.json");
  for (const std::string codec : {"draco", "meshopt"}) {
    for (const std::string& view : {std::string("--model bunny"), "--scene " + scene.string()}) {
      for (const std::string delta : {"", " --delta"}) {
        const std::string args = view + " --codec " + codec + delta +
                                 " --decode --connections 2 --requests 40 --duration 10 --budget 2000 "
                                 "--mix extract=1,gaze=1";
        const json r = run(MTLOD_LOAD_BINARY, args);
        ASSERT_TRUE(r.contains("decode")) << args << "\n" << r.dump(2);
        EXPECT_EQ(r.at("ok"), 40) << args;
        EXPECT_EQ(r.at("errors"), 0) << args;
        EXPECT_EQ(r.at("decode").at("payloads"), r.at("ok")) << args;
        EXPECT_EQ(r.at("decode").at("errors"), 0) << args << ": " << r.at("decode").at("first_error");
      }
    }
  }
  const json plain = run(MTLOD_LOAD_BINARY, "--model bunny --requests 5 --duration 10");
  EXPECT_TRUE(plain.at("decode").is_null());
}

TEST_F(ToolsTest, SceneToolsRefuseABadSceneFile) {
  // A scene naming a model the server does not serve: both tools stop before any extract, saying
  // the server's code and the model's name.
  json unknown = json::parse(test::read_file(write_three_bunnies("unknown-scene.json")));
  unknown["instances"].push_back({{"model", "teapot"}});
  const auto unknown_file = *dir_ / "unknown-scene.json";
  test::write_file(unknown_file, unknown.dump());
  for (const char* binary : {MTLOD_GAZE_BINARY, MTLOD_LOAD_BINARY}) {
    const std::string output = run_failing(binary, "--scene " + unknown_file.string());
    EXPECT_NE(output.find(unknown_file.string() + ": unknown_model: no model named 'teapot'"),
              std::string::npos)
        << binary << "\n"
        << output;
  }
  auto counters = server_counters();
  EXPECT_EQ(counters["requests_extract"], 0);
  EXPECT_EQ(counters["errors_unknown_model"], 2);  // one model_info per tool

  // A singular matrix (its third column 0): refused with the file and the field, before connecting.
  const auto singular = *dir_ / "singular-scene.json";
  test::write_file(singular,
                   R"({"instances": [{"model": "bunny", "matrix": [1,0,0,0, 0,1,0,0, 0,0,0,0, 0,0,0,1]}]})");
  for (const char* binary : {MTLOD_GAZE_BINARY, MTLOD_LOAD_BINARY}) {
    const std::string output = run_failing(binary, "--scene " + singular.string());
    EXPECT_NE(output.find(singular.string() + ": scene.instances[0].matrix is singular"), std::string::npos)
        << binary << "\n"
        << output;
  }
  // No connection but the stats call's own.
  EXPECT_EQ(server_counters()["connections_total"], counters["connections_total"] + 1);
}

// A GLB's JSON and BIN chunks, read by hand (a 12-byte header, then length, type, data).
std::pair<json, std::string> glb_chunks(const std::string& glb) {
  std::pair<json, std::string> out;
  EXPECT_EQ(glb.substr(0, 4), "glTF");
  for (std::size_t at = 12; at + 8 <= glb.size();) {
    std::uint32_t length;
    std::memcpy(&length, glb.data() + at, 4);
    if (glb.compare(at + 4, 4, "JSON") == 0) out.first = json::parse(glb.substr(at + 8, length));
    if (glb.compare(at + 4, 4, std::string("BIN\0", 4)) == 0) out.second = glb.substr(at + 8, length);
    at += 8 + length;
  }
  return out;
}

// Runs the Khronos validator on `files`: no error and no warning (skipped when it is not installed).
void expect_valid_gltf(const std::filesystem::path& dir, const std::vector<std::filesystem::path>& files) {
#ifdef MTLOD_NODE_BINARY
  std::string names;
  for (const auto& file : files) names += " " + file.string();
  const std::string command = fmt::format("{} {}/tests/core/gltf_validate.mjs{} > {} 2>&1", MTLOD_NODE_BINARY,
                                          MTLOD_SOURCE_DIR, names, (dir / "validator.log").string());
  const int status = std::system(command.c_str());
  const std::string report = test::read_file(dir / "validator.log");
  if (WIFEXITED(status) && WEXITSTATUS(status) == 77) GTEST_SKIP() << report;
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << report;
#else
  (void)dir, (void)files;
#endif
}

TEST_F(ToolsTest, ClientGlbEmbedsTheMeshoptStreamsItReceived) {
  // The same request twice on fresh connections: as .mopt (the payload as received) and as .glb,
  // whose buffer views' EXT_meshopt_compression data must be the payload's streams, unchanged.
  client_extract("--codec meshopt -o " + (*dir_ / "cut.mopt").string());
  client_extract("--codec meshopt -o " + (*dir_ / "cut-meshopt.glb").string());
  const std::string mopt = test::read_file(*dir_ / "cut.mopt");
  const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(mopt.data()), mopt.size());
  const auto streams = core::codec::read_meshopt(bytes);
  ASSERT_TRUE(streams.ok()) << streams.error().message;
  const auto decoded = core::codec::decode_meshopt(bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;

  const auto [gltf, bin] = glb_chunks(test::read_file(*dir_ / "cut-meshopt.glb"));
  EXPECT_EQ(gltf.at("extensionsRequired"), json({"EXT_meshopt_compression", "KHR_mesh_quantization"}));
  const json& primitive = gltf.at("meshes")[0].at("primitives")[0];
  const auto stream_of = [&](std::size_t accessor) {
    const json& view =
        gltf.at("bufferViews").at(gltf.at("accessors").at(accessor).at("bufferView").get<std::size_t>());
    const json& compressed = view.at("extensions").at("EXT_meshopt_compression");
    EXPECT_EQ(compressed.at("buffer"), 0);
    EXPECT_EQ(view.at("buffer"), 1);  // the fallback buffer, which has no bytes
    const std::size_t offset = compressed.at("byteOffset"), length = compressed.at("byteLength");
    EXPECT_LE(offset + length, bin.size());
    return bin.substr(offset, length);
  };
  const auto as_string = [](std::span<const std::uint8_t> s) { return std::string(s.begin(), s.end()); };
  const std::size_t position = primitive.at("attributes").at("POSITION");
  EXPECT_EQ(stream_of(position), as_string(streams->positions));
  EXPECT_EQ(stream_of(primitive.at("attributes").at("NORMAL")), as_string(streams->normals));
  EXPECT_EQ(stream_of(primitive.at("indices")), as_string(streams->triangles));
  EXPECT_EQ(gltf.at("accessors").at(primitive.at("indices").get<std::size_t>()).at("count"),
            3 * std::size_t{streams->triangle_count});
  // Positions: the stored values' own bounds, dequantized by the node.
  const json& bounds = gltf.at("accessors").at(position);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(bounds.at("min")[k], decoded->stored_min[k]);
    EXPECT_EQ(bounds.at("max")[k], decoded->stored_max[k]);
    EXPECT_FLOAT_EQ(gltf.at("nodes")[0].at("translation")[k].get<float>(), streams->origin[k]);
    EXPECT_FLOAT_EQ(gltf.at("nodes")[0].at("scale")[k].get<float>(), streams->step);
  }
  expect_valid_gltf(*dir_, {*dir_ / "cut-meshopt.glb"});
}

TEST_F(ToolsTest, ClientGlbEmbedsTheDracoBytesItReceived) {
  // One request three times on fresh connections, which the server answers with the same bytes: as
  // .drc (the payload as received), as .glb (that payload as the Draco buffer view, unchanged) and
  // as a plain .glb (decoded: as many triangles and vertices as the payload holds).
  client_extract("-o " + (*dir_ / "cut.drc").string());
  client_extract("-o " + (*dir_ / "cut.glb").string());
  client_extract("--gltf-compression off -o " + (*dir_ / "cut-plain.glb").string());
  const std::string drc = test::read_file(*dir_ / "cut.drc");
  ASSERT_GT(drc.size(), 0u);

  const auto [gltf, bin] = glb_chunks(test::read_file(*dir_ / "cut.glb"));
  const json& primitive = gltf.at("meshes")[0].at("primitives")[0];
  const json& view = gltf.at("bufferViews")
                         .at(primitive.at("extensions")
                                 .at("KHR_draco_mesh_compression")
                                 .at("bufferView")
                                 .get<std::size_t>());
  const std::size_t offset = view.value("byteOffset", 0u), length = view.at("byteLength");
  ASSERT_LE(offset + length, bin.size());
  EXPECT_EQ(bin.substr(offset, length), drc);

  const auto decoded =
      core::codec::decode_draco(std::span(reinterpret_cast<const std::uint8_t*>(drc.data()), drc.size()));
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  const auto [plain, plain_bin] = glb_chunks(test::read_file(*dir_ / "cut-plain.glb"));
  const json& p = plain.at("meshes")[0].at("primitives")[0];
  EXPECT_FALSE(plain.contains("extensionsRequired"));
  EXPECT_EQ(plain.at("accessors").at(p.at("indices").get<std::size_t>()).at("count"),
            decoded->mesh.triangles.size());
  EXPECT_EQ(plain.at("accessors").at(p.at("attributes").at("POSITION").get<std::size_t>()).at("count"),
            decoded->mesh.vertex_count());

  expect_valid_gltf(*dir_, {*dir_ / "cut.glb", *dir_ / "cut-plain.glb"});
}

TEST_F(ToolsTest, ClientWritesASceneAsANodePerInstance) {
  // Three instances of the bunny from a scene file: the .glb has a node per instance with the file's
  // matrix and a mesh of as many triangles as the reply gave the instance, and passes the validator.
  const auto& matrices = kThreeBunnies;
  write_three_bunnies("scene.json");
  const auto glb = *dir_ / "scene.glb";
  const std::string command = fmt::format(
      "{} --port {} scene {} --error-px 1 --budget 3000 -o {} > {} 2>&1", MTLOD_CLIENT_BINARY,
      server_->port(), (*dir_ / "scene.json").string(), glb.string(), (*dir_ / "client.log").string());
  ASSERT_EQ(std::system(command.c_str()), 0) << command << "\n" << test::read_file(*dir_ / "client.log");
  const std::string log = test::read_file(*dir_ / "client.log");
  const auto [gltf, bin] = glb_chunks(test::read_file(glb));
  ASSERT_EQ(gltf.at("nodes").size(), 3u);
  ASSERT_EQ(gltf.at("scenes")[0].at("nodes"), json({0, 1, 2}));
  std::size_t triangles = 0;
  for (std::size_t i = 0; i < 3; ++i) {
    const json& node = gltf.at("nodes")[i];
    for (int k = 0; k < 16; ++k) EXPECT_EQ(node.at("matrix")[k].get<double>(), matrices[i][k]) << i;
    const json& primitive = gltf.at("meshes").at(node.at("mesh").get<std::size_t>()).at("primitives")[0];
    const std::size_t count = gltf.at("accessors").at(primitive.at("indices").get<std::size_t>()).at("count");
    triangles += count / 3;
    // The client's line for this instance names its triangles.
    EXPECT_NE(log.find(fmt::format("{:>4} {:<16} {:>8} triangles", i, "bunny", count / 3)), std::string::npos)
        << log;
  }
  EXPECT_LE(triangles, 3000u);
  EXPECT_NE(log.find(fmt::format("scene: 3 instances, {} triangles", triangles)), std::string::npos) << log;
  expect_valid_gltf(*dir_, {glb});

  // A scene naming a model the server does not have is refused whole.
  json scene = json::parse(test::read_file(*dir_ / "scene.json"));
  scene["instances"].push_back({{"model", "teapot"}});
  test::write_file(*dir_ / "scene.json", scene.dump());
  EXPECT_NE(std::system(command.c_str()), 0);
  EXPECT_NE(test::read_file(*dir_ / "client.log").find("unknown_model"), std::string::npos)
      << test::read_file(*dir_ / "client.log");
}

}  // namespace
}  // namespace mtlod

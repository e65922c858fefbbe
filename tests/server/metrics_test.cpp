// GET /metrics: the histogram buckets against a brute-force count, and a real server's scrape after
// known traffic — every count what was sent, histograms that add up, session memory that returns
// to zero — passed through Prometheus' own `promtool check metrics`.
#include "server/metrics.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "clients/common/server_connection.hpp"
#include "protocol/frame.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/server/http_client.hpp"
#include "tests/server/server_process.hpp"
#include "tests/server/test_requests.hpp"

namespace mtlod {
namespace {

using server::PrometheusHistogram;

TEST(PrometheusHistogram, BucketsCountWhatIsAtOrBelowEachBound) {
  std::mt19937_64 rng(5);
  std::vector<std::uint64_t> observed;
  PrometheusHistogram h;
  for (int i = 0; i < 5000; ++i) {
    // Log-uniform from 10 µs to 10 s, plus every bound itself (le means "at or below").
    const auto us =
        static_cast<std::uint64_t>(std::exp(std::uniform_real_distribution<double>(2.3, 16.1)(rng)));
    observed.push_back(us);
  }
  for (const std::uint64_t bound : PrometheusHistogram::kBoundsUs) observed.push_back(bound);
  std::uint64_t sum = 0;
  for (const std::uint64_t us : observed) h.observe(us), sum += us;
  const auto counts = h.cumulative();
  for (std::size_t b = 0; b < PrometheusHistogram::kBoundsUs.size(); ++b) {
    const auto expected =
        static_cast<std::uint64_t>(std::count_if(observed.begin(), observed.end(), [&](std::uint64_t us) {
          return us <= PrometheusHistogram::kBoundsUs[b];
        }));
    EXPECT_EQ(counts[b], expected) << "le " << PrometheusHistogram::kBoundsUs[b];
  }
  EXPECT_EQ(counts.back(), observed.size());
  EXPECT_EQ(h.sum_us(), sum);
}

// Samples of a Prometheus text exposition: "name{labels}" → value.
std::map<std::string, double> samples_of(const std::string& text) {
  std::map<std::string, double> out;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    const std::size_t space = line.rfind(' ');
    out[line.substr(0, space)] = std::stod(line.substr(space + 1));
  }
  return out;
}

// promtool's verdict on `text`: empty when it finds nothing to say.
std::string promtool_check(const std::string& text, const std::filesystem::path& dir) {
  const auto file = dir / "scrape.txt";
  std::ofstream(file) << text;
  const std::string command = "promtool check metrics < " + file.string() + " 2>&1; echo exit=$?";
  std::string out;
  if (FILE* pipe = popen(command.c_str(), "r")) {
    char buffer[512];
    while (std::fgets(buffer, sizeof buffer, pipe)) out += buffer;
    pclose(pipe);
  }
  return out;
}

TEST(MetricsEndpoint, CountsWhatWasSentInPrometheusFormat) {
  const auto dir = test::scratch_dir("metrics");
  const auto bunny = test::models_dir() / "bunny.ply";
  if (!std::filesystem::exists(bunny)) GTEST_SKIP() << "no " << bunny;
  test::ServerProcess server(
      {"--mesh", bunny.string(), "--cache-dir", dir.string(), "--http-port", "0", "--log-level", "warn"},
      dir);
  ASSERT_TRUE(server.running()) << server.log();

  {
    auto c = clients::ServerConnection::open("127.0.0.1", server.port());
    ASSERT_TRUE(c.ok()) << c.error().message;
    ASSERT_TRUE(c->call(protocol::Hello{protocol::kProtocolVersion, "metrics-test", ""}, 1).ok());
    auto info = c->call(protocol::ModelInfo{"bunny"}, 2);
    ASSERT_TRUE(info.ok()) << info.error().message;
    const auto& model = std::get<protocol::ModelInfoReply>(info->header.reply);
    for (std::uint64_t id = 3; id < 5; ++id) {
      auto mesh = c->call(test::framing_extract("bunny", model, {128, 128}, 1.0), id);
      ASSERT_TRUE(mesh.ok() && std::holds_alternative<protocol::MeshReply>(mesh->header.reply)) << mesh->json;
    }
    auto gaze = c->call(protocol::Gaze{0.3, 0.6, {}, {}}, 5);
    ASSERT_TRUE(gaze.ok() && std::holds_alternative<protocol::MeshReply>(gaze->header.reply)) << gaze->json;
    std::vector<std::uint8_t> bad;
    protocol::append_frame("{not json", {}, bad);
    ASSERT_TRUE(c->send_raw(bad).ok());
    ASSERT_TRUE(c->receive().ok());

    // While the connection is open its session holds the cut.
    const test::HttpReply open = test::http_get(server.http_port(), "/metrics");
    ASSERT_EQ(open.status, 200) << open.head;
    EXPECT_NE(open.head.find("Content-Type: text/plain; version=0.0.4"), std::string::npos) << open.head;
    auto m = samples_of(open.body);
    EXPECT_EQ(m["mtlod_requests_total{type=\"hello\"}"], 1);
    EXPECT_EQ(m["mtlod_requests_total{type=\"model_info\"}"], 1);
    EXPECT_EQ(m["mtlod_requests_total{type=\"extract\"}"], 2);
    EXPECT_EQ(m["mtlod_requests_total{type=\"gaze\"}"], 1);
    EXPECT_EQ(m["mtlod_requests_total{type=\"ping\"}"], 0);
    EXPECT_EQ(m["mtlod_errors_total{code=\"bad_json\"}"], 1);
    EXPECT_EQ(m["mtlod_errors_total{code=\"internal\"}"], 0);
    EXPECT_EQ(m["mtlod_connections_open"], 1);
    EXPECT_EQ(m["mtlod_models"], 1);
    EXPECT_GT(m["mtlod_model_memory_bytes"], 0);
    EXPECT_GT(m["mtlod_session_memory_bytes"], 0);
    EXPECT_GE(m["mtlod_memory_held_bytes"], m["mtlod_session_memory_bytes"]);
    EXPECT_GT(m["mtlod_received_bytes_total"], 0);
    EXPECT_GT(m["mtlod_sent_bytes_total"], m["mtlod_received_bytes_total"]) << "replies carry meshes";
    // Every stage of every type: cumulative buckets, +Inf equal to the count, as many as were served.
    for (const auto& [type, served] : {std::pair{"extract", 2.0}, std::pair{"gaze", 1.0}}) {
      for (const char* stage : server::Metrics::kStages) {
        const std::string labels = std::string("type=\"") + type + "\",stage=\"" + stage + "\"";
        double previous = 0;
        for (std::size_t b = 0; b <= PrometheusHistogram::kBoundsUs.size(); ++b) {
          std::ostringstream le;
          if (b < PrometheusHistogram::kBoundsUs.size()) {
            le << PrometheusHistogram::kBoundsUs[b] / 1e6;
          } else {
            le << "+Inf";
          }
          const std::string key =
              "mtlod_extraction_duration_seconds_bucket{" + labels + ",le=\"" + le.str() + "\"}";
          ASSERT_TRUE(m.count(key)) << key;
          EXPECT_GE(m[key], previous) << key;
          previous = m[key];
        }
        EXPECT_EQ(previous, served) << labels;
        EXPECT_EQ(m["mtlod_extraction_duration_seconds_count{" + labels + "}"], served) << labels;
      }
    }
    const std::string verdict = promtool_check(open.body, dir);
    if (verdict.find("not found") != std::string::npos) GTEST_SKIP() << "no promtool: " << verdict;
    EXPECT_EQ(verdict, "exit=0\n") << open.body;
  }
  // Closed: the session's memory goes back (the server notices the close a moment later).
  double session_bytes = -1;
  for (int i = 0; i < 100 && session_bytes != 0; ++i) {
    if (i) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    session_bytes =
        samples_of(test::http_get(server.http_port(), "/metrics").body)["mtlod_session_memory_bytes"];
  }
  EXPECT_EQ(session_bytes, 0);
}

}  // namespace
}  // namespace mtlod

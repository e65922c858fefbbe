// Normals end to end: a PLY without normals, one with NaN and zero-length normals, and an MT file
// stored without normals all reach Google's draco_decoder with a unit normal at every vertex, the
// original surface's (computed where the file gave none or broken ones), in whole and delta
// replies, by default; `normals: false` leaves them out. And mtlod-client extracts a model with no
// criteria flags at all.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "clients/common/server_connection.hpp"
#include "core/build/vertex_normals.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "core/model/bounds.hpp"
#include "protocol/camera.hpp"
#include "protocol/frame.hpp"
#include "tests/clients/delta_meshes.hpp"
#include "tests/core/googles_draco_decoder.hpp"
#include "tests/core/mesh_compare.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/server/server_process.hpp"
#include "tests/server/test_requests.hpp"

namespace mtlod {
namespace {

namespace fs = std::filesystem;

struct Served {
  fs::path dir;
  core::model::Mesh shell;           // the surface every model here comes from
  std::vector<float> computed;       // its angle-weighted normals
  std::vector<std::uint8_t> broken;  // per vertex: its normal in broken.ply is NaN or zero-length
  std::vector<float> given;          // broken.ply's normals (the usable ones are kept)
  std::string broken_log;            // what mtlod-build said about broken.ply
  core::model::Bounds box;
  std::unique_ptr<test::ServerProcess> server;
};

// Runs mtlod-build on `ply`, writing `mt`; returns what it printed.
std::string build(const fs::path& ply, const fs::path& mt) {
  const fs::path log = mt.string() + ".log";
  const std::string command = std::string(MTLOD_BUILD_BINARY) + " " + ply.string() + " -o " + mt.string() +
                              " > " + log.string() + " 2>&1";
  EXPECT_EQ(std::system(command.c_str()), 0) << test::read_file(log);
  return test::read_file(log);
}

const Served& served() {
  static const Served s = [] {
    Served s;
    s.dir = test::scratch_dir("normals");
    core::eval::GenerateOptions options;
    options.shape = core::eval::Shape::kShell;
    options.target_triangles = 20'000;
    s.shell = core::eval::generate_mesh(options);
    s.computed = core::build::vertex_normals(s.shell.positions, s.shell.triangles);
    EXPECT_TRUE(core::io::save_mesh(s.dir / "plain.ply", s.shell).ok());
    build(s.dir / "plain.ply", s.dir / "plain.mt");

    // Given normals pointing a fixed odd way, every 7th NaN and every 11th zero.
    core::model::Mesh broken = s.shell;
    const std::size_t n = broken.vertex_count();
    broken.normals.resize(3 * n);
    s.broken.assign(n, 0);
    for (std::size_t v = 0; v < n; ++v) {
      const float own[3] = {0.6f, 0.0f, 0.8f};
      std::copy_n(own, 3, &broken.normals[3 * v]);
      if (v % 7 == 0) broken.normals[3 * v + 1] = std::numeric_limits<float>::quiet_NaN(), s.broken[v] = 1;
      if (v % 11 == 0) std::fill_n(&broken.normals[3 * v], 3, 0.0f), s.broken[v] = 1;
    }
    s.given = broken.normals;
    EXPECT_TRUE(core::io::save_mesh(s.dir / "broken.ply", broken).ok());
    s.broken_log = build(s.dir / "broken.ply", s.dir / "broken.mt");

    // An MT written without normals, as mtlod-build wrote them before every MT had them.
    auto mt = core::io::read_mt_file(s.dir / "plain.mt", core::io::MtLoad::kRead);
    EXPECT_TRUE(mt.ok());
    core::model::MtArrays arrays = mt->arrays();
    arrays.normals.clear();
    EXPECT_TRUE(core::io::write_mt_file(s.dir / "legacy.mt", core::model::Mt(std::move(arrays))).ok());

    s.box = core::model::bounds_of(s.shell.positions);
    s.server = std::make_unique<test::ServerProcess>(
        std::vector<std::string>{(s.dir / "plain.mt").string(), (s.dir / "broken.mt").string(),
                                 (s.dir / "legacy.mt").string(), "--log-level", "info"},
        s.dir);
    return s;
  }();
  return s;
}

// A view with the default attributes (the protocol's defaults: normals on).
protocol::Extract request(const std::string& model) {
  protocol::Extract e = test::framing_extract(model, core::model::to_double(served().box.lo),
                                              core::model::to_double(served().box.hi), {256, 256}, 1.0);
  e.criteria.regions[core::view::Criterion::kFocus] = protocol::Region{20, 0.25, {{0.5, 0.5}}};
  return e;
}

// Every decoded vertex has a unit normal within the 10-bit octahedral quantization of `want` at the
// shell's vertex it decodes to.
void expect_normals(const core::model::Mesh& decoded, const std::vector<float>& want,
                    const std::string& what) {
  const Served& s = served();
  ASSERT_GT(decoded.vertex_count(), 0u) << what;
  ASSERT_EQ(decoded.normals.size(), decoded.positions.size()) << what << ": no normals";
  const float tolerance = test::draco_tolerance(s.box.largest_side(), 14);
  const auto match =
      test::match_vertices(decoded.positions, s.shell.positions, s.shell.triangles, 4 * tolerance, tolerance);
  std::size_t off = 0;
  double worst = 1;
  for (std::size_t i = 0; i < match.size(); ++i) {
    const float* n = &decoded.normals[3 * i];
    const float* w = &want[3 * std::size_t{match[i]}];
    const double length = std::sqrt(double{n[0]} * n[0] + double{n[1]} * n[1] + double{n[2]} * n[2]);
    const double cosine = (n[0] * w[0] + n[1] * w[1] + n[2] * w[2]) / length;
    worst = std::min(worst, cosine);
    // 10 bits per octahedral coordinate: a few thousandths of a radian.
    off += !(std::abs(length - 1.0) < 0.01 && cosine > 0.9995);
  }
  EXPECT_EQ(off, 0u) << what << ": normals off the expected ones (worst cosine " << worst << ")";
}

const protocol::MeshReply* as_mesh(const clients::ReplyFrame& f) {
  return std::get_if<protocol::MeshReply>(&f.header.reply);
}

Result<core::model::Mesh> fetch(const std::string& model, const protocol::Extract& e,
                                const std::string& name) {
  auto c = clients::ServerConnection::open("127.0.0.1", served().server->port());
  if (!c) return c.take_error();
  MTLOD_TRY(clients::ReplyFrame reply, c->call(e, 1));
  if (!as_mesh(reply)) return make_error(ErrorCode::kInternal, model + ": " + reply.json);
  return test::googles_draco_decode(reply.payload, served().dir, name);
}

TEST(Normals, APlyWithoutNormalsIsServedWithTheSurfacesNormalsByDefault) {
  ASSERT_TRUE(served().server->running()) << served().server->log();
  auto decoded = fetch("plain", request("plain"), "plain");
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  expect_normals(*decoded, served().computed, "plain");
}

TEST(Normals, NaNAndZeroLengthNormalsAreComputedAndTheBuildWarns) {
  const Served& s = served();
  EXPECT_NE(s.broken_log.find("warning:"), std::string::npos) << s.broken_log;
  EXPECT_NE(s.broken_log.find("NaN or zero-length"), std::string::npos) << s.broken_log;
  std::vector<float> want = s.given;
  for (std::size_t v = 0; v < s.broken.size(); ++v) {
    if (s.broken[v]) std::copy_n(&s.computed[3 * v], 3, &want[3 * v]);
  }
  auto decoded = fetch("broken", request("broken"), "broken");
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  for (const float x : decoded->normals)
    ASSERT_TRUE(std::isfinite(x)) << "a non-finite normal reached the client";
  expect_normals(*decoded, want, "broken");
}

TEST(Normals, AnMtStoredWithoutNormalsGetsComputedOnesAtLoad) {
  const Served& s = served();
  EXPECT_NE(s.server->log().find("stored without normals"), std::string::npos) << s.server->log();
  auto decoded = fetch("legacy", request("legacy"), "legacy");
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  expect_normals(*decoded, s.computed, "legacy");
}

TEST(Normals, DeltaRepliesCarryTheNormalsOfWhatTheyAdd) {
  const Served& s = served();
  auto c = clients::ServerConnection::open("127.0.0.1", s.server->port());
  ASSERT_TRUE(c.ok()) << c.error().message;
  const std::size_t checked =
      test::check_delta_meshes(*c, request("plain"), {0.2, 0.8}, s.dir,
                               [&](const core::model::Mesh& m, std::uint64_t, const std::string& what) {
                                 expect_normals(m, s.computed, what);
                               });
  EXPECT_GE(checked, 2u);
}

TEST(Normals, AClientMayLeaveThemOut) {
  protocol::Extract without = request("plain");
  without.normals = false;
  auto decoded = fetch("plain", without, "without");
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  EXPECT_GT(decoded->vertex_count(), 0u);
  EXPECT_TRUE(decoded->normals.empty()) << "normals sent though the request left them out";
}

TEST(Normals, MtlodClientExtractsWithNoCriteriaFlags) {
  const Served& s = served();
  const fs::path out = s.dir / "cli.ply", log = s.dir / "cli.log";
  const std::string command = std::string(MTLOD_CLIENT_BINARY) + " --port " +
                              std::to_string(s.server->port()) + " extract plain -o " + out.string() + " > " +
                              log.string() + " 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << test::read_file(log);
  auto loaded = core::io::load_mesh(out, {.clean = false});
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_GT(loaded->mesh.triangle_count(), 0u);
  EXPECT_EQ(loaded->mesh.normals.size(), loaded->mesh.positions.size()) << "the decoded mesh has no normals";
}

}  // namespace
}  // namespace mtlod

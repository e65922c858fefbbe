// Vertex colours end to end: a coloured PLY goes through mtlod-build into an .mt file, the real
// server sends its colours in the Draco payload (COLOR) of whole and delta replies, and Google's
// draco_decoder gives every vertex the colour the PLY gave it.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "clients/common/server_connection.hpp"
#include "core/codec/draco_decode.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mesh_io.hpp"
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
  core::model::Mesh painted;  // the coloured PLY's mesh
  core::model::Bounds box;
  std::unique_ptr<test::ServerProcess> server;
};

// Runs mtlod-build on `ply`, writing `mt`; its output goes to the test's log on failure.
void build(const fs::path& ply, const fs::path& mt) {
  const fs::path log = mt.string() + ".log";
  const std::string command = std::string(MTLOD_BUILD_BINARY) + " " + ply.string() + " -o " + mt.string() +
                              " > " + log.string() + " 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << test::read_file(log);
}

const Served& served() {
  static const Served s = [] {
    Served s;
    s.dir = test::scratch_dir("colours");
    core::eval::GenerateOptions options;
    options.shape = core::eval::Shape::kShell;
    options.target_triangles = 20'000;
    options.colors = true;
    s.painted = core::eval::generate_mesh(options);
    EXPECT_TRUE(core::io::save_mesh(s.dir / "painted.ply", s.painted).ok());
    options.colors = false;
    EXPECT_TRUE(core::io::save_mesh(s.dir / "plain.ply", core::eval::generate_mesh(options)).ok());
    build(s.dir / "painted.ply", s.dir / "painted.mt");
    build(s.dir / "plain.ply", s.dir / "plain.mt");
    s.box = core::model::bounds_of(s.painted.positions);
    s.server = std::make_unique<test::ServerProcess>(
        std::vector<std::string>{(s.dir / "painted.mt").string(), (s.dir / "plain.mt").string(),
                                 "--log-level", "warn"},
        s.dir);
    return s;
  }();
  return s;
}

protocol::Extract request(const std::string& model) {
  protocol::Extract e = test::framing_extract(model, core::model::to_double(served().box.lo),
                                              core::model::to_double(served().box.hi), {256, 256}, 1.0);
  e.criteria.regions[core::view::Criterion::kFocus] = protocol::Region{20, 0.25, {{0.5, 0.5}}};
  e.colors = true;
  return e;
}

// Every vertex of `decoded` has the colour of the painted mesh's vertex at its position (the server
// quantizes positions on the model's bounding box).
void expect_painted(const core::model::Mesh& decoded, const std::string& what) {
  const Served& s = served();
  ASSERT_GT(decoded.vertex_count(), 0u) << what;
  ASSERT_EQ(decoded.colors.size(), decoded.positions.size()) << what << ": no colours";
  const float tolerance = test::draco_tolerance(s.box.largest_side(), 14);
  const auto match = test::match_vertices(decoded.positions, s.painted.positions, s.painted.triangles,
                                          4 * tolerance, tolerance);
  std::size_t wrong = 0;
  for (std::size_t i = 0; i < match.size(); ++i)
    for (int k = 0; k < 3; ++k) wrong += decoded.colors[3 * i + k] != s.painted.colors[3 * match[i] + k];
  EXPECT_EQ(wrong, 0u) << what << ": colour components that differ from the PLY's";
}

const protocol::MeshReply* as_mesh(const clients::ReplyFrame& f) {
  return std::get_if<protocol::MeshReply>(&f.header.reply);
}

TEST(Colours, ThePlysColoursReachGooglesDecoder) {
  const Served& s = served();
  ASSERT_TRUE(s.server->running()) << s.server->log();
  auto c = clients::ServerConnection::open("127.0.0.1", s.server->port());
  ASSERT_TRUE(c.ok()) << c.error().message;
  auto info = c->call(protocol::ModelInfo{"painted"}, 1);
  ASSERT_TRUE(info.ok()) << info.error().message;
  EXPECT_TRUE(std::get<protocol::ModelInfoReply>(info->header.reply).colors) << info->json;

  auto reply = c->call(request("painted"), 2);
  ASSERT_TRUE(reply.ok()) << reply.error().message;
  ASSERT_NE(as_mesh(*reply), nullptr) << reply->json;
  auto loaded = test::googles_draco_decode(reply->payload, s.dir, "whole");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->triangle_count(), as_mesh(*reply)->triangles);
  expect_painted(*loaded, "whole reply");
}

TEST(Colours, DeltaRepliesCarryTheColoursOfWhatTheyAdd) {
  const Served& s = served();
  auto c = clients::ServerConnection::open("127.0.0.1", s.server->port());
  ASSERT_TRUE(c.ok()) << c.error().message;
  const std::size_t checked =
      test::check_delta_meshes(*c, request("painted"), {0.2, 0.8}, s.dir,
                               [](const core::model::Mesh& m, std::uint64_t added, const std::string& what) {
                                 EXPECT_EQ(m.triangle_count(), added) << what;
                                 expect_painted(m, what);
                               });
  EXPECT_GE(checked, 2u);  // the first reply and at least one gaze added triangles
}

TEST(Colours, AModelWithoutColoursSaysSo) {
  const Served& s = served();
  auto c = clients::ServerConnection::open("127.0.0.1", s.server->port());
  ASSERT_TRUE(c.ok()) << c.error().message;
  auto reply = c->call(request("plain"), 1);
  ASSERT_TRUE(reply.ok()) << reply.error().message;
  const auto* error = std::get_if<protocol::ErrorReply>(&reply->header.reply);
  ASSERT_NE(error, nullptr) << reply->json;
  EXPECT_EQ(error->code, protocol::ErrorKind::kBadRequest);
  EXPECT_NE(error->message.find("no colours"), std::string::npos) << error->message;
  // The connection goes on: the same view without colours is served.
  protocol::Extract plain = request("plain");
  plain.colors = false;
  auto served_plain = c->call(plain, 2);
  ASSERT_TRUE(served_plain.ok()) << served_plain.error().message;
  EXPECT_NE(as_mesh(*served_plain), nullptr) << served_plain->json;
}

}  // namespace
}  // namespace mtlod

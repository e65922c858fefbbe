// Integration tests: the real mtlod-server binary on an OS-chosen loopback port, driven by the
// clients' connection code. Payloads are decoded and compared with an in-process extraction.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <map>
#include <random>
#include <thread>

#include "clients/common/delta_mesh.hpp"
#include "clients/common/server_connection.hpp"
#include "core/build/mt_builder.hpp"
#include "core/codec/cut_encoder.hpp"
#include "core/codec/draco_decode.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "core/model/bounds.hpp"
#include "core/view/occupancy_levels.hpp"
#include "core/view/scene_extract.hpp"
#include "core/view/view_extract.hpp"
#include "protocol/camera.hpp"
#include "protocol/frame.hpp"
#include "protocol/parse.hpp"
#include "protocol/view_request.hpp"
#include "tests/core/googles_draco_decoder.hpp"
#include "tests/core/mesh_compare.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/protocol/protocol_cases.hpp"
#include "tests/server/server_process.hpp"

namespace mtlod {
namespace {

using clients::ReplyFrame;
using clients::ServerConnection;

// The model served: the built-in bunny (or a generated sphere when models are not prepared),
// saved as bunny.mt in a scratch folder.
struct Fixture {
  std::filesystem::path dir;
  core::model::Mt mt;
  std::unique_ptr<core::view::OccupancyLevels> levels;
  std::unique_ptr<test::ServerProcess> server;
};

Fixture* g_fixture = nullptr;

class ServerTest : public testing::Test {
 protected:
  static void SetUpTestSuite() {
    g_fixture = new Fixture;
    g_fixture->dir = test::scratch_dir("server");
    core::model::Mesh mesh;
    if (auto bunny = core::io::load_mesh(test::models_dir() / "bunny.ply"); bunny.ok()) {
      mesh = std::move(bunny->mesh);
    } else {
      core::eval::GenerateOptions o;
      o.target_triangles = 4000;
      mesh = core::eval::generate_mesh(o);
    }
    auto mt = core::build::build_mt(mesh);
    ASSERT_TRUE(mt.ok()) << mt.error().message;
    ASSERT_TRUE(core::io::write_mt_file(g_fixture->dir / "bunny.mt", *mt).ok());
    g_fixture->mt = std::move(*mt);
    g_fixture->levels = core::view::OccupancyLevels::make(g_fixture->mt).value();
    // A scene the server loads: two instances of the model, the second moved and halved.
    test::write_file(g_fixture->dir / "pair.json",
                     R"({"instances": [{"model": "bunny"},
                                       {"model": "bunny", "matrix": [0.5,0,0,0, 0,0.5,0,0, 0,0,0.5,0, 1,0,-1,1]}]})");
    g_fixture->server = std::make_unique<test::ServerProcess>(
        std::vector<std::string>{(g_fixture->dir / "bunny.mt").string(), "--scene",
                                 (g_fixture->dir / "pair.json").string(), "--workers", "2", "--log-level",
                                 "warn"},
        g_fixture->dir);
    ASSERT_TRUE(g_fixture->server->running()) << g_fixture->server->log();
  }
  static void TearDownTestSuite() {
    delete g_fixture;
    g_fixture = nullptr;
  }
  void SetUp() override {
    ASSERT_NE(g_fixture, nullptr);
    ASSERT_TRUE(g_fixture->server->running()) << g_fixture->server->log();
  }

  static ServerConnection connect() {
    auto c = ServerConnection::open("127.0.0.1", g_fixture->server->port());
    EXPECT_TRUE(c.ok()) << c.error().message;
    return std::move(*c);
  }

  void expect_deltas_rebuild_the_cut(core::codec::Codec codec);
  void expect_extract_decodes_to_the_in_process_cut(core::codec::Codec codec);

  // A camera looking at the model from the front, with silhouette and focus criteria.
  static protocol::Extract extract_request(double focus_x = 0.5, double focus_y = 0.5) {
    protocol::Extract e;
    e.model = "bunny";
    const core::model::Bounds box = core::model::bounds_of(g_fixture->mt.positions);
    protocol::look_at_camera(
        protocol::frame_bounds(core::model::to_double(box.lo), core::model::to_double(box.hi)), 4.0 / 3.0,
        e.view, e.projection);
    e.grid = {128, 96};
    e.error = 2;
    e.error_unit = core::view::ErrorUnits::kScreenPixels;
    e.criteria.regions[core::view::Criterion::kSilhouette] = protocol::Region{2, 0, {}};
    e.criteria.regions[core::view::Criterion::kFocus] = protocol::Region{10, 0.2, {{focus_x, focus_y}}};
    return e;
  }
};

const protocol::MeshReply* as_mesh(const ReplyFrame& f) {
  return std::get_if<protocol::MeshReply>(&f.header.reply);
}
const protocol::ErrorReply* as_error(const ReplyFrame& f) {
  return std::get_if<protocol::ErrorReply>(&f.header.reply);
}

TEST_F(ServerTest, HelloStatesVersionAndLimits) {
  ServerConnection c = connect();
  auto reply = c.call(protocol::Hello{1, "test"}, 1);
  ASSERT_TRUE(reply.ok()) << reply.error().message;
  const auto& hello = std::get<protocol::HelloReply>(reply->header.reply);
  EXPECT_EQ(hello.version, protocol::kProtocolVersion);
  EXPECT_EQ(hello.limits.max_grid, protocol::Limits{}.max_grid);
  auto models = c.call(protocol::ListModels{}, 2);
  ASSERT_TRUE(models.ok());
  const auto& list = std::get<protocol::ModelsReply>(models->header.reply).models;
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0].name, "bunny");
  EXPECT_EQ(list[0].vertices, g_fixture->mt.vertex_count());
  EXPECT_GT(list[0].memory_bytes, 0u);
}

TEST_F(ServerTest, HelloSetsTheCodecOfExtractsThatNameNone) {
  using core::codec::Codec;
  ServerConnection c = connect();
  auto hello = c.call(protocol::Hello{1, "test", "", Codec::kMeshopt}, 1);
  ASSERT_TRUE(hello.ok()) << hello.error().message;
  EXPECT_EQ(std::get<protocol::HelloReply>(hello->header.reply).codec, Codec::kMeshopt);

  protocol::Extract request = extract_request();
  request.codec.reset();
  auto meshopt = c.call(request, 2);
  ASSERT_TRUE(meshopt.ok()) << meshopt.error().message;
  ASSERT_NE(as_mesh(*meshopt), nullptr) << meshopt->json;
  EXPECT_EQ(as_mesh(*meshopt)->codec, Codec::kMeshopt);
  auto decoded = core::codec::decode_payload(Codec::kMeshopt, meshopt->payload);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  EXPECT_EQ(decoded->triangle_count(), as_mesh(*meshopt)->triangles);

  // The gazes that follow keep the extract's codec; an extract naming one overrides the connection's.
  auto gaze = c.call(protocol::Gaze{0.6, 0.5}, 3);
  ASSERT_TRUE(gaze.ok()) << gaze.error().message;
  ASSERT_NE(as_mesh(*gaze), nullptr) << gaze->json;
  EXPECT_EQ(as_mesh(*gaze)->codec, Codec::kMeshopt);
  EXPECT_TRUE(core::codec::decode_payload(Codec::kMeshopt, gaze->payload).ok());
  request.codec = Codec::kDraco;
  auto draco = c.call(request, 4);
  ASSERT_TRUE(draco.ok()) << draco.error().message;
  ASSERT_NE(as_mesh(*draco), nullptr) << draco->json;
  EXPECT_EQ(as_mesh(*draco)->codec, Codec::kDraco);
  EXPECT_EQ(as_mesh(*draco)->triangles, as_mesh(*meshopt)->triangles);

  // What the connection's codec cannot carry is refused as if the extract had named it.
  request.codec.reset();
  request.labels = true;
  auto labels = c.call(request, 5);
  ASSERT_TRUE(labels.ok()) << labels.error().message;
  ASSERT_NE(as_error(*labels), nullptr) << labels->json;
  EXPECT_EQ(as_error(*labels)->code, protocol::ErrorKind::kBadRequest);
  EXPECT_NE(as_error(*labels)->message.find("cannot carry attributes.labels"), std::string::npos);

  // A hello without a codec keeps the connection's.
  auto again = c.call(protocol::Hello{1, "test"}, 6);
  ASSERT_TRUE(again.ok()) << again.error().message;
  EXPECT_EQ(std::get<protocol::HelloReply>(again->header.reply).codec, Codec::kMeshopt);
}

TEST_F(ServerTest, ExtractDecodesToTheInProcessCut) {
  for (const core::codec::Codec codec : {core::codec::Codec::kDraco, core::codec::Codec::kMeshopt}) {
    SCOPED_TRACE(protocol::enum_name(protocol::kCodecNames, codec));
    expect_extract_decodes_to_the_in_process_cut(codec);
  }
}

void ServerTest::expect_extract_decodes_to_the_in_process_cut(core::codec::Codec codec) {
  protocol::Extract request = extract_request(0.3, 0.4);
  request.codec = codec;
  ServerConnection c = connect();
  auto reply = c.call(request, 7);
  ASSERT_TRUE(reply.ok()) << reply.error().message;
  const auto* mesh = as_mesh(*reply);
  ASSERT_NE(mesh, nullptr) << reply->json;
  EXPECT_EQ(mesh->bytes, reply->payload.size());
  EXPECT_EQ(mesh->codec, codec);

  // The same request computed here, from the same MT file, with a fresh session cut.
  core::view::ViewExtractor extractor(g_fixture->mt, *g_fixture->levels);
  core::cut::Refiner refiner(g_fixture->mt);
  core::view::ViewCache session;
  core::cut::CutMesh cut;
  const core::view::ViewRequest view = protocol::to_view_request(request, g_fixture->mt.has_normals());
  extractor.map(view, &session);
  extractor.occupancy();
  extractor.distance_transforms();
  extractor.allowed_error();
  EXPECT_TRUE(extractor.refine(refiner, cut));
  EXPECT_EQ(mesh->triangles, cut.triangle_count());
  EXPECT_FLOAT_EQ(static_cast<float>(mesh->max_error), cut.max_error);
  // The memory reported is what the same refinement and view session hold here, and the worker's
  // scratch at least holds a per-vertex allowed error.
  EXPECT_EQ(mesh->session_bytes, refiner.memory_bytes() + session.memory_bytes());
  EXPECT_GE(session.memory_bytes(), g_fixture->mt.vertex_count() * sizeof(float));
  EXPECT_GE(mesh->scratch_bytes, g_fixture->mt.vertex_count() * sizeof(float));

  auto decoded = core::codec::decode_payload(codec, reply->payload);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  ASSERT_EQ(decoded->triangle_count(), cut.triangle_count());
  EXPECT_EQ(decoded->vertex_count(), mesh->vertices);
  const float tolerance = test::draco_tolerance(test::used_extent(g_fixture->mt.positions, cut.triangles),
                                                request.quantization.position_bits);
  const auto match = test::match_vertices(decoded->positions, g_fixture->mt.positions, cut.triangles,
                                          4 * tolerance, tolerance);
  EXPECT_EQ(test::canonical_triangles(decoded->triangles, &match), test::canonical_triangles(cut.triangles));
}

// Three instances of the model: one in front, a small one hidden behind it, one beside them. Each
// instance's part of the payload decodes to the cut the same scene gives in-process, the hidden one
// is at its root, and a gaze after the scene answers with the scene again.
TEST_F(ServerTest, ASceneDecodesToTheInProcessCutsOfItsInstances) {
  const core::model::Bounds box = core::model::bounds_of(g_fixture->mt.positions);
  const double size = box.largest_side();
  const std::array<float, 3> c = box.centre();
  auto placed = [&](double scale, double dx, double dz) {
    // Scaled about the box centre, then moved by (dx, 0, dz) box sizes.
    return protocol::Matrix4{scale,
                             0,
                             0,
                             0,
                             0,
                             scale,
                             0,
                             0,
                             0,
                             0,
                             scale,
                             0,
                             (1 - scale) * c[0] + dx * size,
                             (1 - scale) * c[1],
                             (1 - scale) * c[2] + dz * size,
                             1};
  };
  for (const core::codec::Codec codec : {core::codec::Codec::kDraco, core::codec::Codec::kMeshopt}) {
    SCOPED_TRACE(protocol::enum_name(protocol::kCodecNames, codec));
    protocol::Extract request = extract_request(0.3, 0.4);
    request.model.clear();
    request.instances = {
        {"bunny", placed(1.5, -0.3, 0)}, {"bunny", placed(0.3, -0.3, -2)}, {"bunny", placed(0.5, 0.8, 0)}};
    request.criteria.hidden_factor = 1e6;
    request.codec = codec;
    // The camera frames the three of them.
    protocol::look_at_camera(protocol::frame_bounds({c[0] - 1.5 * size, c[1] - size, c[2] - 2.5 * size},
                                                    {c[0] + 1.5 * size, c[1] + size, c[2] + size}),
                             4.0 / 3.0, request.view, request.projection);
    ServerConnection conn = connect();
    auto reply = conn.call(request, 3);
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    const auto* mesh = as_mesh(*reply);
    ASSERT_NE(mesh, nullptr) << reply->json;
    ASSERT_EQ(mesh->instances.size(), 3u) << reply->json;
    EXPECT_TRUE(mesh->model.empty());
    auto parts = protocol::split_scene_payload(*mesh, reply->payload);
    ASSERT_TRUE(parts.ok()) << parts.error().message;

    std::vector<core::view::SceneInstance> instances;
    for (const protocol::Instance& i : request.instances)
      instances.push_back({&g_fixture->mt, g_fixture->levels.get(), protocol::to_glm(i.matrix)});
    core::view::SceneExtractor extractor;
    std::vector<core::cut::CutMesh> cuts;
    ASSERT_TRUE(extractor.extract({protocol::to_view_request(request, true), instances}, cuts).ok());
    std::uint64_t triangles = 0;
    for (std::size_t i = 0; i < cuts.size(); ++i) {
      const protocol::InstanceMesh& one = mesh->instances[i];
      EXPECT_EQ(one.model, "bunny");
      ASSERT_EQ(one.triangles, cuts[i].triangle_count()) << "instance " << i;
      EXPECT_EQ(one.bytes, (*parts)[i].size());
      triangles += one.triangles;
      auto decoded = core::codec::decode_payload(codec, (*parts)[i]);
      ASSERT_TRUE(decoded.ok()) << decoded.error().message;
      const float tolerance = test::draco_tolerance(
          test::used_extent(g_fixture->mt.positions, cuts[i].triangles), request.quantization.position_bits);
      const auto match = test::match_vertices(decoded->positions, g_fixture->mt.positions, cuts[i].triangles,
                                              4 * tolerance, tolerance);
      EXPECT_EQ(test::canonical_triangles(decoded->triangles, &match),
                test::canonical_triangles(cuts[i].triangles))
          << "instance " << i;
    }
    EXPECT_EQ(mesh->triangles, triangles);
    EXPECT_EQ(mesh->instances[1].triangles, g_fixture->mt.root_triangle_count());
    EXPECT_GT(mesh->instances[0].triangles, 4 * g_fixture->mt.root_triangle_count());
    if (codec == core::codec::Codec::kDraco) {
      auto loaded = test::googles_draco_decode((*parts)[2], g_fixture->dir, "scene-instance");
      ASSERT_TRUE(loaded.ok()) << loaded.error().message;
      EXPECT_EQ(loaded->triangle_count(), mesh->instances[2].triangles);
    }
    auto gazed = conn.call(protocol::Gaze{0.7, 0.5, std::nullopt, std::nullopt}, 4);
    ASSERT_TRUE(gazed.ok()) << gazed.error().message;
    ASSERT_NE(as_mesh(*gazed), nullptr) << gazed->json;
    EXPECT_EQ(as_mesh(*gazed)->instances.size(), 3u);
  }
}

TEST_F(ServerTest, ASceneTheServerLoadedIsServedByName) {
  // The named scene and the same instances given in the request get the same meshes.
  protocol::Extract named = extract_request();
  named.model.clear();
  named.scene_name = "pair";
  named.draco.method = core::codec::DracoMethod::kSequential;
  protocol::Extract inline_scene = named;
  inline_scene.scene_name.clear();
  inline_scene.instances = {{"bunny"}, {"bunny", {0.5, 0, 0, 0, 0, 0.5, 0, 0, 0, 0, 0.5, 0, 1, 0, -1, 1}}};
  ServerConnection c = connect();
  auto by_name = c.call(named, 1);
  auto given = c.call(inline_scene, 2);
  ASSERT_TRUE(by_name.ok() && given.ok());
  ASSERT_NE(as_mesh(*by_name), nullptr) << by_name->json;
  ASSERT_NE(as_mesh(*given), nullptr) << given->json;
  ASSERT_EQ(as_mesh(*by_name)->instances.size(), 2u);
  for (std::size_t i = 0; i < 2; ++i)
    EXPECT_EQ(as_mesh(*by_name)->instances[i].triangles, as_mesh(*given)->instances[i].triangles) << i;
  EXPECT_EQ(by_name->payload, given->payload);

  named.scene_name = "trio";
  auto unknown = c.call(named, 3);
  ASSERT_TRUE(unknown.ok());
  ASSERT_NE(as_error(*unknown), nullptr) << unknown->json;
  EXPECT_EQ(as_error(*unknown)->code, protocol::ErrorKind::kUnknownModel);
  EXPECT_EQ(as_error(*unknown)->message, "no scene named 'trio'; loaded: pair");
}

TEST_F(ServerTest, GooglesDracoDecoderReadsAServerPayload) {
  ServerConnection c = connect();
  protocol::Extract request = extract_request();
  request.draco.method = core::codec::DracoMethod::kSequential;
  auto reply = c.call(request, 1);
  ASSERT_TRUE(reply.ok()) << reply.error().message;
  ASSERT_NE(as_mesh(*reply), nullptr) << reply->json;
  auto loaded = test::googles_draco_decode(reply->payload, g_fixture->dir, "reply");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->triangle_count(), as_mesh(*reply)->triangles);
}

// One connection asks for deltas and moves its gaze (small steps and jumps); after every reply, the
// mesh it keeps holds the same triangles, id for id and corner for corner, as the whole cut a new
// connection gets for the same focus (meshopt's index codec may start a triangle at another corner
// of the same winding: for it, corners are compared from the smallest).
void ServerTest::expect_deltas_rebuild_the_cut(core::codec::Codec codec) {
  protocol::Extract request = extract_request(0.3, 0.4);
  request.delta = true;
  request.codec = codec;
  const bool draco = codec == core::codec::Codec::kDraco;
  // A triangle's nine coordinates, rotated to start at its smallest corner for meshopt.
  auto corners_of = [draco](std::span<const float, 9> c) {
    std::array<std::array<float, 3>, 3> t{{{c[0], c[1], c[2]}, {c[3], c[4], c[5]}, {c[6], c[7], c[8]}}};
    if (!draco) std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
    return t;
  };
  ServerConnection c = connect();
  clients::DeltaMesh kept;
  auto first = c.call(request, 1);
  ASSERT_TRUE(first.ok()) << first.error().message;
  ASSERT_NE(as_mesh(*first), nullptr) << first->json;
  ASSERT_TRUE(as_mesh(*first)->delta && as_mesh(*first)->delta->reset) << first->json;
  ASSERT_TRUE(kept.apply(*as_mesh(*first), first->payload).ok());
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> anywhere(0.15, 0.85), step(-0.02, 0.02);
  double x = 0.3, y = 0.4;
  std::size_t partial = 0;
  bool decoder_checked = false;
  std::size_t repeats = 0;
  for (std::uint64_t id = 2; id < 16; ++id) {
    if (id % 5 == 0) {
      // The same point again: nothing to add or drop.
    } else if (id % 4 == 0) {
      x = anywhere(rng), y = anywhere(rng);
    } else {
      x = std::clamp(x + step(rng), 0.0, 1.0), y = std::clamp(y + step(rng), 0.0, 1.0);
    }
    auto reply = c.call(protocol::Gaze{x, y, std::nullopt, std::nullopt}, id);
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    const auto* mesh = as_mesh(*reply);
    ASSERT_NE(mesh, nullptr) << reply->json;
    ASSERT_TRUE(mesh->delta && !mesh->delta->reset) << reply->json;
    ASSERT_TRUE(kept.apply(*mesh, reply->payload).ok()) << "gaze " << id;
    partial += mesh->delta->added < mesh->triangles;
    if (id % 5 == 0) {
      EXPECT_EQ(mesh->delta->added, 0u) << "gaze " << id;
      EXPECT_EQ(mesh->delta->removed, 0u) << "gaze " << id;
      ++repeats;
    }
    if (draco && !decoder_checked && mesh->delta->added > 0) {
      // The Draco part of a delta is a Draco mesh of its own, for Google's decoder too.
      auto parts = protocol::split_delta_payload(*mesh->delta, reply->payload);
      ASSERT_TRUE(parts.ok());
      auto loaded = test::googles_draco_decode(parts->mesh, g_fixture->dir, "delta");
      ASSERT_TRUE(loaded.ok()) << loaded.error().message;
      EXPECT_EQ(loaded->triangle_count(), mesh->delta->added);
      decoder_checked = true;
    }

    protocol::Extract fresh = request;
    protocol::gaze_region(fresh.criteria).points[0] = {x, y};
    ServerConnection other = connect();
    auto whole = other.call(fresh, 1);
    ASSERT_TRUE(whole.ok()) << whole.error().message;
    ASSERT_NE(as_mesh(*whole), nullptr) << whole->json;
    clients::DeltaMesh reference;
    ASSERT_TRUE(reference.apply(*as_mesh(*whole), whole->payload).ok());
    ASSERT_EQ(kept.triangle_count(), reference.triangle_count()) << "gaze " << id;
    std::map<std::uint32_t, std::size_t> slot;
    for (std::size_t i = 0; i < reference.ids().size(); ++i) slot[reference.ids()[i]] = i;
    for (std::size_t i = 0; i < kept.ids().size(); ++i) {
      const auto it = slot.find(kept.ids()[i]);
      ASSERT_NE(it, slot.end()) << "gaze " << id << ": triangle " << kept.ids()[i] << " is not in the cut";
      // Delta payloads share the model's quantization grid: the same floats, not just close ones.
      ASSERT_EQ(corners_of(kept.corners(i)), corners_of(reference.corners(it->second)));
    }
  }
  EXPECT_GT(partial, 0u);  // most gazes sent less than the whole cut
  EXPECT_EQ(repeats, 3u);
  EXPECT_EQ(decoder_checked, draco);
}

TEST_F(ServerTest, DeltaRepliesRebuildTheCutAFreshConnectionGets) {
  expect_deltas_rebuild_the_cut(core::codec::Codec::kDraco);
}
TEST_F(ServerTest, MeshoptDeltaRepliesRebuildTheCutAFreshConnectionGets) {
  expect_deltas_rebuild_the_cut(core::codec::Codec::kMeshopt);
}

TEST_F(ServerTest, ThirtyTwoConcurrentClientsMixingExtractAndGaze) {
  constexpr int kClients = 32, kRounds = 4;
  std::atomic<int> meshes{0}, failures{0};
  std::vector<std::thread> threads;
  for (int client = 0; client < kClients; ++client) {
    threads.emplace_back([&, client] {
      auto c = ServerConnection::open("127.0.0.1", g_fixture->server->port());
      if (!c.ok()) return void(++failures);
      std::uint64_t id = 1;
      for (int round = 0; round < kRounds; ++round) {
        const bool gaze = round > 0 && (client + round) % 2 == 0;
        const protocol::Request request = gaze ? protocol::Request(protocol::Gaze{0.1 * round, 0.5, {}, {}})
                                               : protocol::Request(extract_request(0.02 * client, 0.5));
        auto reply = c->call(request, id++, std::chrono::seconds(120));
        if (!reply.ok() || !as_mesh(*reply) || as_mesh(*reply)->bytes != reply->payload.size()) {
          ++failures;
          continue;
        }
        if (core::codec::decode_draco(reply->payload).ok()) ++meshes;
      }
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(meshes.load(), kClients * kRounds);
}

TEST_F(ServerTest, EveryDocumentedMalformedRequestGetsItsCodeWhileOthersAreServed) {
  const auto cases = test::malformed_cases();
  ASSERT_GE(cases.size(), 15u);
  ServerConnection bad = connect();
  ServerConnection good = connect();
  std::uint64_t good_id = 100;
  for (const auto& c : cases) {
    std::vector<std::uint8_t> frame;
    protocol::append_frame(c.json, {}, frame);
    ASSERT_TRUE(bad.send_raw(frame).ok());
    auto reply = bad.receive(std::chrono::seconds(30));
    ASSERT_TRUE(reply.ok()) << c.json << ": " << reply.error().message;
    const auto* error = as_error(*reply);
    ASSERT_NE(error, nullptr) << c.json << " -> " << reply->json;
    EXPECT_EQ(protocol::to_string(error->code), c.code) << c.json << " -> " << error->message;
    EXPECT_NE(error->message.find(c.message_contains), std::string::npos)
        << c.json << " -> " << error->message;
    // Everyone else is still served.
    auto pong = good.call(protocol::Ping{}, good_id++);
    ASSERT_TRUE(pong.ok()) << pong.error().message;
    EXPECT_TRUE(std::holds_alternative<protocol::Pong>(pong->header.reply));
  }
  // And the connection that sent them all still works.
  auto last = bad.call(extract_request(), 999);
  ASSERT_TRUE(last.ok()) << last.error().message;
  EXPECT_NE(as_mesh(*last), nullptr) << last->json;
}

TEST_F(ServerTest, GazeBurstIsCoalescedAndTheLastReplyReflectsTheLastGaze) {
  ServerConnection c = connect();
  auto first = c.call(extract_request(), 1);
  ASSERT_TRUE(first.ok() && as_mesh(*first));
  constexpr int kGazes = 200;
  for (int i = 0; i < kGazes; ++i) {
    ASSERT_TRUE(c.send(protocol::Gaze{(i % 100) / 100.0, 0.25 + 0.5 * (i % 2), {}, {}}, 1000 + i).ok());
  }
  int meshes = 0, superseded = 0;
  std::uint64_t superseded_reported = 0;
  const protocol::MeshReply* last_mesh = nullptr;
  std::vector<ReplyFrame> replies;
  for (int i = 0; i < kGazes; ++i) {
    auto reply = c.receive(std::chrono::seconds(120));
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    EXPECT_EQ(reply->header.id, 1000u + i) << "replies must come in request order";
    replies.push_back(std::move(*reply));
  }
  for (const ReplyFrame& r : replies) {
    if (const auto* m = as_mesh(r)) {
      ++meshes;
      superseded_reported += m->superseded;
      last_mesh = m;
    } else {
      const auto* e = as_error(r);
      ASSERT_NE(e, nullptr) << r.json;
      EXPECT_EQ(e->code, protocol::ErrorKind::kSuperseded) << e->message;
      ++superseded;
    }
  }
  EXPECT_EQ(meshes + superseded, kGazes);
  EXPECT_LT(meshes, kGazes / 4) << "gaze updates were queued up instead of coalesced";
  EXPECT_EQ(superseded_reported, static_cast<std::uint64_t>(superseded));
  ASSERT_NE(as_mesh(replies.back()), nullptr) << "the newest gaze must be served";
  ASSERT_TRUE(last_mesh->focus.has_value());
  EXPECT_DOUBLE_EQ((*last_mesh->focus)[0], ((kGazes - 1) % 100) / 100.0);
  EXPECT_DOUBLE_EQ((*last_mesh->focus)[1], 0.25 + 0.5 * ((kGazes - 1) % 2));
}

TEST_F(ServerTest, OversizedFrameClosesOnlyThatConnection) {
  ServerConnection bad = connect();
  ServerConnection good = connect();
  const auto header = protocol::encode_frame_header({1u << 30, 0});
  ASSERT_TRUE(bad.send_raw({header.begin(), header.end()}).ok());
  auto reply = bad.receive(std::chrono::seconds(10));
  ASSERT_TRUE(reply.ok()) << reply.error().message;
  ASSERT_NE(as_error(*reply), nullptr);
  EXPECT_EQ(as_error(*reply)->code, protocol::ErrorKind::kBadFrame);
  EXPECT_FALSE(bad.receive(std::chrono::seconds(10)).ok()) << "the connection should be closed";
  auto pong = good.call(protocol::Ping{}, 5);
  ASSERT_TRUE(pong.ok()) << pong.error().message;
}

// A connection that ends on a bad frame while its client is still sending loses none of the
// replies before it. Closed with input unread, a socket sends a reset, and the reset discards what
// the client has not yet received: here most of a mesh, since this client keeps its receive
// buffer small and reads only once the server is done.
TEST_F(ServerTest, ABadFrameAfterAnExtractLosesNoneOfTheMeshBeforeIt) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  const int small = 4096;
  ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(g_fixture->server->port());
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address), 0);
  protocol::Extract whole = extract_request();
  whole.error = 0;  // the whole model: far more than the client's receive buffer
  std::vector<std::uint8_t> out;
  protocol::append_frame(protocol::to_json(protocol::Request{whole}, 1), {}, out);
  const auto bad = protocol::encode_frame_header({0, 0});  // an empty JSON part
  out.insert(out.end(), bad.begin(), bad.end());
  out.resize(out.size() + 32768, 'x');  // what the client sends on: never read
  ASSERT_EQ(::send(fd, out.data(), out.size(), MSG_NOSIGNAL), static_cast<ssize_t>(out.size()));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the server answers and ends

  std::vector<std::uint8_t> in;
  for (;;) {
    pollfd p{fd, POLLIN, 0};
    ASSERT_EQ(::poll(&p, 1, 10000), 1) << "the server neither sent nor closed";
    std::array<std::uint8_t, 65536> buffer;
    const ssize_t n = ::recv(fd, buffer.data(), buffer.size(), 0);
    ASSERT_GE(n, 0) << "the connection was reset after " << in.size() << " bytes";
    if (n == 0) break;
    in.insert(in.end(), buffer.begin(), buffer.begin() + n);
  }
  ::close(fd);
  std::vector<protocol::ParsedReply> replies;
  std::span<const std::uint8_t> rest(in);
  while (rest.size() >= protocol::kFrameHeaderBytes) {
    const auto header = protocol::decode_frame_header(rest.first<protocol::kFrameHeaderBytes>(), 1u << 30);
    ASSERT_TRUE(header.ok());
    ASSERT_GE(rest.size(), protocol::kFrameHeaderBytes + header->body_bytes()) << "a reply cut short";
    const std::string_view json(reinterpret_cast<const char*>(rest.data()) + protocol::kFrameHeaderBytes,
                                header->json_bytes);
    auto reply = protocol::parse_reply(json);
    ASSERT_TRUE(reply.ok()) << json;
    if (const auto* mesh = std::get_if<protocol::MeshReply>(&reply->reply)) {
      // The whole payload arrived: it decodes to the cut the reply announces.
      const auto payload =
          rest.subspan(protocol::kFrameHeaderBytes + header->json_bytes, header->payload_bytes);
      const auto decoded = core::codec::decode_payload(mesh->codec, payload);
      ASSERT_TRUE(decoded.ok()) << decoded.error().message;
      EXPECT_EQ(decoded->triangle_count(), mesh->triangles);
      EXPECT_GT(payload.size(), 2u * static_cast<std::size_t>(small))
          << "larger than the receive buffer (the kernel doubles what SO_RCVBUF asks)";
    }
    replies.push_back(std::move(*reply));
    rest = rest.subspan(protocol::kFrameHeaderBytes + header->body_bytes());
  }
  EXPECT_TRUE(rest.empty());
  ASSERT_EQ(replies.size(), 2u);
  EXPECT_NE(std::get_if<protocol::MeshReply>(&replies[0].reply), nullptr);
  const auto* error = std::get_if<protocol::ErrorReply>(&replies[1].reply);
  ASSERT_NE(error, nullptr);
  EXPECT_EQ(error->code, protocol::ErrorKind::kBadFrame);
}

TEST_F(ServerTest, AbruptDisconnectsMidFrameAndMidRequestLoseNothingForOthers) {
  ServerConnection good = connect();
  for (int i = 0; i < 10; ++i) {
    ServerConnection gone = connect();
    std::vector<std::uint8_t> frame;
    protocol::append_frame(protocol::to_json(protocol::Request(extract_request()), 1), {}, frame);
    if (i % 2 == 0) frame.resize(frame.size() / 2);  // half a frame, then gone
    ASSERT_TRUE(gone.send_raw(frame).ok());
    gone.close();
  }
  auto reply = good.call(extract_request(), 2);
  ASSERT_TRUE(reply.ok()) << reply.error().message;
  EXPECT_NE(as_mesh(*reply), nullptr);
  auto stats = good.call(protocol::Stats{}, 3);
  ASSERT_TRUE(stats.ok());
  double open = -1;
  for (const auto& [name, value] : std::get<protocol::StatsReply>(stats->header.reply).counters) {
    if (name == "connections_open") open = value;
  }
  EXPECT_GE(open, 1);
}

TEST_F(ServerTest, CancelAnswersTheCancelledRequestOrSaysItHadStarted) {
  ServerConnection c = connect();
  for (std::uint64_t id = 1; id <= 4; ++id) ASSERT_TRUE(c.send(extract_request(0.1 * id, 0.5), id).ok());
  ASSERT_TRUE(c.send(protocol::Cancel{4}, 5).ok());
  std::vector<ReplyFrame> replies;
  for (int i = 0; i < 5; ++i) {
    auto r = c.receive(std::chrono::seconds(60));
    ASSERT_TRUE(r.ok()) << r.error().message;
    replies.push_back(std::move(*r));
  }
  const auto& cancel = std::get<protocol::CancelReply>(replies[4].header.reply);
  EXPECT_EQ(cancel.target, 4u);
  if (cancel.cancelled) {
    ASSERT_NE(as_error(replies[3]), nullptr);
    EXPECT_EQ(as_error(replies[3])->code, protocol::ErrorKind::kCancelled);
  } else {
    EXPECT_NE(as_mesh(replies[3]), nullptr);
  }
}

TEST(ServerShutdown, SigtermFinishesInFlightWorkThenExits) {
  const auto dir = test::scratch_dir("server-drain");
  core::eval::GenerateOptions o;
  o.target_triangles = 60'000;
  auto mt = core::build::build_mt(core::eval::generate_mesh(o));
  ASSERT_TRUE(mt.ok());
  ASSERT_TRUE(core::io::write_mt_file(dir / "sphere.mt", *mt).ok());
  test::ServerProcess server({(dir / "sphere.mt").string(), "--workers", "1", "--log-level", "info"}, dir);
  ASSERT_TRUE(server.running()) << server.log();
  auto c = ServerConnection::open("127.0.0.1", server.port());
  ASSERT_TRUE(c.ok());
  protocol::Extract e;
  e.model = "sphere";
  protocol::look_at_camera(protocol::LookAt{}, 1.0, e.view, e.projection);
  e.error = 0;  // full resolution: long enough to still be running at the signal
  for (std::uint64_t id = 1; id <= 3; ++id) ASSERT_TRUE(c->send(e, id).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::thread stopper([&] { server.stop(SIGTERM); });
  int meshes = 0, shutting_down = 0;
  for (int i = 0; i < 3; ++i) {
    auto r = c->receive(std::chrono::seconds(60));
    ASSERT_TRUE(r.ok()) << r.error().message;
    if (as_mesh(*r)) {
      ++meshes;
      EXPECT_TRUE(core::codec::decode_draco(r->payload).ok());
    } else {
      ASSERT_NE(as_error(*r), nullptr);
      EXPECT_EQ(as_error(*r)->code, protocol::ErrorKind::kShuttingDown);
      ++shutting_down;
    }
  }
  stopper.join();
  EXPECT_GE(meshes, 1) << "the running extraction must finish";
  EXPECT_EQ(meshes + shutting_down, 3);
  EXPECT_NE(server.log().find("stopped"), std::string::npos) << server.log();
  EXPECT_FALSE(ServerConnection::open("127.0.0.1", server.port(), std::chrono::milliseconds(500)).ok())
      << "a stopped server accepts no connection";
}

}  // namespace
}  // namespace mtlod

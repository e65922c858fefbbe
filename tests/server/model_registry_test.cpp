// ModelRegistry (server/model_registry.hpp): what it does with cached .mt files a mesh was built
// into — reused when current, built again when an older mtlod-build numbered the vertices
// otherwise or when the file cannot be read — that such older files still load on their own, and
// that a directory's bad file does not keep its good ones from being served.
#include "server/model_registry.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <numeric>
#include <random>

#include "core/build/mt_builder.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod {
namespace {

namespace fs = std::filesystem;

// The same MT with its vertices numbered by a random permutation: valid, not in node order.
core::model::Mt shuffled_vertices(const core::model::Mt& built, std::uint32_t seed) {
  core::model::MtArrays mt = built.arrays();
  std::vector<std::uint32_t> to(built.vertex_count());
  std::iota(to.begin(), to.end(), 0u);
  std::shuffle(to.begin(), to.end(), std::mt19937(seed));
  std::vector<float> positions(mt.positions.size());
  for (std::size_t v = 0; v < to.size(); ++v)
    std::copy_n(&mt.positions[3 * v], 3, &positions[3 * std::size_t{to[v]}]);
  mt.positions = std::move(positions);
  for (std::uint32_t& v : mt.node_vertex)
    if (v != core::model::kNoVertex) v = to[v];
  for (std::uint32_t& v : mt.triangle_corners) v = to[v];
  for (std::uint32_t& v : mt.root_first_corner) v = to[v];
  return core::model::Mt(std::move(mt));
}

class ModelRegistryTest : public testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::scratch_dir("registry");
    mesh_path_ = dir_ / "shell.ply";
    mt_path_ = dir_ / "shell.mt";
    core::eval::GenerateOptions o;
    o.shape = core::eval::Shape::kShell;
    o.target_triangles = 3000;
    const core::model::Mesh mesh = core::eval::generate_mesh(o);
    ASSERT_TRUE(core::io::save_mesh(mesh_path_, mesh).ok());
    auto mt = core::build::build_mt(mesh);
    ASSERT_TRUE(mt.ok());
    built_ = std::move(*mt);
    ASSERT_TRUE(built_.vertices_in_node_order());
  }
  // Writes mt as the mesh's cached file, newer than the mesh.
  void write_cache(const core::model::Mt& mt) {
    ASSERT_TRUE(core::io::write_mt_file(mt_path_, mt).ok());
    fs::last_write_time(mt_path_, fs::last_write_time(mesh_path_) + std::chrono::seconds(5));
  }

  fs::path dir_, mesh_path_, mt_path_;
  core::model::Mt built_;
};

TEST_F(ModelRegistryTest, CurrentCacheIsReusedAsItIs) {
  write_cache(built_);
  const auto written = fs::last_write_time(mt_path_);
  server::ModelRegistry registry;
  ASSERT_TRUE(registry.add_mesh(mesh_path_, mt_path_).ok());
  EXPECT_EQ(fs::last_write_time(mt_path_), written);
  ASSERT_NE(registry.find("shell"), nullptr);
  EXPECT_TRUE(std::ranges::equal(registry.find("shell")->mt.node_vertex, built_.node_vertex));
}

TEST_F(ModelRegistryTest, CacheFromAnOlderBuilderIsBuiltAgain) {
  const core::model::Mt older = shuffled_vertices(built_, 7);
  ASSERT_FALSE(older.vertices_in_node_order());
  write_cache(older);
  server::ModelRegistry registry;
  ASSERT_TRUE(registry.add_mesh(mesh_path_, mt_path_).ok());
  const server::ModelPtr model = registry.find("shell");
  ASSERT_NE(model, nullptr);
  EXPECT_TRUE(model->mt.vertices_in_node_order());
  EXPECT_TRUE(std::ranges::equal(model->mt.node_vertex, built_.node_vertex));
  auto rewritten = core::io::read_mt_file(mt_path_);
  ASSERT_TRUE(rewritten.ok());
  EXPECT_TRUE(rewritten->vertices_in_node_order());
}

TEST_F(ModelRegistryTest, UnreadableCacheIsBuiltAgain) {
  write_cache(built_);
  std::fstream(mt_path_, std::ios::in | std::ios::out | std::ios::binary).seekp(100).put('\x5a');
  fs::last_write_time(mt_path_, fs::last_write_time(mesh_path_) + std::chrono::seconds(5));
  ASSERT_FALSE(core::io::read_mt_file(mt_path_).ok());  // the checksum sees the byte
  server::ModelRegistry registry;
  ASSERT_TRUE(registry.add_mesh(mesh_path_, mt_path_).ok());
  ASSERT_NE(registry.find("shell"), nullptr);
  EXPECT_TRUE(core::io::read_mt_file(mt_path_).ok());
}

TEST_F(ModelRegistryTest, OlderFileGivenByItselfIsServedAsItIs) {
  const core::model::Mt older = shuffled_vertices(built_, 11);
  const fs::path path = dir_ / "older.mt";
  ASSERT_TRUE(core::io::write_mt_file(path, older).ok());
  server::ModelRegistry registry;
  ASSERT_TRUE(registry.add_file(path).ok());
  ASSERT_NE(registry.find("older"), nullptr);
  EXPECT_TRUE(std::ranges::equal(registry.find("older")->mt.node_vertex, older.node_vertex));
}

TEST_F(ModelRegistryTest, ADirectoryServesItsGoodFilesWhileOthersDoNotLoad) {
  // A replica restarted while an operator replaces one model still serves the others, and the
  // replaced one once its file is whole.
  const fs::path models = dir_ / "models";
  fs::create_directories(models / "folder.mt");  // a directory named like a model
  ASSERT_TRUE(core::io::write_mt_file(models / "good.mt", built_).ok());
  test::write_file(models / "damaged.mt", std::string(200, 'x'));
  server::ModelRegistry registry;
  ASSERT_TRUE(registry.add_directory(models).ok());
  EXPECT_NE(registry.find("good"), nullptr);
  EXPECT_EQ(registry.find("damaged"), nullptr);
  EXPECT_EQ(registry.find("folder"), nullptr);
  EXPECT_EQ(registry.models().size(), 1u);

  ASSERT_TRUE(core::io::write_mt_file(models / "damaged.mt", built_).ok());
  const auto outcomes = registry.reload();
  const auto damaged = std::find_if(outcomes.begin(), outcomes.end(),
                                    [](const protocol::ModelReload& o) { return o.name == "damaged"; });
  ASSERT_NE(damaged, outcomes.end());
  EXPECT_EQ(damaged->change, "loaded") << damaged->message;
  EXPECT_NE(registry.find("damaged"), nullptr);
}

}  // namespace
}  // namespace mtlod

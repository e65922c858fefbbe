// The out-of-core build (core/build/large_build.hpp): with one block it is build_mt byte for byte; with
// many blocks, side by side or in turn, it gives the same valid MT every time. The MT properties of
// its results (conformity, error bound, dynamic = static) are checked with build_mt's in
// mt_builder_test.cpp and refine_test.cpp through test::large_case.
#include "core/build/large_build.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "core/build/mt_builder.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mesh_io.hpp"
#include "core/io/mt_file.hpp"
#include "core/model/mt_format.hpp"
#include "core/threads/thread_pool.hpp"
#include "tests/core/mt_fixtures.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod {
namespace {

using core::build::LargeBuildOptions;
using core::build::LargeBuildStats;
using core::model::Mesh;

std::vector<std::uint8_t> file_bytes(const std::filesystem::path& path) {
  const std::string bytes = test::read_file(path);
  return {bytes.begin(), bytes.end()};
}

// The file build_mt_file writes for mesh (saved as PLY first) with these options.
std::vector<std::uint8_t> large_build_bytes(const Mesh& mesh, LargeBuildOptions options,
                                            LargeBuildStats* stats = nullptr) {
  const auto dir = test::scratch_dir("large-build");
  EXPECT_TRUE(core::io::save_mesh(dir / "in.ply", mesh).ok());
  const auto built = core::build::build_mt_file(dir / "in.ply", dir / "out.mt", options, stats);
  EXPECT_TRUE(built.ok()) << (built.ok() ? "" : built.error().message);
  return file_bytes(dir / "out.mt");
}

std::vector<Mesh> clean_inputs() {
  std::vector<Mesh> meshes = {
      core::eval::generate_mesh({.shape = core::eval::Shape::kSphere, .target_triangles = 20'000}),
      core::eval::generate_mesh({.shape = core::eval::Shape::kTerrain, .target_triangles = 5'000}),
      core::eval::generate_mesh({.shape = core::eval::Shape::kShell, .target_triangles = 8'000})};
  const auto path = test::shared_meshes_dir() / "dragon-vrip-res4-11k.ply";  // non-manifold
  if (std::filesystem::exists(path)) {
    auto loaded = core::io::load_mesh(path);
    EXPECT_TRUE(loaded.ok());
    if (loaded.ok()) meshes.push_back(std::move(loaded->mesh));
  }
  return meshes;
}

TEST(LargeBuild, OneBlockWritesBuildMtsFileByteForByte) {
  for (const Mesh& mesh : clean_inputs()) {
    auto mt = core::build::build_mt(mesh);
    ASSERT_TRUE(mt.ok());
    std::vector<std::uint8_t> expected;
    core::model::serialize_mt(*mt, expected);
    LargeBuildOptions options;
    options.block_triangles = mesh.triangle_count();
    LargeBuildStats stats;
    EXPECT_EQ(large_build_bytes(mesh, options, &stats), expected) << mesh.triangle_count() << " triangles";
    EXPECT_EQ(stats.blocks, 1u);
    EXPECT_EQ(stats.nodes, mt->node_count());
    // The same with the stage's passes on two threads.
    core::threads::ThreadPool pool(2);
    pool.attach(options.build);
    options.threads = 2;
    EXPECT_EQ(large_build_bytes(mesh, options), expected) << mesh.triangle_count() << " triangles, 2 threads";
  }
}

// Raw scans with their defects: the streaming path cleans as load_mesh does, so one block gives the
// file of build_mt on the loaded mesh.
TEST(LargeBuild, OneBlockOfARawScanIsTheBuildOfTheCleanedScan) {
  int meshes = 0;
  for (const char* file : {"dragon-vrip-res2-203k.ply", "bunny-zipper-69k.ply"}) {
    const auto path = test::shared_meshes_dir() / file;
    if (!std::filesystem::exists(path)) continue;
    ++meshes;
    auto loaded = core::io::load_mesh(path);
    ASSERT_TRUE(loaded.ok());
    auto mt = core::build::build_mt(loaded->mesh);
    ASSERT_TRUE(mt.ok());
    std::vector<std::uint8_t> expected;
    core::model::serialize_mt(*mt, expected);
    const auto dir = test::scratch_dir("large-build-raw");
    LargeBuildOptions options;
    options.block_triangles = std::size_t{1} << 20;
    LargeBuildStats stats;
    ASSERT_TRUE(core::build::build_mt_file(path, dir / "out.mt", options, &stats).ok());
    EXPECT_EQ(file_bytes(dir / "out.mt"), expected) << file;
    EXPECT_EQ(stats.dropped_degenerate, loaded->cleanup.dropped_degenerate_triangles) << file;
    EXPECT_EQ(stats.dropped_duplicate, loaded->cleanup.dropped_duplicate_triangles) << file;
  }
  if (meshes == 0) GTEST_SKIP() << "no shared meshes";
}

TEST(LargeBuild, ManyBlocksGiveTheSameFileInTurnAndSideBySide) {
  const Mesh mesh =
      core::eval::generate_mesh({.shape = core::eval::Shape::kShell, .target_triangles = 30'000});
  LargeBuildOptions options;
  options.block_triangles = 2'000;
  LargeBuildStats stats;
  const auto serial = large_build_bytes(mesh, options, &stats);
  EXPECT_GE(stats.blocks, 15u);
  EXPECT_GE(stats.levels, 5u);
  EXPECT_EQ(stats.stages, 2 * stats.blocks - 1);  // a binary tree over the leaves
  auto mt = core::model::deserialize_mt(serial);  // validates the DAG, the indices and the checksum
  ASSERT_TRUE(mt.ok()) << mt.error().message;
  EXPECT_EQ(mt->vertex_count(), mesh.vertex_count());
  EXPECT_EQ(stats.mt_triangles, mt->triangle_count());
  // Every input triangle is in the MT, created by some node and removed by none.
  EXPECT_EQ(std::count(mt->triangle_remover.begin(), mt->triangle_remover.end(), core::model::kNoNode),
            std::ptrdiff_t(mesh.triangle_count()));
  EXPECT_LT(mt->root_triangle_count(), mesh.triangle_count() / 4);

  core::threads::ThreadPool pool(2);
  pool.attach(options.build);
  options.threads = 2;
  EXPECT_EQ(large_build_bytes(mesh, options), serial);
}

TEST(LargeBuild, DropsDegenerateAndDuplicateTrianglesAndCountsThem) {
  Mesh mesh = core::eval::generate_mesh({.shape = core::eval::Shape::kSphere, .target_triangles = 3'000});
  const std::size_t faces = mesh.triangle_count();
  mesh.triangles.insert(mesh.triangles.end(), {0, 0, 1});  // repeated id
  mesh.triangles.insert(mesh.triangles.end(),
                        {mesh.triangles[4], mesh.triangles[5], mesh.triangles[3]});  // duplicate
  LargeBuildOptions options;
  options.block_triangles = 500;
  LargeBuildStats stats;
  auto mt = core::model::deserialize_mt(large_build_bytes(mesh, options, &stats));
  ASSERT_TRUE(mt.ok()) << mt.error().message;
  EXPECT_EQ(stats.input_triangles, faces + 2);
  EXPECT_EQ(stats.dropped_degenerate, 1u);
  EXPECT_EQ(stats.dropped_duplicate, 1u);
  EXPECT_EQ(std::count(mt->triangle_remover.begin(), mt->triangle_remover.end(), core::model::kNoNode),
            std::ptrdiff_t(faces));
}

TEST(LargeBuild, DerivesItsBlocksFromTheMemoryLimitAndRefusesOneTooSmall) {
  const Mesh mesh =
      core::eval::generate_mesh({.shape = core::eval::Shape::kSphere, .target_triangles = 20'000});
  LargeBuildOptions options;
  options.memory_limit = std::uint64_t{132} << 20;  // a few MiB over the fixed part
  LargeBuildStats stats;
  auto mt = core::model::deserialize_mt(large_build_bytes(mesh, options, &stats));
  ASSERT_TRUE(mt.ok()) << mt.error().message;
  EXPECT_GT(stats.blocks, 1u);
  EXPECT_LT(stats.block_triangles, mesh.triangle_count());

  const auto dir = test::scratch_dir("large-build-limit");
  ASSERT_TRUE(core::io::save_mesh(dir / "in.ply", mesh).ok());
  options.memory_limit = std::uint64_t{1} << 20;
  const auto refused = core::build::build_mt_file(dir / "in.ply", dir / "out.mt", options);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().code, ErrorCode::kLimitExceeded);
  EXPECT_NE(refused.error().message.find("too small"), std::string::npos) << refused.error().message;
  EXPECT_FALSE(std::filesystem::exists(dir / "out.mt"));
}

TEST(LargeBuild, BadInputsAreClearErrorsAndLeaveNoFiles) {
  const auto dir = test::scratch_dir("large-build-bad");
  const Mesh mesh =
      core::eval::generate_mesh({.shape = core::eval::Shape::kSphere, .target_triangles = 2'000});
  ASSERT_TRUE(core::io::save_mesh(dir / "in.ply", mesh).ok());
  const auto whole = file_bytes(dir / "in.ply");
  {
    std::ofstream out(dir / "cut.ply", std::ios::binary);
    out.write(reinterpret_cast<const char*>(whole.data()), std::streamsize(whole.size() - 100));
  }
  const auto missing = core::build::build_mt_file(dir / "none.ply", dir / "out.mt", {});
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.error().message.find("none.ply"), std::string::npos) << missing.error().message;
  const auto truncated = core::build::build_mt_file(dir / "cut.ply", dir / "out.mt", {});
  ASSERT_FALSE(truncated.ok());
  EXPECT_EQ(truncated.error().code, ErrorCode::kCorrupt) << truncated.error().message;
  // Neither the output nor a temporary directory is left behind.
  std::vector<std::string> left;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) left.push_back(entry.path().filename());
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{"cut.ply", "in.ply"}));
}

}  // namespace
}  // namespace mtlod

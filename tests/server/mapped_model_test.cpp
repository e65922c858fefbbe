// A server on mapped .mt files (core/model/FORMAT.md, version 2): a file damaged in a block that only fine
// cuts reach is served; the requests that reach the block get an error naming it, every other
// request is answered, and the process runs on. A file damaged in the root's block is refused at
// start with the file and the block named.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "clients/common/server_connection.hpp"
#include "core/build/mt_builder.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mt_file.hpp"
#include "core/model/mt_format.hpp"
#include "core/threads/thread_pool.hpp"
#include "tests/core/test_meshes.hpp"
#include "tests/server/server_process.hpp"
#include "tests/server/test_requests.hpp"

namespace mtlod {
namespace {

namespace fs = std::filesystem;

// A shell large enough that the coarse cuts a server reads at start (up to 256k triangles) leave
// its last node blocks untouched; its file, and where a byte of its last block lies.
struct Damaged {
  std::string bytes;
  std::size_t last_block_byte = 0;
  std::uint32_t last_block = 0;
};

Damaged build_shell(std::size_t triangles) {
  core::eval::GenerateOptions options;
  options.shape = core::eval::Shape::kShell;
  options.target_triangles = triangles;
  core::threads::ThreadPool pool;
  core::build::BuildOptions build;
  pool.attach(build);
  auto mt = core::build::build_mt(core::eval::generate_mesh(options), build);
  EXPECT_TRUE(mt.ok());
  Damaged d;
  const auto path = test::scratch_dir("mapped-model") / "built.mt";
  EXPECT_TRUE(core::io::write_mt_file(path, *mt).ok());
  d.bytes = test::read_file(path);
  const core::model::MtCounts counts = core::model::mt_counts(*mt);
  d.last_block = core::model::mt_block_count(counts.nodes) - 1;
  const std::uint32_t first =
      mt->node_triangle_offsets[std::size_t{d.last_block} << core::model::kMtBlockShift];
  d.last_block_byte = core::model::mt_layout(counts).triangle_remover + 4 * std::size_t{first};
  return d;
}

const Damaged& shell() {
  static const Damaged d = build_shell(700000);
  return d;
}

fs::path models_with(const Damaged& model, const std::string& name, std::size_t damaged_byte) {
  const fs::path dir = test::scratch_dir("mapped-model-" + name);
  const fs::path models = dir / "models";
  fs::create_directories(models);
  std::string bytes = model.bytes;
  bytes[damaged_byte] ^= 0x40;
  test::write_file(models / (name + ".mt"), bytes);
  return dir;
}

TEST(MappedModel, ADamagedBlockFailsOnlyTheRequestsThatReachIt) {
  const fs::path dir = models_with(shell(), "shell", shell().last_block_byte);
  test::ServerProcess server({"--models", (dir / "models").string()}, dir);
  ASSERT_TRUE(server.running()) << server.log();
  auto c = clients::ServerConnection::open("127.0.0.1", server.port());
  ASSERT_TRUE(c.ok()) << c.error().message;
  auto info = c->call(protocol::ModelInfo{"shell"}, 1);
  ASSERT_TRUE(info.ok()) << info.error().message;
  const auto& model = std::get<protocol::ModelInfoReply>(info->header.reply);

  auto coarse = [&](std::uint64_t id) {
    auto reply = c->call(test::framing_extract("shell", model, {128, 128}, 20.0), id);
    ASSERT_TRUE(reply.ok()) << reply.error().message;
    ASSERT_TRUE(std::holds_alternative<protocol::MeshReply>(reply->header.reply)) << reply->json;
    EXPECT_GT(std::get<protocol::MeshReply>(reply->header.reply).triangles, 0u);
  };
  coarse(2);
  // Every node: the refinement reaches the damaged block.
  protocol::Extract fine = test::framing_extract("shell", model, {128, 128}, 0.0);
  fine.error = 0.0;
  auto reply = c->call(fine, 3);
  ASSERT_TRUE(reply.ok()) << reply.error().message;
  ASSERT_TRUE(std::holds_alternative<protocol::ErrorReply>(reply->header.reply)) << reply->json;
  const auto& error = std::get<protocol::ErrorReply>(reply->header.reply);
  EXPECT_EQ(error.code, protocol::ErrorKind::kInternal);
  EXPECT_NE(error.message.find("damaged"), std::string::npos) << error.message;
  EXPECT_NE(error.message.find("block " + std::to_string(shell().last_block)), std::string::npos)
      << error.message;
  // The same connection, and the process, go on serving what does not reach the block.
  coarse(4);
  EXPECT_TRUE(server.running());
  EXPECT_NE(server.log().find("block " + std::to_string(shell().last_block)), std::string::npos);
}

TEST(MappedModel, ADamagedRootBlockIsRefusedAtStart) {
  // A position of a root vertex: block 0, checked when the file is opened.
  const fs::path dir = models_with(build_shell(3000), "root", core::model::kMtHeaderBytes + 6);
  test::ServerProcess server({"--models", (dir / "models").string()}, dir);
  EXPECT_FALSE(server.running());
  const std::string log = server.log();
  EXPECT_NE(log.find("root.mt"), std::string::npos) << log;
  EXPECT_NE(log.find("block 0"), std::string::npos) << log;
}

}  // namespace
}  // namespace mtlod

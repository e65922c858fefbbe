// The real scans in the shared test meshes folder must all load, and their counts must match the
// table of that folder's README, which is parsed here as the independent expectation. Also checks
// that the built-in bunny converted from npm is the same mesh as the shared copy of it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "core/io/mesh_io.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::core {
namespace {

struct ReadmeRow {
  std::string file;
  std::size_t vertices = 0;
  std::size_t triangles = 0;
  std::string topology;  // the free-text topology column
};

std::size_t parse_count(std::string text) {
  text.erase(std::remove(text.begin(), text.end(), ','), text.end());
  return std::stoull(text);
}

std::vector<ReadmeRow> read_readme_table(const std::filesystem::path& readme) {
  std::ifstream in(readme);
  std::vector<ReadmeRow> rows;
  std::string line;
  // | `file.ply` | model | vertices | triangles | topology | ...
  const std::regex row(R"(^\|\s*`([^`]+\.ply)`\s*\|[^|]*\|\s*([\d,]+)\s*\|\s*([\d,]+)\s*\|([^|]*)\|)");
  while (std::getline(in, line)) {
    std::smatch m;
    if (std::regex_search(line, m, row)) rows.push_back({m[1], parse_count(m[2]), parse_count(m[3]), m[4]});
  }
  return rows;
}

// "223 boundary edges" -> 223; nullopt when the phrase is absent.
std::optional<std::size_t> count_before(const std::string& text, const std::string& phrase) {
  const std::regex re("([\\d,]+) " + phrase);
  std::smatch m;
  if (!std::regex_search(text, m, re)) return std::nullopt;
  return parse_count(m[1]);
}

TEST(RealMeshes, EveryScanLoadsWithTheCountsItsReadmeStates) {
  const auto dir = test::shared_meshes_dir();
  if (!std::filesystem::exists(dir / "README.md")) GTEST_SKIP() << "no shared meshes at " << dir;
  const std::vector<ReadmeRow> rows = read_readme_table(dir / "README.md");
  ASSERT_GE(rows.size(), 8u) << "README table not understood";
  for (const ReadmeRow& row : rows) {
    SCOPED_TRACE(row.file);
    io::LoadOptions options;
    options.clean = false;
    auto loaded = io::load_mesh(dir / row.file, options);
    ASSERT_TRUE(loaded.ok()) << loaded.error().message;
    const model::TopologyReport& t = loaded->input_topology;
    EXPECT_EQ(t.vertices, row.vertices);
    EXPECT_EQ(t.triangles, row.triangles);
    EXPECT_EQ(t.boundary_edges, count_before(row.topology, "boundary edges").value_or(0));
    EXPECT_EQ(t.unused_vertices, count_before(row.topology, "unused vertices").value_or(0));
    EXPECT_EQ(t.non_manifold_edges, count_before(row.topology, "edges with >2 faces").value_or(0));
    EXPECT_EQ(t.duplicate_positions, count_before(row.topology, "duplicate vertex positions").value_or(0));
    if (auto components = count_before(row.topology, "components")) {
      EXPECT_EQ(t.components, *components);
    }
    if (row.topology.find("closed 2-manifold") != std::string::npos) {
      EXPECT_TRUE(t.is_closed_manifold());
      EXPECT_EQ(t.components, 1u);
      EXPECT_EQ(t.euler_characteristic, 2);  // genus 0
    }
    // The README's "edges with clashing orientation" figures are not reproduced: in those files
    // every edge has as many triangles walking it one way as the other (see mesh_cleanup.hpp),
    // so our inconsistent-edge count, defined on two-triangle edges, is 0 there.
    if (row.topology.find("consistent orientation") != std::string::npos) {
      EXPECT_EQ(t.inconsistent_edges, 0u);
    }

    // Clean-up leaves a mesh with no unused vertices, no degenerate and no duplicate triangles.
    model::Mesh cleaned = loaded->mesh;
    model::clean_mesh(cleaned);
    const model::TopologyReport after = model::analyze_topology(cleaned.positions, cleaned.triangles);
    EXPECT_EQ(after.unused_vertices, 0u);
    EXPECT_EQ(after.degenerate_triangles, 0u);
    EXPECT_EQ(after.duplicate_triangles, 0u);
  }
}

TEST(BuiltInModels, NpmBunnyIsTheSharedBunnyExactly) {
  const auto npm_bunny = test::models_dir() / "bunny.ply";
  const auto shared_bunny = test::shared_meshes_dir() / "bunny-npm-3k.ply";
  if (!std::filesystem::exists(npm_bunny)) GTEST_SKIP() << "run scripts/prepare-models.sh first";
  if (!std::filesystem::exists(shared_bunny)) GTEST_SKIP() << "no shared meshes";
  io::LoadOptions options;
  options.clean = false;
  auto a = io::load_mesh(npm_bunny, options);
  auto b = io::load_mesh(shared_bunny, options);
  ASSERT_TRUE(a.ok()) << a.error().message;
  ASSERT_TRUE(b.ok()) << b.error().message;
  ASSERT_EQ(a->mesh.positions.size(), b->mesh.positions.size());
  EXPECT_EQ(std::memcmp(a->mesh.positions.data(), b->mesh.positions.data(), a->mesh.positions.size() * 4), 0);
  EXPECT_EQ(a->mesh.triangles, b->mesh.triangles);
  EXPECT_TRUE(a->input_topology.is_closed_manifold());
}

TEST(BuiltInModels, NpmDragonHasItsPublishedSize) {
  const auto dragon = test::models_dir() / "dragon-871k.ply";
  if (!std::filesystem::exists(dragon)) GTEST_SKIP() << "run scripts/prepare-models.sh first";
  io::LoadOptions options;
  options.clean = false;
  auto loaded = io::load_mesh(dragon, options);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  // dragon_vrip.ply of the Stanford repository: 437,645 vertices, 871,414 triangles.
  EXPECT_EQ(loaded->mesh.vertex_count(), 437'645u);
  EXPECT_EQ(loaded->mesh.triangle_count(), 871'414u);
}

}  // namespace
}  // namespace mtlod::core

// Mapped .mt files (format 2, core/model/FORMAT.md): the same cuts as the file read whole, node blocks
// checked the first time a refinement reaches them, and damaged or truncated files refused at open
// or at first use with an error naming what is wrong, never undefined behaviour (ASan/UBSan).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "core/build/mt_builder.hpp"
#include "core/build/vertex_normals.hpp"
#include "core/cut/refine.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/io/mt_file.hpp"
#include "core/model/mt_format.hpp"
#include "core/view/occupancy_levels.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::core {
namespace {

namespace fs = std::filesystem;

// A model of several node blocks, written once.
struct Model {
  fs::path dir, path;
  model::Mt built;
  std::string bytes;
};

const Model& model() {
  static const Model m = [] {
    Model m;
    eval::GenerateOptions options;
    options.shape = eval::Shape::kShell;
    options.target_triangles = 40000;
    auto built = build::build_mt(eval::generate_mesh(options));
    EXPECT_TRUE(built.ok());
    m.built = std::move(built).value();
    m.dir = test::scratch_dir("mt-map");
    m.path = m.dir / "shell.mt";
    EXPECT_TRUE(io::write_mt_file(m.path, m.built).ok());
    m.bytes = test::read_file(m.path);
    return m;
  }();
  return m;
}

// The model's file with `change` applied to its bytes, written beside it.
fs::path altered(const std::string& name, const std::function<void(std::string&)>& change) {
  std::string bytes = model().bytes;
  change(bytes);
  const fs::path path = model().dir / name;
  test::write_file(path, bytes);
  return path;
}

std::uint32_t block_of(std::uint32_t node) {
  return node >> model::kMtBlockShift;
}

void expect_same_cut(const cut::CutMesh& a, const cut::CutMesh& b, const std::string& what) {
  EXPECT_EQ(a.triangles, b.triangles) << what;
  EXPECT_EQ(a.ids, b.ids) << what;
  EXPECT_EQ(a.node_count, b.node_count) << what;
  EXPECT_EQ(a.max_error, b.max_error) << what;
}

TEST(MtMap, OpensInPlace) {
  const Model& m = model();
  ASSERT_GE(model::mt_block_count(std::uint32_t(m.built.node_count())), 4u)
      << "the test needs several blocks";
  auto mapped = io::read_mt_file(m.path);
  ASSERT_TRUE(mapped.ok()) << mapped.error().message;
  EXPECT_TRUE(mapped->mapped());
  EXPECT_EQ(mapped->memory_bytes(), 0u);
  EXPECT_EQ(mapped->mapped_bytes(), m.built.array_bytes());
  // The summary comes from the header, equal to what the arrays give.
  EXPECT_EQ(mapped->bounds.lo, m.built.bounds.lo);
  EXPECT_EQ(mapped->bounds.hi, m.built.bounds.hi);
  EXPECT_EQ(mapped->input_triangles, m.built.input_triangles);
  auto read = io::read_mt_file(m.path, io::MtLoad::kRead);
  ASSERT_TRUE(read.ok());
  EXPECT_FALSE(read->mapped());
  EXPECT_EQ(read->memory_bytes(), m.built.array_bytes());
}

TEST(MtMap, NormalsComputedForAFileWithoutThemAreCountedInMemory) {
  const Model& m = model();
  model::MtArrays arrays = m.built.arrays();
  const std::vector<float> stored = arrays.normals;
  ASSERT_EQ(stored.size(), arrays.positions.size()) << "every build stores normals";
  arrays.normals.clear();
  const fs::path path = model().dir / "no-normals.mt";
  ASSERT_TRUE(io::write_mt_file(path, model::Mt(std::move(arrays))).ok());
  auto mapped = io::read_mt_file(path);
  ASSERT_TRUE(mapped.ok()) << mapped.error().message;
  ASSERT_TRUE(mapped->mapped());
  const std::size_t mapped_before = mapped->mapped_bytes();
  const Result<bool> computed = build::ensure_normals(*mapped);
  ASSERT_TRUE(computed) << computed.error().message;
  ASSERT_TRUE(*computed);
  EXPECT_EQ(mapped->memory_bytes(), stored.size() * sizeof(float));
  EXPECT_EQ(mapped->mapped_bytes(), mapped_before);
  // From the full-resolution triangles the MT holds: the builder's normals, up to summation order.
  ASSERT_EQ(mapped->normals.size(), stored.size());
  for (std::size_t i = 0; i < stored.size(); ++i) EXPECT_NEAR(mapped->normals[i], stored[i], 1e-5) << i / 3;
}

TEST(MtMap, CutsEqualThoseOfTheFileReadWhole) {
  const Model& m = model();
  auto mapped = io::read_mt_file(m.path);
  auto read = io::read_mt_file(m.path, io::MtLoad::kRead);
  ASSERT_TRUE(mapped.ok() && read.ok());
  cut::Refiner a(*mapped), b(*read);
  cut::CutMesh ca, cb;
  const float top = m.built.node_error[1];
  for (const float fraction : {1.0f, 0.3f, 0.05f, 0.01f, 0.0f}) {
    EXPECT_TRUE(a.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(top * fraction)), ca));
    EXPECT_TRUE(b.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(top * fraction)), cb));
    expect_same_cut(ca, cb, "uniform " + std::to_string(fraction));
  }
  for (const std::size_t budget : {500, 5000, 30000}) {
    EXPECT_TRUE(a.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)).within(budget), ca));
    EXPECT_TRUE(b.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)).within(budget), cb));
    expect_same_cut(ca, cb, "budget " + std::to_string(budget));
  }
  // Per-vertex fields moved by dynamic updates, as a gaze moves them.
  std::mt19937 rng(5);
  std::vector<float> field(m.built.vertex_count());
  for (int step = 0; step < 4; ++step) {
    const float centre = std::uniform_real_distribution<float>(-1, 1)(rng);
    for (std::size_t v = 0; v < field.size(); ++v)
      field[v] = top * 0.02f * (0.05f + std::abs(m.built.positions[3 * v] - centre));
    EXPECT_TRUE(a.refine(cut::Refinement::move(cut::AllowedError::from_vertices(field)), ca));
    EXPECT_TRUE(b.refine(cut::Refinement::move(cut::AllowedError::from_vertices(field)), cb));
    expect_same_cut(ca, cb, "update " + std::to_string(step));
  }
  // The occupancy stage's coarse cuts too.
  auto la = view::OccupancyLevels::make(*mapped), lb = view::OccupancyLevels::make(*read);
  ASSERT_TRUE(la && lb);
  ASSERT_EQ((*la)->levels().size(), (*lb)->levels().size());
  for (std::size_t i = 0; i < (*la)->levels().size(); ++i) {
    EXPECT_EQ((*la)->levels()[i].triangles, (*lb)->levels()[i].triangles);
    EXPECT_EQ((*la)->levels()[i].positions, (*lb)->levels()[i].positions);
  }
}

TEST(MtMap, ADamagedBlockFailsAtFirstUseOnly) {
  const Model& m = model();
  const std::uint32_t last_block = model::mt_block_count(std::uint32_t(m.built.node_count())) - 1;
  // A removed-by entry of a triangle created in the last block, not resealed.
  const model::MtCounts counts = model::mt_counts(m.built);
  const std::uint32_t first_triangle =
      m.built.node_triangle_offsets[std::size_t{last_block} << model::kMtBlockShift];
  const std::uint64_t at = model::mt_layout(counts).triangle_remover + 4 * std::uint64_t{first_triangle};
  const fs::path path = altered("damaged-block.mt", [&](std::string& bytes) { bytes[at] ^= 0x40; });

  auto read = io::read_mt_file(path, io::MtLoad::kRead);
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(read.error().message.find("block " + std::to_string(last_block)), std::string::npos)
      << read.error().message;

  auto mapped = io::read_mt_file(path);
  ASSERT_TRUE(mapped.ok()) << "only the root's block is checked at open: " << mapped.error().message;
  cut::Refiner refiner(*mapped);
  cut::CutMesh cut;
  EXPECT_TRUE(refiner.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(m.built.node_error[1])),
                             cut));  // the root alone
  EXPECT_EQ(cut.node_count, 1u);
  const Status every_node =
      refiner.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)), cut);
  ASSERT_FALSE(every_node) << "the damaged block was used without a complaint";
  EXPECT_EQ(every_node.error().code, ErrorCode::kCorrupt);
  EXPECT_NE(every_node.error().message.find("block " + std::to_string(last_block)), std::string::npos)
      << every_node.error().message;
  // The same MT, and the same refiner, keep serving the cuts that do not reach the block, and keep
  // refusing those that do.
  cut::CutMesh intact;
  EXPECT_TRUE(cut::Refiner(m.built).refine(
      cut::Refinement::from_root(cut::AllowedError::everywhere(m.built.node_error[1] * 0.5f)), intact));
  cut::Refiner fresh(*mapped);
  for (cut::Refiner* r : {&refiner, &fresh}) {
    EXPECT_TRUE(r->refine(
        cut::Refinement::from_root(cut::AllowedError::everywhere(m.built.node_error[1] * 0.5f)), cut));
    EXPECT_GT(cut.node_count, 1u);
    expect_same_cut(cut, intact, "a cut short of the damaged block");
    EXPECT_FALSE(r->refine(cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)), cut));
  }
}

// A budgeted view orders its heap by the errors of the nodes that would refine its mesh (on a large
// model, the removers of the root's triangles lie all over the file); it checks only the blocks of
// the nodes it forces.
TEST(MtMap, ABudgetedViewChecksOnlyTheBlocksItForces) {
  const Model& m = model();
  // A budget whose cut lies in blocks before the block of one of its mesh's removers, `far`. The
  // cut's largest node has no child in the cut, so it creates triangles of the mesh.
  // Allowed errors that vary from vertex to vertex (a uniform one refines in node order, no heap).
  std::vector<float> field(m.built.vertex_count());
  for (std::size_t v = 0; v < field.size(); ++v) field[v] = 1e-6f * float(1 + v % 5);
  const cut::AllowedError everywhere = cut::AllowedError::from_vertices(field);
  std::size_t budget = 0;
  std::uint32_t far = 0;
  cut::CutMesh intact;
  for (std::size_t extra = 10; extra < m.built.triangle_count() && budget == 0; extra *= 2) {
    EXPECT_TRUE(cut::Refiner(m.built).refine(
        cut::Refinement::from_root(everywhere).within(m.built.root_triangle_count() + extra), intact));
    std::uint32_t last_in_cut = 0;
    far = 0;
    for (const std::uint32_t t : intact.ids) {
      last_in_cut = std::max(last_in_cut, m.built.triangle_creator(t));
      if (m.built.triangle_remover[t] != model::kNoNode) far = std::max(far, m.built.triangle_remover[t]);
    }
    if (block_of(far) > block_of(last_in_cut)) budget = m.built.root_triangle_count() + extra;
  }
  ASSERT_GT(budget, 0u) << "no budget reads the error of a node beyond its cut's blocks";
  const std::uint64_t at = model::mt_layout(model::mt_counts(m.built)).triangle_remover +
                           4 * std::uint64_t{m.built.node_triangle_offsets[far]};
  const fs::path path = altered("damaged-far-block.mt", [&](std::string& bytes) { bytes[at] ^= 0x40; });
  auto mapped = io::read_mt_file(path);
  ASSERT_TRUE(mapped.ok()) << mapped.error().message;

  cut::CutMesh cut;
  EXPECT_TRUE(cut::Refiner(*mapped).refine(cut::Refinement::from_root(everywhere).within(budget), cut));
  EXPECT_GT(cut.node_count, 1u);
  expect_same_cut(cut, intact, "budget of " + std::to_string(budget));
  const Status whole = cut::Refiner(*mapped).refine(
      cut::Refinement::from_root(everywhere).within(m.built.triangle_count()), cut);
  ASSERT_FALSE(whole) << "the damaged block was used without a complaint";
  EXPECT_NE(whole.error().message.find("block " + std::to_string(block_of(far))), std::string::npos)
      << whole.error().message;
}

TEST(MtMap, TruncatedOrDamagedHeadersAreRefusedAtOpen) {
  const Model& m = model();
  const std::size_t size = m.bytes.size();
  for (const std::size_t length : {std::size_t{0}, std::size_t{100}, std::size_t{300}, size / 2, size - 1}) {
    const fs::path path =
        altered("truncated-" + std::to_string(length) + ".mt", [&](std::string& b) { b.resize(length); });
    auto mt = io::read_mt_file(path);
    ASSERT_FALSE(mt.ok()) << length;
    EXPECT_EQ(mt.error().code, ErrorCode::kCorrupt) << length;
    EXPECT_NE(mt.error().message.find(path.string()), std::string::npos) << mt.error().message;
  }
  struct Case {
    const char* name;
    std::size_t at;
    const char* expect;
  };
  const std::size_t table =
      size - model::kMtBlockEntryBytes * model::mt_block_count(std::uint32_t(m.built.node_count()));
  const Case cases[] = {
      {"bounds", 64, "header checksum"},
      {"block-table", table + 3, "header checksum"},
      {"root-block", model::kMtHeaderBytes + 5, "block 0"},  // a position of a root vertex
      {"reserved", 200, "reserved"},
  };
  for (const Case& c : cases) {
    const fs::path path = altered(std::string(c.name) + ".mt", [&](std::string& b) { b[c.at] ^= 0x11; });
    auto mt = io::read_mt_file(path);
    ASSERT_FALSE(mt.ok()) << c.name;
    EXPECT_NE(mt.error().message.find(c.expect), std::string::npos) << c.name << ": " << mt.error().message;
  }
}

TEST(MtMap, FormatOneFilesAreReadWhole) {
  // An MT whose vertices are not in node order is written as version 1 and read whole.
  model::MtArrays arrays = model().built.arrays();
  const std::uint32_t v = arrays.node_vertex[1], w = arrays.node_vertex[2];
  arrays.node_vertex[1] = w;
  arrays.node_vertex[2] = v;
  for (std::uint32_t& c : arrays.triangle_corners) c = c == v ? w : c == w ? v : c;
  for (std::uint32_t& c : arrays.root_first_corner) c = c == v ? w : c == w ? v : c;
  for (int k = 0; k < 3; ++k) {
    std::swap(arrays.positions[3 * v + k], arrays.positions[3 * w + k]);
    if (!arrays.normals.empty()) std::swap(arrays.normals[3 * v + k], arrays.normals[3 * w + k]);
    if (!arrays.colors.empty()) std::swap(arrays.colors[3 * v + k], arrays.colors[3 * w + k]);
  }
  const model::Mt swapped(std::move(arrays));
  ASSERT_FALSE(swapped.vertices_in_node_order());
  const fs::path path = model().dir / "v1.mt";
  ASSERT_TRUE(io::write_mt_file(path, swapped).ok());
  EXPECT_EQ(test::read_file(path).substr(8, 1), std::string(1, '\1'));
  auto mt = io::read_mt_file(path);
  ASSERT_TRUE(mt.ok()) << mt.error().message;
  EXPECT_FALSE(mt->mapped());
  cut::Refiner a(*mt), b(swapped);
  cut::CutMesh ca, cb;
  EXPECT_TRUE(a.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)), ca));
  EXPECT_TRUE(b.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)), cb));
  expect_same_cut(ca, cb, "version 1");
}

}  // namespace
}  // namespace mtlod::core

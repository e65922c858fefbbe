// .mt format: bit-exact round trips, and rejection of every truncation, random byte corruptions and
// well-checksummed files with bad contents (core/ARCHITECTURE.md §2.8; core/model/FORMAT.md).
#include "core/model/mt_format.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <vector>

#include "core/cut/refine.hpp"
#include "core/io/mt_file.hpp"
#include "tests/core/mt_fixtures.hpp"
#include "tests/core/mt_reseal.hpp"

namespace mtlod::core {
namespace {

// A small MT with normals and colours, so every optional array is present.
const model::Mt& small_mt() {
  static const model::Mt mt = [] {
    eval::GenerateOptions options;
    options.shape = eval::Shape::kTerrain;
    options.target_triangles = 300;
    model::Mesh mesh = eval::generate_mesh(options);
    mesh.normals.assign(mesh.positions.size(), 0.0f);
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) mesh.normals[3 * v + 2] = 1.0f;
    mesh.colors.resize(mesh.positions.size());
    for (std::size_t i = 0; i < mesh.colors.size(); ++i) mesh.colors[i] = std::uint8_t(i * 7);
    auto built = build::build_mt(mesh);
    EXPECT_TRUE(built.ok());
    return std::move(built).value();
  }();
  return mt;
}

std::vector<std::uint8_t> bytes_of(const model::Mt& mt) {
  std::vector<std::uint8_t> bytes;
  model::serialize_mt(mt, bytes);
  return bytes;
}

template <class T>
void expect_equal(std::span<const T> a, std::span<const T> b, const char* name) {
  EXPECT_TRUE(std::ranges::equal(a, b)) << name;
}

void expect_same(const model::Mt& a, const model::Mt& b) {
  expect_equal(a.positions, b.positions, "positions");
  expect_equal(a.normals, b.normals, "normals");
  expect_equal(a.colors, b.colors, "colors");
  expect_equal(a.node_vertex, b.node_vertex, "node_vertex");
  expect_equal(a.node_error, b.node_error, "node_error");
  expect_equal(a.node_triangle_offsets, b.node_triangle_offsets, "node_triangle_offsets");
  expect_equal(a.node_parent_offsets, b.node_parent_offsets, "node_parent_offsets");
  expect_equal(a.node_parents, b.node_parents, "node_parents");
  expect_equal(a.triangle_corners, b.triangle_corners, "triangle_corners");
  expect_equal(a.root_first_corner, b.root_first_corner, "root_first_corner");
  expect_equal(a.triangle_remover, b.triangle_remover, "triangle_remover");
  EXPECT_EQ(a.bounds.lo, b.bounds.lo);
  EXPECT_EQ(a.bounds.hi, b.bounds.hi);
  EXPECT_EQ(a.input_triangles, b.input_triangles);
}

TEST(MtFormat, RoundTripIsBitExact) {
  const model::Mt& mt = small_mt();
  ASSERT_TRUE(mt.has_normals() && mt.has_colors());
  const std::vector<std::uint8_t> bytes = bytes_of(mt);
  auto back = model::deserialize_mt(bytes);
  ASSERT_TRUE(back.ok()) << back.error().message;
  expect_same(mt, *back);
  EXPECT_EQ(bytes_of(*back), bytes);
}

TEST(MtFormat, FileRoundTripOfARealScanIsBitExact) {
  const test::MtCase* c = test::scan_case("bunny-npm-3k.ply");
  if (!c) GTEST_SKIP();
  const auto path = test::scratch_dir("mt-format") / "bunny.mt";
  auto size = io::write_mt_file(path, c->mt);
  ASSERT_TRUE(size.ok()) << size.error().message;
  EXPECT_EQ(*size, std::filesystem::file_size(path));
  auto back = io::read_mt_file(path);
  ASSERT_TRUE(back.ok()) << back.error().message;
  expect_same(c->mt, *back);
  std::ifstream in(path, std::ios::binary);
  const std::vector<std::uint8_t> on_disk((std::istreambuf_iterator<char>(in)),
                                          std::istreambuf_iterator<char>());
  EXPECT_EQ(on_disk, bytes_of(c->mt));
}

TEST(MtFormat, MissingFileIsNotFound) {
  auto mt = io::read_mt_file(test::scratch_dir("mt-missing") / "absent.mt");
  ASSERT_FALSE(mt.ok());
  EXPECT_EQ(mt.error().code, ErrorCode::kNotFound);
}

TEST(MtFormat, EveryTruncationIsRejected) {
  const std::vector<std::uint8_t> bytes = bytes_of(small_mt());
  for (std::size_t length = 0; length < bytes.size(); ++length) {
    auto mt = model::deserialize_mt(std::span<const std::uint8_t>(bytes.data(), length));
    ASSERT_FALSE(mt.ok()) << "length " << length;
    ASSERT_EQ(mt.error().code, ErrorCode::kCorrupt) << length;
  }
  // One byte too many is as wrong as one too few.
  std::vector<std::uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_FALSE(model::deserialize_mt(longer).ok());
}

TEST(MtFormat, RandomSingleByteCorruptionsAreRejected) {
  const std::vector<std::uint8_t> bytes = bytes_of(small_mt());
  std::mt19937 rng(42);
  std::uniform_int_distribution<std::size_t> where(0, bytes.size() - 1);
  std::uniform_int_distribution<int> delta(1, 255);
  for (int i = 0; i < 1000; ++i) {
    std::vector<std::uint8_t> bad = bytes;
    const std::size_t at = where(rng);
    bad[at] = std::uint8_t(bad[at] + delta(rng));  // never the same value
    auto mt = model::deserialize_mt(bad);
    ASSERT_FALSE(mt.ok()) << "byte " << at;
    ASSERT_FALSE(mt.error().message.empty());
  }
}

// Files whose checksum is right but whose content is not: each names the field it breaks.
TEST(MtFormat, ContentErrorsBehindAValidChecksumAreNamed) {
  const model::Mt& good = small_mt();
  struct Case {
    const char* expect;  // substring of the error message
    void (*mutate)(model::MtArrays&);
  };
  const Case cases[] = {
      {"node_vertex[0]", [](model::MtArrays& m) { m.node_vertex[0] = 0; }},
      {"node_vertex[", [](model::MtArrays& m) { m.node_vertex[1] = std::uint32_t(m.positions.size() / 3); }},
      {"node_error", [](model::MtArrays& m) { m.node_error[1] = std::nanf(""); }},
      {"node_error", [](model::MtArrays& m) { m.node_error[2] = -1.0f; }},
      {"decreasing error", [](model::MtArrays& m) { m.node_error[1] = 0.0f; }},
      {"node_triangle_offsets",
       [](model::MtArrays& m) { std::swap(m.node_triangle_offsets[2], m.node_triangle_offsets[3]); }},
      {"parent", [](model::MtArrays& m) { m.node_parents[m.node_parent_offsets[1]] = 1; }},
      {"triangle_corners", [](model::MtArrays& m) { m.triangle_corners[5] = 1u << 30; }},
      {"root_first_corner",
       [](model::MtArrays& m) { m.root_first_corner[0] = std::uint32_t(m.positions.size() / 3); }},
      {"remover", [](model::MtArrays& m) { m.triangle_remover[m.node_triangle_offsets[1]] = 0; }},
      {"remover", [](model::MtArrays& m) { m.triangle_remover[0] = std::uint32_t(m.node_vertex.size()); }},
      {"positions", [](model::MtArrays& m) { m.positions[4] = std::numeric_limits<float>::infinity(); }},
  };
  for (const Case& c : cases) {
    model::MtArrays bad = good.arrays();
    c.mutate(bad);
    auto mt = model::deserialize_mt(bytes_of(model::Mt(std::move(bad))));
    ASSERT_FALSE(mt.ok()) << c.expect;
    EXPECT_EQ(mt.error().code, ErrorCode::kCorrupt);
    EXPECT_NE(mt.error().message.find(c.expect), std::string::npos) << mt.error().message;
  }
  // Version and magic are read before any checksum.
  std::vector<std::uint8_t> bytes = bytes_of(good);
  bytes[8] = 3;  // version
  auto mt = model::deserialize_mt(bytes);
  ASSERT_FALSE(mt.ok());
  EXPECT_EQ(mt.error().code, ErrorCode::kUnsupported);
  bytes = bytes_of(good);
  bytes[0] = 'X';
  EXPECT_NE(model::deserialize_mt(bytes).error().message.find("magic"), std::string::npos);
}

TEST(MtFormat, ResealedRandomWordsAreRejectedOrRefineSafely) {
  // A random 32-bit word of the arrays behind valid checksums either fails validation or gives an
  // MT the refiner walks without leaving its arrays (this runs under ASan/UBSan in CI); read whole
  // or viewed in place with its blocks checked on first use.
  const std::vector<std::uint8_t> bytes = bytes_of(small_mt());
  const std::size_t table = model::mt_layout(*model::mt_header_counts(bytes)).block_table;
  std::mt19937 rng(9);
  std::uniform_int_distribution<std::size_t> word(model::kMtHeaderBytes / 4, table / 4 - 1);
  int accepted = 0, viewed = 0;
  // Whether every refinement succeeded; one that reaches a block failing its check fails (kCorrupt).
  auto walk = [](const model::Mt& mt) {
    cut::CutMesh out;
    cut::Refiner refiner(mt);
    bool all = true;
    auto check = [&](const Status& refined) {
      if (!refined) {
        EXPECT_EQ(refined.error().code, ErrorCode::kCorrupt) << refined.error().message;
        all = false;
        return;
      }
      for (const std::uint32_t v : out.triangles) ASSERT_LT(v, mt.vertex_count());
    };
    check(refiner.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(-1.0f)), out));
    check(refiner.refine(cut::Refinement::from_root(cut::AllowedError::everywhere(0.0f)).within(100), out));
    check(refiner.refine(cut::Refinement::move(cut::AllowedError::everywhere(0.01f)), out));
    return all;
  };
  for (int i = 0; i < 1000; ++i) {
    std::vector<std::uint8_t> bad = bytes;
    const std::size_t at = 4 * word(rng);
    const std::uint32_t value = rng() % 4 == 0 ? std::uint32_t(rng() % 64) : std::uint32_t(rng());
    std::memcpy(bad.data() + at, &value, 4);
    ASSERT_TRUE(test::reseal_mt_image(bad));
    auto view = model::view_mt(bad, nullptr);
    auto mt = model::deserialize_mt(bad);
    if (view.ok()) {
      ++viewed;
      if (!walk(*view)) EXPECT_FALSE(mt.ok()) << "a block of a valid file failed its check";
    } else {
      EXPECT_FALSE(mt.ok()) << "the view refused what the whole read accepts: " << view.error().message;
    }
    if (!mt.ok()) continue;
    ++accepted;
    EXPECT_TRUE(walk(*mt));
  }
  EXPECT_GE(viewed, accepted);
  // Positions, normals, colours and errors accept most values, so some files must pass.
  EXPECT_GT(accepted, 0);
}

TEST(MtFormat, ChecksumSeesEverySingleByteChange) {
  // Each 8-byte step is x -> (h ^ x) * odd, a bijection, so no single-byte change can cancel.
  std::vector<std::uint8_t> bytes(37);
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = std::uint8_t(i * 31);
  const std::uint64_t base = model::mt_checksum(bytes);
  for (std::size_t i = 0; i < bytes.size(); ++i)
    for (int d = 1; d < 256; ++d) {
      std::vector<std::uint8_t> changed = bytes;
      changed[i] = std::uint8_t(changed[i] + d);
      ASSERT_NE(model::mt_checksum(changed), base) << i << " " << d;
    }
}

}  // namespace
}  // namespace mtlod::core

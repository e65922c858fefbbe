// .mt format: bit-exact round trips, and rejection of every truncation, random byte corruptions and
// well-checksummed files with bad contents (DESIGN.md §2 "Storage"; core/FORMAT.md).
#include "core/mt_format.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <fstream>
#include <random>
#include <vector>

#include "core/io/mt_file.hpp"
#include "core/refine.hpp"
#include "tests/core/mt_fixtures.hpp"

namespace mtlod::core {
namespace {

// A small MT with normals and colours, so every optional array is present.
const Mt& small_mt() {
  static const Mt mt = [] {
    GenerateOptions options;
    options.shape = Shape::kTerrain;
    options.target_triangles = 300;
    Mesh mesh = generate_mesh(options);
    mesh.normals.assign(mesh.positions.size(), 0.0f);
    for (std::size_t v = 0; v < mesh.vertex_count(); ++v) mesh.normals[3 * v + 2] = 1.0f;
    mesh.colors.resize(mesh.positions.size());
    for (std::size_t i = 0; i < mesh.colors.size(); ++i) mesh.colors[i] = std::uint8_t(i * 7);
    auto built = build_mt(mesh);
    EXPECT_TRUE(built.ok());
    return std::move(built).value();
  }();
  return mt;
}

std::vector<std::uint8_t> bytes_of(const Mt& mt) {
  std::vector<std::uint8_t> bytes;
  serialize_mt(mt, bytes);
  return bytes;
}

// Rewrites the checksum so a deliberate change reaches the content checks.
void reseal(std::vector<std::uint8_t>& bytes) {
  std::memset(bytes.data() + 48, 0, 8);
  const std::uint64_t sum = mt_checksum(bytes);
  std::memcpy(bytes.data() + 48, &sum, 8);
}

void expect_same(const Mt& a, const Mt& b) {
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.normals, b.normals);
  EXPECT_EQ(a.colors, b.colors);
  EXPECT_EQ(a.node_vertex, b.node_vertex);
  EXPECT_EQ(a.node_error, b.node_error);
  EXPECT_EQ(a.node_triangle_offsets, b.node_triangle_offsets);
  EXPECT_EQ(a.node_parent_offsets, b.node_parent_offsets);
  EXPECT_EQ(a.node_parents, b.node_parents);
  EXPECT_EQ(a.triangle_corners, b.triangle_corners);
  EXPECT_EQ(a.root_first_corner, b.root_first_corner);
  EXPECT_EQ(a.triangle_remover, b.triangle_remover);
}

TEST(MtFormat, RoundTripIsBitExact) {
  const Mt& mt = small_mt();
  ASSERT_TRUE(mt.has_normals() && mt.has_colors());
  const std::vector<std::uint8_t> bytes = bytes_of(mt);
  auto back = deserialize_mt(bytes);
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
  const std::vector<std::uint8_t> on_disk((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
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
    auto mt = deserialize_mt(std::span<const std::uint8_t>(bytes.data(), length));
    ASSERT_FALSE(mt.ok()) << "length " << length;
    ASSERT_EQ(mt.error().code, ErrorCode::kCorrupt) << length;
  }
  // One byte too many is as wrong as one too few.
  std::vector<std::uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_FALSE(deserialize_mt(longer).ok());
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
    auto mt = deserialize_mt(bad);
    ASSERT_FALSE(mt.ok()) << "byte " << at;
    ASSERT_FALSE(mt.error().message.empty());
  }
}

// Files whose checksum is right but whose content is not: each names the field it breaks.
TEST(MtFormat, ContentErrorsBehindAValidChecksumAreNamed) {
  const Mt& good = small_mt();
  struct Case {
    const char* expect;  // substring of the error message
    void (*mutate)(Mt&);
  };
  const Case cases[] = {
      {"node_vertex[0]", [](Mt& m) { m.node_vertex[0] = 0; }},
      {"node_vertex[", [](Mt& m) { m.node_vertex[1] = std::uint32_t(m.vertex_count()); }},
      {"node_error", [](Mt& m) { m.node_error[1] = std::nanf(""); }},
      {"node_error", [](Mt& m) { m.node_error[2] = -1.0f; }},
      {"node_triangle_offsets", [](Mt& m) { std::swap(m.node_triangle_offsets[2], m.node_triangle_offsets[3]); }},
      {"parent", [](Mt& m) { m.node_parents[m.node_parent_offsets[1]] = 1; }},
      {"triangle_corners", [](Mt& m) { m.triangle_corners[5] = 1u << 30; }},
      {"root_first_corner", [](Mt& m) { m.root_first_corner[0] = std::uint32_t(m.vertex_count()); }},
      {"remover", [](Mt& m) { m.triangle_remover[m.node_triangle_offsets[1]] = 0; }},
      {"remover", [](Mt& m) { m.triangle_remover[0] = std::uint32_t(m.node_count()); }},
      {"positions", [](Mt& m) { m.positions[4] = std::numeric_limits<float>::infinity(); }},
  };
  for (const Case& c : cases) {
    Mt bad = good;
    c.mutate(bad);
    auto mt = deserialize_mt(bytes_of(bad));
    ASSERT_FALSE(mt.ok()) << c.expect;
    EXPECT_EQ(mt.error().code, ErrorCode::kCorrupt);
    EXPECT_NE(mt.error().message.find(c.expect), std::string::npos) << mt.error().message;
  }
  std::vector<std::uint8_t> bytes = bytes_of(good);
  bytes[8] = 2;  // version
  reseal(bytes);
  auto mt = deserialize_mt(bytes);
  ASSERT_FALSE(mt.ok());
  EXPECT_EQ(mt.error().code, ErrorCode::kUnsupported);
  bytes = bytes_of(good);
  bytes[0] = 'X';
  reseal(bytes);
  EXPECT_NE(deserialize_mt(bytes).error().message.find("magic"), std::string::npos);
}

TEST(MtFormat, ResealedRandomWordsAreRejectedOrRefineSafely) {
  // A random 32-bit word behind a valid checksum either fails validation or gives an MT the refiner
  // walks without leaving its arrays (this runs under ASan/UBSan in CI).
  const std::vector<std::uint8_t> bytes = bytes_of(small_mt());
  std::mt19937 rng(9);
  std::uniform_int_distribution<std::size_t> word(0, bytes.size() / 4 - 1);
  int accepted = 0;
  for (int i = 0; i < 1000; ++i) {
    std::vector<std::uint8_t> bad = bytes;
    const std::size_t at = 4 * word(rng);
    if (at == 48 || at == 52) continue;  // the checksum itself
    const std::uint32_t value = rng() % 4 == 0 ? std::uint32_t(rng() % 64) : std::uint32_t(rng());
    std::memcpy(bad.data() + at, &value, 4);
    reseal(bad);
    auto mt = deserialize_mt(bad);
    if (!mt.ok()) continue;
    ++accepted;
    CutMesh out;
    Refiner refiner(*mt);
    refiner.refine(AllowedError::everywhere(-1.0f), out);
    refiner.refine_budget(AllowedError::everywhere(0.0f), 100, out);
    refiner.update(AllowedError::everywhere(0.01f), out);
    for (const std::uint32_t v : out.triangles) ASSERT_LT(v, mt->vertex_count());
  }
  // Positions, normals, colours and errors accept most values, so some files must pass.
  EXPECT_GT(accepted, 0);
}

TEST(MtFormat, ChecksumSeesEverySingleByteChange) {
  // Each 8-byte step is x -> (h ^ x) * odd, a bijection, so no single-byte change can cancel.
  std::vector<std::uint8_t> bytes(37);
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = std::uint8_t(i * 31);
  const std::uint64_t base = mt_checksum(bytes);
  for (std::size_t i = 0; i < bytes.size(); ++i)
    for (int d = 1; d < 256; ++d) {
      std::vector<std::uint8_t> changed = bytes;
      changed[i] = std::uint8_t(changed[i] + d);
      ASSERT_NE(mt_checksum(changed), base) << i << " " << d;
    }
}

}  // namespace
}  // namespace mtlod::core

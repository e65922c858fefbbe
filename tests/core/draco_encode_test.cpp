// Draco payloads decode (with the Draco library, and with Google's draco_decoder command) to the
// cut that was encoded: same triangles over the same vertices, positions within quantization,
// colours exact.
#include "core/codec/draco_encode.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <unordered_map>

#include "core/codec/draco_decode.hpp"
#include "core/eval/mesh_gen.hpp"
#include "core/model/bounds.hpp"
#include "tests/core/googles_draco_decoder.hpp"
#include "tests/core/mesh_compare.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::core {
namespace {

// Colours that differ from vertex to vertex and cover the whole byte range.
std::vector<std::uint8_t> colours_of(std::size_t vertices) {
  std::vector<std::uint8_t> colours(3 * vertices);
  for (std::size_t i = 0; i < colours.size(); ++i) colours[i] = static_cast<std::uint8_t>(i * 37 % 256);
  return colours;
}

model::Mesh sphere(std::size_t triangles) {
  eval::GenerateOptions o;
  o.target_triangles = triangles;
  model::Mesh m = eval::generate_mesh(o);
  // Normals: the normalised position is close enough for a closed blob and gives distinct values.
  for (std::size_t v = 0; v < m.vertex_count(); ++v) {
    const float* p = &m.positions[3 * v];
    const float len = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    m.normals.insert(m.normals.end(), {p[0] / len, p[1] / len, p[2] / len});
  }
  return m;
}

// Encodes `cut` (triangles of `model`), decodes, and checks the triangle set is unchanged.
void expect_round_trip(const model::Mesh& model, const std::vector<std::uint32_t>& cut,
                       const codec::DracoOptions& options) {
  codec::DracoEncoder encoder;
  std::vector<std::uint8_t> bytes;
  codec::DracoInput input{model.positions, model.normals, {}, cut};
  auto stats = encoder.encode(input, options, bytes);
  ASSERT_TRUE(stats.ok()) << stats.error().message;
  EXPECT_EQ(stats->bytes, bytes.size());
  EXPECT_EQ(stats->triangles, cut.size() / 3);
  auto decoded = codec::decode_draco(bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  ASSERT_EQ(decoded->mesh.triangle_count(), cut.size() / 3);
  const float tolerance =
      test::draco_tolerance(test::used_extent(model.positions, cut), options.position_bits);
  const auto match =
      test::match_vertices(decoded->mesh.positions, model.positions, cut, 4 * tolerance, tolerance);
  EXPECT_EQ(test::canonical_triangles(decoded->mesh.triangles, &match), test::canonical_triangles(cut));
}

TEST(DracoEncoder, DecodesToTheSameTrianglesForEveryMethodAndSpeed) {
  const model::Mesh m = sphere(8'000);
  for (codec::DracoMethod method : {codec::DracoMethod::kEdgebreaker, codec::DracoMethod::kSequential}) {
    for (int speed : {0, 5, 10}) {
      for (bool entropy : {true, false}) {
        SCOPED_TRACE(testing::Message()
                     << "method " << int(method) << " speed " << speed << " entropy " << entropy);
        codec::DracoOptions options;
        options.method = method;
        options.speed = speed;
        options.entropy_coding = entropy;
        expect_round_trip(m, m.triangles, options);
      }
    }
  }
}

TEST(DracoEncoder, RawAttributeValuesTradeBytesForSpeed) {
  // Without entropy coding the quantized positions are stored as they are: the payload must grow.
  const model::Mesh m = sphere(8'000);
  for (codec::DracoMethod method : {codec::DracoMethod::kEdgebreaker, codec::DracoMethod::kSequential}) {
    codec::DracoOptions coded, raw;
    coded.method = raw.method = method;
    raw.entropy_coding = false;
    std::vector<std::uint8_t> coded_bytes, raw_bytes;
    ASSERT_TRUE(codec::DracoEncoder().encode({m.positions, {}, {}, m.triangles}, coded, coded_bytes).ok());
    ASSERT_TRUE(codec::DracoEncoder().encode({m.positions, {}, {}, m.triangles}, raw, raw_bytes).ok());
    EXPECT_GT(raw_bytes.size(), coded_bytes.size()) << "method " << int(method);
  }
}

TEST(DracoEncoder, EncodesOnlyTheVerticesOfAPartialCut) {
  // Every third triangle: an open, sparse subset whose vertex ids are scattered over the model.
  const model::Mesh m = sphere(6'000);
  std::vector<std::uint32_t> cut;
  for (std::size_t t = 0; t < m.triangle_count(); t += 3)
    cut.insert(cut.end(), &m.triangles[3 * t], &m.triangles[3 * t] + 3);
  std::vector<std::uint8_t> used(m.vertex_count(), 0);
  for (std::uint32_t v : cut) used[v] = 1;
  codec::DracoEncoder encoder;
  std::vector<std::uint8_t> bytes;
  codec::DracoOptions options;
  options.method = codec::DracoMethod::kSequential;
  auto stats = encoder.encode({m.positions, {}, {}, cut}, options, bytes);
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->vertices, static_cast<std::size_t>(std::count(used.begin(), used.end(), 1)));
  expect_round_trip(m, cut, options);
}

TEST(DracoEncoder, ReusedEncoderGivesTheSameBytesAsAFreshOne) {
  const model::Mesh a = sphere(3'000), b = sphere(1'000);
  codec::DracoEncoder reused;
  std::vector<std::uint8_t> first, second, fresh;
  ASSERT_TRUE(reused.encode({a.positions, {}, {}, a.triangles}, {}, first).ok());
  ASSERT_TRUE(reused.encode({b.positions, {}, {}, b.triangles}, {}, second).ok());
  ASSERT_TRUE(codec::DracoEncoder().encode({b.positions, {}, {}, b.triangles}, {}, fresh).ok());
  EXPECT_EQ(second, fresh);
  // Partial cuts of one model in turn: nothing of the previous cut's vertices is left behind.
  for (const std::size_t step : {3u, 2u, 5u}) {
    std::vector<std::uint32_t> cut;
    for (std::size_t t = 0; t < a.triangle_count(); t += step)
      cut.insert(cut.end(), &a.triangles[3 * t], &a.triangles[3 * t] + 3);
    ASSERT_TRUE(reused.encode({a.positions, {}, {}, cut}, {}, second).ok());
    ASSERT_TRUE(codec::DracoEncoder().encode({a.positions, {}, {}, cut}, {}, fresh).ok());
    EXPECT_EQ(second, fresh) << "every " << step << "th triangle";
  }
}

TEST(DracoEncoder, AFixedGridDecodesAVertexToTheSameFloatsInEveryPayload) {
  // Two overlapping halves of a mesh, encoded on the model's grid: every vertex they share decodes
  // bit for bit the same in both, and within the grid's quantization of the original.
  const model::Mesh m = sphere(4'000);
  codec::DracoOptions options;
  options.method = codec::DracoMethod::kSequential;
  options.entropy_coding = false;
  codec::DracoOptions::Grid grid;
  const model::Bounds box = model::bounds_of(m.positions);
  grid.origin = box.lo;
  grid.range = box.largest_side();
  options.position_grid = grid;
  const std::size_t n = m.triangle_count();
  const std::vector<std::uint32_t> first(m.triangles.begin(), m.triangles.begin() + 3 * (2 * n / 3)),
      second(m.triangles.begin() + 3 * (n / 3), m.triangles.end());
  std::map<std::array<float, 3>, int> seen;  // decoded position → how many payloads hold it
  std::size_t shared = 0;
  for (const auto* cut : {&first, &second}) {
    std::vector<std::uint8_t> bytes;
    ASSERT_TRUE(codec::DracoEncoder().encode({m.positions, {}, {}, *cut}, options, bytes).ok());
    auto decoded = codec::decode_draco(bytes);
    ASSERT_TRUE(decoded.ok()) << decoded.error().message;
    const float tolerance = test::draco_tolerance(grid.range, options.position_bits);
    const auto match =
        test::match_vertices(decoded->mesh.positions, m.positions, *cut, 4 * tolerance, tolerance);
    EXPECT_EQ(test::canonical_triangles(decoded->mesh.triangles, &match), test::canonical_triangles(*cut));
    for (std::size_t i = 0; i < decoded->mesh.vertex_count(); ++i) {
      const float* p = &decoded->mesh.positions[3 * i];
      shared += ++seen[{p[0], p[1], p[2]}] == 2;
    }
  }
  // The middle third's vertices appear in both payloads: with one grid, as the same floats.
  std::vector<std::uint8_t> used_first(m.vertex_count()), used_second(m.vertex_count());
  for (std::uint32_t v : first) used_first[v] = 1;
  for (std::uint32_t v : second) used_second[v] = 1;
  std::size_t common = 0;
  for (std::size_t v = 0; v < m.vertex_count(); ++v) common += used_first[v] && used_second[v];
  EXPECT_GT(common, 0u);
  EXPECT_EQ(shared, common);
}

class DracoAttributes : public testing::TestWithParam<bool> {};

TEST_P(DracoAttributes, NormalsColoursAndLabelsSurviveTheRoundTrip) {
  const model::Mesh m = sphere(2'000);
  const std::vector<std::uint8_t> colours = colours_of(m.vertex_count());
  std::vector<std::uint32_t> labels(m.vertex_count());
  for (std::size_t v = 0; v < labels.size(); ++v) labels[v] = static_cast<std::uint32_t>(v * 7 % 70'000);
  codec::DracoOptions options;
  options.normals = true;
  options.colors = true;
  options.labels = true;
  options.method = codec::DracoMethod::kSequential;
  options.entropy_coding = GetParam();
  std::vector<std::uint8_t> bytes;
  ASSERT_TRUE(codec::DracoEncoder()
                  .encode({m.positions, m.normals, labels, m.triangles, colours}, options, bytes)
                  .ok());
  auto decoded = codec::decode_draco(bytes);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  // Four distinct attributes, each named by its own id.
  const codec::DracoAttributeIds& ids = decoded->attribute_ids;
  EXPECT_GE(ids.position, 0);
  EXPECT_GE(ids.normal, 0);
  EXPECT_GE(ids.color, 0);
  EXPECT_GE(ids.label, 0);
  EXPECT_EQ(std::set<int>({ids.position, ids.normal, ids.color, ids.label}).size(), 4u);
  const float tolerance =
      test::draco_tolerance(test::used_extent(m.positions, m.triangles), options.position_bits);
  const auto match =
      test::match_vertices(decoded->mesh.positions, m.positions, m.triangles, 4 * tolerance, tolerance);
  ASSERT_EQ(decoded->mesh.normals.size(), decoded->mesh.positions.size());
  ASSERT_EQ(decoded->labels.size(), decoded->mesh.vertex_count());
  ASSERT_EQ(decoded->mesh.colors.size(), decoded->mesh.positions.size());
  for (std::size_t i = 0; i < match.size(); ++i) {
    const std::uint32_t v = match[i];
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(decoded->mesh.colors[3 * i + k], colours[3 * v + k]) << i;  // lossless
    const float* n = &decoded->mesh.normals[3 * i];
    // 10-bit octahedral quantization keeps directions within about 0.1 degree: cos > 0.9999.
    EXPECT_GT(n[0] * m.normals[3 * v] + n[1] * m.normals[3 * v + 1] + n[2] * m.normals[3 * v + 2], 0.9999f);
    EXPECT_EQ(decoded->labels[i], std::min<std::uint32_t>(labels[v], 65535));  // labels over 65535 saturate
  }
}
INSTANTIATE_TEST_SUITE_P(EntropyCoding, DracoAttributes, testing::Bool());

TEST(DracoEncoder, RejectsBadOptionsAndMissingAttributes) {
  const model::Mesh m = test::tetrahedron();
  std::vector<std::uint8_t> bytes;
  codec::DracoEncoder encoder;
  codec::DracoOptions bad_speed;
  bad_speed.speed = 11;
  EXPECT_FALSE(encoder.encode({m.positions, {}, {}, m.triangles}, bad_speed, bytes).ok());
  codec::DracoOptions want_normals;
  want_normals.normals = true;
  EXPECT_FALSE(encoder.encode({m.positions, {}, {}, m.triangles}, want_normals, bytes).ok());
  codec::DracoOptions want_colours;
  want_colours.colors = true;
  EXPECT_FALSE(encoder.encode({m.positions, {}, {}, m.triangles}, want_colours, bytes).ok());
  EXPECT_FALSE(encoder.encode({m.positions, {}, {}, {}}, {}, bytes).ok());
}

// Edgebreaker with entropy coding (the extract default) and sequential with raw values (the gaze
// default).
class GooglesDecoder : public testing::TestWithParam<bool> {};

TEST_P(GooglesDecoder, ReadsThePayload) {
  const model::Mesh m = sphere(5'000);
  std::vector<std::uint8_t> bytes;
  codec::DracoOptions options;
  if (!GetParam()) options.method = codec::DracoMethod::kSequential, options.entropy_coding = false;
  options.colors = true;
  const std::vector<std::uint8_t> colours = colours_of(m.vertex_count());
  ASSERT_TRUE(codec::DracoEncoder().encode({m.positions, {}, {}, m.triangles, colours}, options, bytes).ok());
  auto loaded =
      test::googles_draco_decode(bytes, test::scratch_dir("draco-cli"), GetParam() ? "coded" : "raw");
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->triangle_count(), m.triangle_count());
  ASSERT_EQ(loaded->vertex_count(), m.vertex_count());
  // Each vertex keeps its colour: matched by position (the encoder keeps every vertex here).
  const float tolerance =
      test::draco_tolerance(test::used_extent(m.positions, m.triangles), options.position_bits);
  const auto match =
      test::match_vertices(loaded->positions, m.positions, m.triangles, 4 * tolerance, tolerance);
  ASSERT_EQ(loaded->colors.size(), loaded->positions.size()) << "draco_decoder's PLY has no colours";
  for (std::size_t i = 0; i < match.size(); ++i)
    for (int k = 0; k < 3; ++k) EXPECT_EQ(loaded->colors[3 * i + k], colours[3 * match[i] + k]) << i;
}
INSTANTIATE_TEST_SUITE_P(EntropyCoding, GooglesDecoder, testing::Bool());

}  // namespace
}  // namespace mtlod::core

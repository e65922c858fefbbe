// Draco payloads decode (with the Draco library, and with Google's draco_decoder command) to the
// cut that was encoded: same triangles over the same vertices, positions within quantization.
#include "core/draco_encode.hpp"

#include <draco/compression/decode.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <unordered_map>

#include "core/io/mesh_io.hpp"
#include "core/mesh_gen.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::core {
namespace {

Mesh sphere(std::size_t triangles) {
  GenerateOptions o;
  o.target_triangles = triangles;
  Mesh m = generate_mesh(o);
  // Normals: the normalised position is close enough for a closed blob and gives distinct values.
  for (std::size_t v = 0; v < m.vertex_count(); ++v) {
    const float* p = &m.positions[3 * v];
    const float len = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    m.normals.insert(m.normals.end(), {p[0] / len, p[1] / len, p[2] / len});
  }
  return m;
}

std::unique_ptr<draco::Mesh> decode(const std::vector<std::uint8_t>& bytes) {
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  draco::Decoder decoder;
  auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
  EXPECT_TRUE(decoded.ok()) << decoded.status().error_msg_string();
  return decoded.ok() ? std::move(decoded).value() : nullptr;
}

// Maps each decoded point to the model vertex nearest to it (a hashed grid of cell `cell`), and
// checks the distance is within `tolerance`.
std::vector<std::uint32_t> match_points(const draco::Mesh& decoded, const Mesh& model,
                                        std::span<const std::uint32_t> candidates, float cell, float tolerance) {
  auto key = [cell](const float* p) {
    std::array<long, 3> k;
    for (int c = 0; c < 3; ++c) k[c] = std::lround(std::floor(p[c] / cell));
    return k;
  };
  struct KeyHash {
    std::size_t operator()(const std::array<long, 3>& k) const { return k[0] * 73856093 ^ k[1] * 19349663 ^ k[2] * 83492791; }
  };
  std::unordered_map<std::array<long, 3>, std::vector<std::uint32_t>, KeyHash> grid;
  for (std::uint32_t v : candidates) grid[key(&model.positions[3 * v])].push_back(v);
  const draco::PointAttribute* pos = decoded.GetNamedAttribute(draco::GeometryAttribute::POSITION);
  std::vector<std::uint32_t> match(decoded.num_points(), UINT32_MAX);
  for (draco::PointIndex i(0); i < decoded.num_points(); ++i) {
    float p[3];
    pos->GetMappedValue(i, p);
    const auto k = key(p);
    float best = INFINITY;
    for (long dx = -1; dx <= 1; ++dx)
      for (long dy = -1; dy <= 1; ++dy)
        for (long dz = -1; dz <= 1; ++dz) {
          auto it = grid.find({k[0] + dx, k[1] + dy, k[2] + dz});
          if (it == grid.end()) continue;
          for (std::uint32_t v : it->second) {
            const float* q = &model.positions[3 * v];
            const float d = std::max({std::abs(p[0] - q[0]), std::abs(p[1] - q[1]), std::abs(p[2] - q[2])});
            if (d < best) best = d, match[i.value()] = v;
          }
        }
    EXPECT_LE(best, tolerance) << "decoded point " << i.value() << " is far from every model vertex";
  }
  return match;
}

// Triangles as vertex-id triples rotated to start at their smallest id (orientation kept), sorted.
std::vector<std::array<std::uint32_t, 3>> canonical(std::vector<std::array<std::uint32_t, 3>> tris) {
  for (auto& t : tris) std::rotate(t.begin(), std::min_element(t.begin(), t.end()), t.end());
  std::sort(tris.begin(), tris.end());
  return tris;
}

float max_extent(const Mesh& m) {
  float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (std::size_t v = 0; v < m.vertex_count(); ++v)
    for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], m.positions[3 * v + c]), hi[c] = std::max(hi[c], m.positions[3 * v + c]);
  return std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
}

// Encodes `cut` (triangles of `model`), decodes, and checks the triangle set is unchanged.
void expect_round_trip(const Mesh& model, const std::vector<std::uint32_t>& cut, const DracoOptions& options) {
  DracoEncoder encoder;
  std::vector<std::uint8_t> bytes;
  DracoInput input{model.positions, model.normals, {}, cut};
  auto stats = encoder.encode(input, options, bytes);
  ASSERT_TRUE(stats.ok()) << stats.error().message;
  EXPECT_EQ(stats->bytes, bytes.size());
  EXPECT_EQ(stats->triangles, cut.size() / 3);
  auto decoded = decode(bytes);
  ASSERT_NE(decoded, nullptr);
  ASSERT_EQ(decoded->num_faces(), cut.size() / 3);
  // Draco quantizes over the largest extent: one step is extent / (2^bits - 1); a value moves by
  // at most half a step (plus float rounding, hence the factor 0.75 rather than 0.5).
  const float step = max_extent(model) / static_cast<float>((1 << options.position_bits) - 1);
  const auto match = match_points(*decoded, model, cut, 4 * step, 0.75f * step);
  std::vector<std::array<std::uint32_t, 3>> got, want;
  for (draco::FaceIndex f(0); f < decoded->num_faces(); ++f) {
    const auto& face = decoded->face(f);
    got.push_back({match[face[0].value()], match[face[1].value()], match[face[2].value()]});
  }
  for (std::size_t t = 0; t < cut.size() / 3; ++t) want.push_back({cut[3 * t], cut[3 * t + 1], cut[3 * t + 2]});
  EXPECT_EQ(canonical(got), canonical(want));
}

TEST(DracoEncoder, DecodesToTheSameTrianglesForEveryMethodAndSpeed) {
  const Mesh m = sphere(8'000);
  for (DracoMethod method : {DracoMethod::kEdgebreaker, DracoMethod::kSequential}) {
    for (int speed : {0, 5, 10}) {
      SCOPED_TRACE(testing::Message() << "method " << int(method) << " speed " << speed);
      DracoOptions options;
      options.method = method;
      options.speed = speed;
      expect_round_trip(m, m.triangles, options);
    }
  }
}

TEST(DracoEncoder, EncodesOnlyTheVerticesOfAPartialCut) {
  // Every third triangle: an open, sparse subset whose vertex ids are scattered over the model.
  const Mesh m = sphere(6'000);
  std::vector<std::uint32_t> cut;
  for (std::size_t t = 0; t < m.triangle_count(); t += 3) cut.insert(cut.end(), &m.triangles[3 * t], &m.triangles[3 * t] + 3);
  std::vector<std::uint8_t> used(m.vertex_count(), 0);
  for (std::uint32_t v : cut) used[v] = 1;
  DracoEncoder encoder;
  std::vector<std::uint8_t> bytes;
  DracoOptions options;
  options.method = DracoMethod::kSequential;
  auto stats = encoder.encode({m.positions, {}, {}, cut}, options, bytes);
  ASSERT_TRUE(stats.ok());
  EXPECT_EQ(stats->vertices, static_cast<std::size_t>(std::count(used.begin(), used.end(), 1)));
  expect_round_trip(m, cut, options);
}

TEST(DracoEncoder, ReusedEncoderGivesTheSameBytesAsAFreshOne) {
  const Mesh a = sphere(3'000), b = sphere(1'000);
  DracoEncoder reused;
  std::vector<std::uint8_t> first, second, fresh;
  ASSERT_TRUE(reused.encode({a.positions, {}, {}, a.triangles}, {}, first).ok());
  ASSERT_TRUE(reused.encode({b.positions, {}, {}, b.triangles}, {}, second).ok());
  ASSERT_TRUE(DracoEncoder().encode({b.positions, {}, {}, b.triangles}, {}, fresh).ok());
  EXPECT_EQ(second, fresh);
}

TEST(DracoEncoder, NormalsAndLabelsSurviveTheRoundTrip) {
  const Mesh m = sphere(2'000);
  std::vector<std::uint32_t> labels(m.vertex_count());
  for (std::size_t v = 0; v < labels.size(); ++v) labels[v] = static_cast<std::uint32_t>(v * 7 % 70'000);
  DracoOptions options;
  options.normals = true;
  options.labels = true;
  options.method = DracoMethod::kSequential;
  std::vector<std::uint8_t> bytes;
  ASSERT_TRUE(DracoEncoder().encode({m.positions, m.normals, labels, m.triangles}, options, bytes).ok());
  auto decoded = decode(bytes);
  ASSERT_NE(decoded, nullptr);
  const float step = max_extent(m) / ((1 << options.position_bits) - 1);
  const auto match = match_points(*decoded, m, m.triangles, 4 * step, 0.75f * step);
  const draco::PointAttribute* normal = decoded->GetNamedAttribute(draco::GeometryAttribute::NORMAL);
  const draco::PointAttribute* label = decoded->GetNamedAttribute(draco::GeometryAttribute::GENERIC);
  ASSERT_NE(normal, nullptr);
  ASSERT_NE(label, nullptr);
  for (draco::PointIndex i(0); i < decoded->num_points(); ++i) {
    const std::uint32_t v = match[i.value()];
    float n[3];
    normal->GetMappedValue(i, n);
    // 10-bit octahedral quantization keeps directions within about 0.1 degree: cos > 0.9999.
    EXPECT_GT(n[0] * m.normals[3 * v] + n[1] * m.normals[3 * v + 1] + n[2] * m.normals[3 * v + 2], 0.9999f);
    std::uint16_t l = 0;
    label->GetMappedValue(i, &l);
    EXPECT_EQ(l, std::min<std::uint32_t>(labels[v], 65535));  // labels over 65535 saturate
  }
}

TEST(DracoEncoder, RejectsBadOptionsAndMissingAttributes) {
  const Mesh m = test::tetrahedron();
  std::vector<std::uint8_t> bytes;
  DracoEncoder encoder;
  DracoOptions bad_speed;
  bad_speed.speed = 11;
  EXPECT_FALSE(encoder.encode({m.positions, {}, {}, m.triangles}, bad_speed, bytes).ok());
  DracoOptions want_normals;
  want_normals.normals = true;
  EXPECT_FALSE(encoder.encode({m.positions, {}, {}, m.triangles}, want_normals, bytes).ok());
  EXPECT_FALSE(encoder.encode({m.positions, {}, {}, {}}, {}, bytes).ok());
}

TEST(DracoEncoder, GooglesDracoDecoderReadsThePayload) {
  const Mesh m = sphere(5'000);
  std::vector<std::uint8_t> bytes;
  ASSERT_TRUE(DracoEncoder().encode({m.positions, {}, {}, m.triangles}, {}, bytes).ok());
  const auto dir = test::scratch_dir("draco-cli");
  std::ofstream(dir / "cut.drc", std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  const std::string command = "draco_decoder -i " + (dir / "cut.drc").string() + " -o " + (dir / "cut.ply").string() +
                              " > " + (dir / "log.txt").string() + " 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << "draco_decoder (Debian package draco) failed or is missing";
  io::LoadOptions raw;
  raw.clean = false;
  auto loaded = io::load_mesh(dir / "cut.ply", raw);
  ASSERT_TRUE(loaded.ok()) << loaded.error().message;
  EXPECT_EQ(loaded->mesh.triangle_count(), m.triangle_count());
  EXPECT_EQ(loaded->mesh.vertex_count(), m.vertex_count());
}

}  // namespace
}  // namespace mtlod::core

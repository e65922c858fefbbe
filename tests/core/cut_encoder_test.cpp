// The codec table (core/codec/cut_encoder.hpp): every codec takes the same codec-neutral
// PayloadOptions and its payload decodes, through the same decode_payload, to the cut's triangles
// with the attributes asked for; a delta's triangle order survives in each; each codec's file
// extension names it.
#include "core/codec/cut_encoder.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "core/build/vertex_normals.hpp"
#include "core/eval/mesh_gen.hpp"

namespace mtlod::core::codec {
namespace {

class CodecTable : public testing::TestWithParam<Codec> {
 protected:
  CodecTable() : mesh_(eval::generate_mesh({eval::Shape::kSphere, 3000, 1, 0.05f, true})) {
    mesh_.normals = build::vertex_normals(mesh_.positions, mesh_.triangles);
  }

  DracoInput input() const { return {mesh_.positions, mesh_.normals, {}, mesh_.triangles, mesh_.colors}; }

  // Triangle t's centroid, in the input or in a decoded mesh.
  static std::array<float, 3> centroid(const model::Mesh& m, std::size_t t) {
    std::array<float, 3> c{};
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) c[a] += m.positions[3 * std::size_t{m.triangles[3 * t + k]} + a] / 3;
    return c;
  }

  model::Mesh mesh_;
};

TEST_P(CodecTable, TheSameOptionsGiveEveryCodecTheAttributesAskedFor) {
  const Codec codec = GetParam();
  EXPECT_EQ(codec_of_file(traits(codec).file_extension), codec);
  CutEncoder encoder;
  EncodeOptions options;
  options.codec = codec;
  std::vector<std::uint8_t> payload;
  for (const bool attributes : {false, true}) {
    options.payload.normals = options.payload.colors = attributes;
    ASSERT_TRUE(encoder.encode(input(), options, payload).ok());
    const auto decoded = decode_payload(codec, payload);
    ASSERT_TRUE(decoded.ok()) << decoded.error().message;
    EXPECT_EQ(decoded->triangle_count(), mesh_.triangle_count());
    EXPECT_EQ(decoded->normals.size(), attributes ? decoded->positions.size() : 0u);
    EXPECT_EQ(decoded->colors.size(), attributes ? decoded->positions.size() : 0u);
  }
}

TEST_P(CodecTable, KeptTriangleOrderSurvivesEveryCodec) {
  // A delta's ids follow the cut's order: with keep_triangle_order each codec's triangles come back
  // in that order (Draco by its sequential method, whatever method is asked), within the
  // quantization of 14 bits over the sphere's box of about 2 units.
  CutEncoder encoder;
  EncodeOptions options;
  options.codec = GetParam();
  options.payload.keep_triangle_order = true;
  options.draco.method = DracoMethod::kEdgebreaker;
  std::vector<std::uint8_t> payload;
  ASSERT_TRUE(encoder.encode(input(), options, payload).ok());
  const auto decoded = decode_payload(GetParam(), payload);
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  ASSERT_EQ(decoded->triangle_count(), mesh_.triangle_count());
  const float tolerance = 2.5f / (1 << 14);
  std::size_t misplaced = 0;
  for (std::size_t t = 0; t < mesh_.triangle_count(); ++t) {
    const auto want = centroid(mesh_, t), got = centroid(*decoded, t);
    for (int a = 0; a < 3; ++a) misplaced += std::abs(want[a] - got[a]) > tolerance ? 1 : 0;
  }
  EXPECT_EQ(misplaced, 0u);
}

TEST(CodecTraits, NoOtherCodecClaimsAnExtension) {
  for (std::size_t c = 0; c < kCodecCount; ++c) {
    EXPECT_EQ(codec_of_file(kCodecTraits[c].file_extension), static_cast<Codec>(c));
    EXPECT_GT(kCodecTraits[c].max_position_bits, 0);
  }
  EXPECT_FALSE(codec_of_file(".glb").has_value());
}

INSTANTIATE_TEST_SUITE_P(Codecs, CodecTable, testing::Values(Codec::kDraco, Codec::kMeshopt),
                         [](const auto& info) { return info.param == Codec::kDraco ? "draco" : "meshopt"; });

}  // namespace
}  // namespace mtlod::core::codec

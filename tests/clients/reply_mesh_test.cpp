// Any mesh reply decoded as a viewer would (clients/common/reply_mesh.hpp): real payloads of both
// codecs, whole and in a scene, that decode and add up, and the ways they can fail to.
#include "clients/common/reply_mesh.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "core/codec/cut_encoder.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod {
namespace {

using core::codec::Codec;

// The tetrahedron's four triangles as a payload of `codec`.
std::vector<std::uint8_t> tetrahedron_payload(Codec codec) {
  const core::model::Mesh mesh = test::tetrahedron();
  core::codec::CutEncoder encoder;
  core::codec::EncodeOptions options;
  options.codec = codec;
  std::vector<std::uint8_t> payload;
  const auto encoded = encoder.encode({mesh.positions, {}, {}, mesh.triangles, {}}, options, payload);
  EXPECT_TRUE(encoded.ok()) << encoded.error().message;
  return payload;
}

protocol::MeshReply whole_reply(Codec codec, std::uint64_t triangles) {
  protocol::MeshReply reply;
  reply.model = "tetrahedron";
  reply.codec = codec;
  reply.triangles = triangles;
  return reply;
}

class ReplyMeshTest : public testing::TestWithParam<Codec> {};

TEST_P(ReplyMeshTest, AWholeMeshDecodesToTheTrianglesItsReplyGives) {
  const std::vector<std::uint8_t> payload = tetrahedron_payload(GetParam());
  clients::ReplyMesh mesh;
  EXPECT_TRUE(mesh.apply(whole_reply(GetParam(), 4), payload).ok());
  const auto miscounted = mesh.apply(whole_reply(GetParam(), 5), payload);
  ASSERT_FALSE(miscounted.ok());
  EXPECT_EQ(miscounted.error().message, "the payload decodes to 4 triangles, the reply says 5");
  // Cut short, or read with the other codec's decoder: the decoder's own error.
  const std::vector<std::uint8_t> cut(payload.begin(), payload.begin() + payload.size() / 2);
  EXPECT_FALSE(mesh.apply(whole_reply(GetParam(), 4), cut).ok());
  const Codec other = GetParam() == Codec::kDraco ? Codec::kMeshopt : Codec::kDraco;
  EXPECT_FALSE(mesh.apply(whole_reply(other, 4), payload).ok());
}

TEST_P(ReplyMeshTest, ASceneDecodesInstanceByInstance) {
  const std::vector<std::uint8_t> one = tetrahedron_payload(GetParam());
  std::vector<std::uint8_t> payload = one;
  payload.insert(payload.end(), one.begin(), one.end());
  protocol::MeshReply scene = whole_reply(GetParam(), 8);
  scene.model.clear();
  for (const char* name : {"a", "b"}) {
    protocol::InstanceMesh instance;
    instance.model = name;
    instance.triangles = 4;
    instance.bytes = one.size();
    scene.instances.push_back(instance);
  }
  clients::ReplyMesh mesh;
  EXPECT_TRUE(mesh.apply(scene, payload).ok());
  scene.instances[1].triangles = 3;
  const auto miscounted = mesh.apply(scene, payload);
  ASSERT_FALSE(miscounted.ok());
  EXPECT_EQ(miscounted.error().message,
            "instance 1 (b): the payload decodes to 4 triangles, the reply says 3");
  // Parts that do not add up to the payload.
  scene.instances[1].triangles = 4;
  scene.instances[1].bytes += 1;
  EXPECT_FALSE(mesh.apply(scene, payload).ok());
}

INSTANTIATE_TEST_SUITE_P(Codecs, ReplyMeshTest, testing::Values(Codec::kDraco, Codec::kMeshopt),
                         [](const auto& info) { return info.param == Codec::kDraco ? "draco" : "meshopt"; });

}  // namespace
}  // namespace mtlod

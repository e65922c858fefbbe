// One encoder and one decoder over the codecs (see cut_encoder.hpp).
#include "core/codec/cut_encoder.hpp"

#include <utility>

#include "core/codec/draco_decode.hpp"
#include "core/codec/meshopt_decode.hpp"

namespace mtlod::core::codec {
namespace {

DracoOptions draco_options(const PayloadOptions& p, const DracoTuning& tuning) {
  DracoOptions o;
  // Edgebreaker renumbers the faces; the sequential method keeps them.
  o.method = p.keep_triangle_order ? DracoMethod::kSequential : tuning.method;
  o.speed = tuning.speed;
  o.entropy_coding = tuning.entropy_coding;
  o.position_bits = p.position_bits;
  o.normal_bits = p.normal_bits;
  o.normals = p.normals;
  o.colors = p.colors;
  o.labels = p.labels;
  o.position_grid = p.position_grid;
  return o;
}

MeshoptOptions meshopt_options(const PayloadOptions& p) {
  MeshoptOptions o;
  o.position_bits = p.position_bits;
  o.normal_bits = p.normal_bits;
  o.normals = p.normals;
  o.colors = p.colors;
  o.keep_triangle_order = p.keep_triangle_order;
  o.position_grid = p.position_grid;
  return o;
}

}  // namespace

Result<EncodeStats> CutEncoder::encode(const DracoInput& input, const EncodeOptions& options,
                                       std::vector<std::uint8_t>& out) {
  switch (options.codec) {
    case Codec::kDraco:
      return draco_.encode(input, draco_options(options.payload, options.draco), out);
    case Codec::kMeshopt:
      return meshopt_.encode(input, meshopt_options(options.payload), out);
  }
  return make_error(ErrorCode::kInvalidArgument, "unknown codec");
}

Result<model::Mesh> decode_payload(Codec codec, std::span<const std::uint8_t> payload) {
  switch (codec) {
    case Codec::kDraco: {
      MTLOD_TRY(DecodedMesh decoded, decode_draco(payload));
      return std::move(decoded.mesh);
    }
    case Codec::kMeshopt: {
      MTLOD_TRY(DecodedMeshopt decoded, decode_meshopt(payload));
      return std::move(decoded.mesh);
    }
  }
  return make_error(ErrorCode::kInvalidArgument, "unknown codec");
}

}  // namespace mtlod::core::codec

// One encoder and one decoder over the codecs (see cut_encoder.hpp).
#include "core/codec/cut_encoder.hpp"

#include <utility>

#include "core/codec/draco_decode.hpp"
#include "core/codec/meshopt_decode.hpp"

namespace mtlod::core::codec {

Result<EncodeStats> CutEncoder::encode(const DracoInput& input, const EncodeOptions& options,
                                       std::vector<std::uint8_t>& out) {
  switch (options.codec) {
    case Codec::kDraco:
      return draco_.encode(input, options.draco, out);
    case Codec::kMeshopt:
      return meshopt_.encode(input, options.meshopt, out);
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

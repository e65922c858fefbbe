// The codecs a cut can be sent with, behind one encoder and one decoder: adding a codec is an
// enumerator here, a case in cut_encoder.cpp, its name in the protocol (kCodecNames) and the
// clients' decoders.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/codec/draco_encode.hpp"
#include "core/codec/meshopt_encode.hpp"
#include "core/model/mesh.hpp"
#include "core/result.hpp"

namespace mtlod::core::codec {

enum class Codec : std::uint8_t {
  kDraco,    // Draco (draco_encode): the smallest payloads with edgebreaker
  kMeshopt,  // meshoptimizer's streams (meshopt_encode): fast to encode and decode
};
inline constexpr std::size_t kCodecCount = 2;

// The codec and each codec's options (only the chosen one's are read).
struct EncodeOptions {
  Codec codec = Codec::kDraco;
  DracoOptions draco;
  MeshoptOptions meshopt;
};

// One reusable encoder per worker: each codec's encoder keeps its tables between calls.
class CutEncoder {
 public:
  // Encodes into `out` with the chosen codec; fails as that codec's encoder does.
  Result<EncodeStats> encode(const DracoInput& input, const EncodeOptions& options,
                             std::vector<std::uint8_t>& out);

 private:
  DracoEncoder draco_;
  MeshoptEncoder meshopt_;
};

// A payload of `codec` back to a mesh (positions; normals and colours when it has them;
// triangles), or the codec's decoding error.
Result<model::Mesh> decode_payload(Codec codec, std::span<const std::uint8_t> payload);

}  // namespace mtlod::core::codec

// The codecs a cut can be sent with, behind one encoder and one decoder: adding a codec is an
// enumerator and its file extension here, a case in cut_encoder.cpp (and in core/io/gltf's
// write_glb_payload), its name in the protocol (kCodecNames) and the viewer's decoder
// (clients/web/codecs.js).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
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

// The extension of a file holding one payload, as received, per codec.
inline constexpr std::array<std::string_view, kCodecCount> kCodecFileExtensions = {".drc", ".mopt"};

// The codec whose payload files end in `extension` (".drc"), if any.
constexpr std::optional<Codec> codec_of_file(std::string_view extension) {
  for (std::size_t c = 0; c < kCodecCount; ++c) {
    if (kCodecFileExtensions[c] == extension) return static_cast<Codec>(c);
  }
  return std::nullopt;
}

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

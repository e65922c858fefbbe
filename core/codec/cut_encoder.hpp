// The codecs a cut can be sent with, behind one encoder and one decoder. A codec is a row of this
// table: its enumerator and traits (file extension, what it can carry) here, its encoder's and
// decoder's cases in cut_encoder.cpp, which map the codec-neutral PayloadOptions to its own; beyond
// core/codec it has a name in the protocol (kCodecNames), a glTF writer (core/io/gltf
// write_glb_payload) and a decoder in the viewer (clients/web/codecs.js).
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

// What a codec's payloads are as files and what they can carry: the protocol refuses a request for
// more (protocol::codec_refusal).
struct CodecTraits {
  std::string_view file_extension;  // of a file holding one payload as received
  bool carries_labels;              // per-vertex distance labels
  int max_position_bits;            // the finest position quantization it writes
};
inline constexpr std::array<CodecTraits, kCodecCount> kCodecTraits = {{
    {".drc", true, 30},
    {".mopt", false, 16},
}};
constexpr const CodecTraits& traits(Codec codec) {
  return kCodecTraits[static_cast<std::size_t>(codec)];
}

// The codec whose payload files end in `extension` (".drc"), if any.
constexpr std::optional<Codec> codec_of_file(std::string_view extension) {
  for (std::size_t c = 0; c < kCodecCount; ++c) {
    if (kCodecTraits[c].file_extension == extension) return static_cast<Codec>(c);
  }
  return std::nullopt;
}

// What every codec is asked for, whichever is chosen.
struct PayloadOptions {
  int position_bits = 14;  // quantization of positions (at most traits(codec).max_position_bits)
  int normal_bits = 10;    // octahedral quantization of normals
  bool normals = false;    // the original vertices' normals (needs them in the input)
  bool colors = false;     // the vertices' colours (needs them in the input)
  bool labels = false;     // per-vertex labels (codecs that carry them)
  // Positions on this grid (the model's bounding box) instead of the encoded vertices' own box, so a
  // vertex decodes to the same floats in every payload (deltas).
  std::optional<DracoOptions::Grid> position_grid;
  // The triangles in the cut's order, which a delta's triangle ids follow: a codec that reorders
  // triangles for its ratio must not (Draco: the sequential method).
  bool keep_triangle_order = false;
};

// Draco's own choices, beyond PayloadOptions.
struct DracoTuning {
  DracoMethod method = DracoMethod::kEdgebreaker;
  int speed = 10;              // 0 (best ratio) .. 10 (fastest)
  bool entropy_coding = true;  // false: raw quantized values (faster, larger)
};

struct EncodeOptions {
  Codec codec = Codec::kDraco;
  PayloadOptions payload;
  DracoTuning draco;  // read only when codec is Draco
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

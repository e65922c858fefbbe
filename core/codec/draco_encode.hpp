// Draco compression of an extracted cut (core/ARCHITECTURE.md §3): positions, optional normals and
// colours of the original vertices and an optional per-vertex distance label as a generic attribute. Draco's
// headers stay inside draco_encode.cpp; callers see byte vectors only.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "core/result.hpp"

namespace mtlod::core::codec {

enum class DracoMethod : std::uint8_t {
  kEdgebreaker,  // best ratio (~6–10 bits per triangle), slower
  kSequential,   // fastest, ~80 bits per triangle
};
inline constexpr std::size_t kDracoMethodCount = 2;

struct DracoOptions {
  DracoMethod method = DracoMethod::kEdgebreaker;
  int speed = 10;              // Draco's encoding speed 0 (best ratio) .. 10 (fastest)
  int position_bits = 14;      // quantization of positions, 1..30 (0 = lossless float)
  int normal_bits = 10;        // quantization of normals, 1..30
  bool normals = false;        // encode the original vertices' normals (needs them in the input)
  bool colors = false;         // encode the vertices' colours as COLOR, 3 normalized uint8 (lossless)
  bool labels = false;         // encode per-vertex labels as a generic uint16 attribute "label"
  bool entropy_coding = true;  // false: attribute values stored as raw quantized integers (faster, larger)
  // Quantize positions on this fixed grid (the model's bounding box: origin and largest side)
  // instead of the encoded vertices' own box, so that a vertex decodes to the same floats in every
  // payload: meshes assembled from several payloads (delta replies) then have no cracks.
  struct Grid {
    std::array<float, 3> origin{};
    float range = 0;
  };
  std::optional<Grid> position_grid;
};

// What a cut looks like to the encoder: the model's vertex arrays and the cut's triangles, whose
// ids index those arrays. Only vertices the triangles use are encoded, in model vertex order.
struct DracoInput {
  std::span<const float> positions;          // x, y, z per model vertex
  std::span<const float> normals;            // empty, or x, y, z per model vertex
  std::span<const std::uint32_t> labels;     // empty, or one per model vertex (saturated to 65535)
  std::span<const std::uint32_t> triangles;  // three model vertex ids per triangle
  std::span<const std::uint8_t> colors;      // empty, or r, g, b per model vertex
};

// What an encoder reports of a payload (every codec of core/codec).
struct EncodeStats {
  std::size_t vertices = 0;   // vertices encoded
  std::size_t triangles = 0;  // triangles encoded
  std::size_t bytes = 0;      // size of the payload
};

// Reusable encoder: keeps its renumbering tables between calls, sized to the largest model seen.
class DracoEncoder {
 public:
  // Encodes into `out` (cleared first). Fails with kInvalidArgument when options are out of range
  // or attributes asked for are missing, and kInternal when Draco refuses the mesh.
  Result<EncodeStats> encode(const DracoInput& input, const DracoOptions& options,
                             std::vector<std::uint8_t>& out);

 private:
  // Marks the triangles' vertices in used_bits_ and lists them in model order in used_, with
  // rank_ holding each touched word's first encoded id.
  void list_used(std::span<const std::uint32_t> triangles);

  std::vector<std::uint64_t> used_bits_;      // one bit per model vertex: used by the cut (zero between)
  std::vector<std::uint32_t> rank_;           // per touched 64-bit word: used vertices in the words before it
  std::vector<std::uint32_t> touched_words_;  // words of used_bits_ the cut's vertices fall in
  std::vector<std::uint32_t> used_;           // encoded id -> model vertex id
  std::vector<float> scratch_;                // compacted attribute values
  std::vector<std::uint8_t> colors_;          // compacted colours
};

}  // namespace mtlod::core::codec

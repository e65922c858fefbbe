// meshoptimizer payload → Mesh (see meshopt_decode.hpp). Every length is checked against the bytes
// before anything is read, and the counts against the streams' sizes before anything is allocated:
// a vertex buffer spends at least one header byte on every 8 vertices of a stride-8 stream, and an
// index buffer a byte per triangle plus 17, so a short payload cannot ask for a huge mesh.
// meshoptimizer's decoders are safe on any bytes but may return garbage, so the decoded values are
// checked against what the header allows as they are converted.
#include "core/codec/meshopt_decode.hpp"

#include <meshoptimizer.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>
#include <utility>
#include <vector>

#include "core/codec/meshopt_encode.hpp"
#include "fmt/format.h"

namespace mtlod::core::codec {
namespace {

std::uint32_t get_u32(const std::uint8_t* at) {
  return std::uint32_t{at[0]} | std::uint32_t{at[1]} << 8 | std::uint32_t{at[2]} << 16 |
         std::uint32_t{at[3]} << 24;
}

float get_f32(const std::uint8_t* at) {
  return std::bit_cast<float>(get_u32(at));
}

Error corrupt(std::string message) {
  return make_error(ErrorCode::kCorrupt, "meshopt payload: " + std::move(message));
}

// Decodes one vertex stream of `count` elements into `values` (sized by the caller).
template <class T>
Status decode_stream(std::span<const std::uint8_t> stream, const char* name, std::size_t count,
                     std::size_t stride, std::vector<T>& values) {
  if (stream.empty() || stream[0] != kMeshoptVertexStreamHeader) {
    return corrupt(fmt::format("the {} stream is not a version-0 meshoptimizer vertex buffer", name));
  }
  values.resize(count * stride / sizeof(T));
  if (const int rc = meshopt_decodeVertexBuffer(values.data(), count, stride, stream.data(), stream.size())) {
    return corrupt(fmt::format("the {} stream does not decode (meshoptimizer error {})", name, rc));
  }
  return Ok{};
}

// Octahedral normals as meshopt_encodeFilterOct stores them, back to unit floats. Decoded in float
// rather than with meshopt_decodeFilterOct, which rounds the result to the stored width again.
template <class T>
Status decode_normals(std::span<const std::uint8_t> stream, const MeshoptPayload& p,
                      std::vector<float>& out) {
  std::vector<T> stored;
  MTLOD_RETURN_IF_ERROR(decode_stream(stream, "normals", p.vertex_count, p.normal_stride, stored));
  const int one = (1 << (p.normal_bits - 1)) - 1;
  out.resize(3 * std::size_t{p.vertex_count});
  for (std::size_t i = 0; i < p.vertex_count; ++i) {
    const int u = stored[4 * i], v = stored[4 * i + 1];
    // Off the octahedron |x| + |y| + |z| = 1 (in units of `one`) the decoding below could reach a zero
    // vector; the encoder writes `one` as the third component and zero as the fourth.
    if (stored[4 * i + 2] != one || std::abs(u) > one || std::abs(v) > one || stored[4 * i + 3] != 0) {
      return corrupt(fmt::format("normal {} is not an octahedral {}-bit vector", i, p.normal_bits));
    }
    float x = static_cast<float>(u) / static_cast<float>(one);
    float y = static_cast<float>(v) / static_cast<float>(one);
    const float z = 1.0f - std::abs(x) - std::abs(y);
    // The lower half is folded over the diagonals: unfold it.
    if (z < 0) {
      const float fx = std::copysign(1.0f - std::abs(y), x);
      y = std::copysign(1.0f - std::abs(x), y);
      x = fx;
    }
    const float length = std::sqrt(x * x + y * y + z * z);  // at least 1/√3 on the octahedron
    out[3 * i] = x / length;
    out[3 * i + 1] = y / length;
    out[3 * i + 2] = z / length;
  }
  return Ok{};
}

}  // namespace

Result<MeshoptPayload> read_meshopt(std::span<const std::uint8_t> payload) {
  if (payload.size() < kMeshoptHeaderBytes) {
    return corrupt(
        fmt::format("{} bytes, shorter than the {}-byte header", payload.size(), kMeshoptHeaderBytes));
  }
  const std::uint8_t* h = payload.data();
  if (std::memcmp(h, kMeshoptMagic, 4) != 0) return corrupt("the magic is not \"MOPT\"");
  if (h[4] != kMeshoptVersion) {
    return make_error(
        ErrorCode::kUnsupported,
        fmt::format("meshopt payload version {}; this build reads version {}", h[4], kMeshoptVersion));
  }
  MeshoptPayload p;
  const std::uint8_t flags = h[5];
  constexpr std::uint8_t kKnownFlags = kMeshoptHasNormals | kMeshoptHasColors | kMeshoptWideNormals;
  const bool normals = flags & kMeshoptHasNormals, wide = flags & kMeshoptWideNormals;
  if ((flags & ~kKnownFlags) != 0 || (wide && !normals)) {
    return corrupt(fmt::format("flags {:#04x} are not a valid combination", flags));
  }
  p.colors = flags & kMeshoptHasColors;
  p.position_bits = h[6];
  if (p.position_bits < 1 || p.position_bits > 16) {
    return corrupt(fmt::format("position_bits {} outside 1..16", p.position_bits));
  }
  p.normal_bits = h[7];
  if (normals) {
    p.normal_stride = wide ? 8 : 4;
    const int lowest = wide ? 9 : 2, highest = wide ? 16 : 8;
    if (p.normal_bits < lowest || p.normal_bits > highest) {
      return corrupt(fmt::format("normal_bits {} outside {}..{} for {}-byte normals", p.normal_bits, lowest,
                                 highest, p.normal_stride));
    }
  } else if (p.normal_bits != 0) {
    return corrupt(fmt::format("normal_bits {} without normals", p.normal_bits));
  }
  p.vertex_count = get_u32(h + 8);
  p.triangle_count = get_u32(h + 12);
  if (p.vertex_count == 0 || p.triangle_count == 0) {
    return corrupt(
        fmt::format("{} vertices and {} triangles: neither may be 0", p.vertex_count, p.triangle_count));
  }
  for (int k = 0; k < 3; ++k) p.origin[k] = get_f32(h + 16 + 4 * k);
  p.step = get_f32(h + 28);
  // Every decoded coordinate, up to the grid's far corner, must be finite too.
  const float top = static_cast<float>((1 << p.position_bits) - 1) * p.step;
  if (!std::isfinite(top) || p.step < 0 || !std::isfinite(p.origin[0] + top) ||
      !std::isfinite(p.origin[1] + top) || !std::isfinite(p.origin[2] + top)) {
    return corrupt("the grid of the positions (origin and step) is not finite, or its step is negative");
  }

  std::size_t at = kMeshoptHeaderBytes;
  auto next_stream = [&](const char* name, std::span<const std::uint8_t>& stream) -> Status {
    if (payload.size() - at < 4) {
      return corrupt(fmt::format("ends at byte {} before the length of the {} stream", payload.size(), name));
    }
    const std::uint32_t length = get_u32(h + at);
    at += 4;
    if (length > payload.size() - at) {
      return corrupt(fmt::format("the {} stream's {} bytes at byte {} run past the end ({} bytes)", name,
                                 length, at, payload.size()));
    }
    stream = payload.subspan(at, length);
    at += length;
    return Ok{};
  };
  MTLOD_RETURN_IF_ERROR(next_stream("positions", p.positions));
  if (normals) MTLOD_RETURN_IF_ERROR(next_stream("normals", p.normals));
  if (p.colors) MTLOD_RETURN_IF_ERROR(next_stream("colours", p.colours));
  MTLOD_RETURN_IF_ERROR(next_stream("triangles", p.triangles));
  if (at != payload.size()) {
    return corrupt(fmt::format("{} bytes follow the last stream", payload.size() - at));
  }
  if (p.vertex_count / 8 > p.positions.size()) {
    return corrupt(fmt::format("{} vertices cannot fit in a {}-byte positions stream", p.vertex_count,
                               p.positions.size()));
  }
  if (std::size_t{p.triangle_count} + 17 > p.triangles.size()) {
    return corrupt(fmt::format("{} triangles cannot fit in a {}-byte triangles stream", p.triangle_count,
                               p.triangles.size()));
  }
  return p;
}

Result<DecodedMeshopt> decode_meshopt(std::span<const std::uint8_t> payload) {
  MTLOD_TRY(const MeshoptPayload p, read_meshopt(payload));
  const std::size_t n = p.vertex_count;
  DecodedMeshopt out;
  out.origin = p.origin;
  out.step = p.step;
  out.position_bits = p.position_bits;
  out.normal_bits = p.normal_bits;
  model::Mesh& mesh = out.mesh;

  std::vector<std::uint16_t> stored;
  MTLOD_RETURN_IF_ERROR(decode_stream(p.positions, "positions", n, 8, stored));
  const unsigned highest = (1u << p.position_bits) - 1;
  mesh.positions.resize(3 * n);
  out.stored_min.fill(UINT16_MAX);
  for (std::size_t i = 0; i < n; ++i) {
    if (stored[4 * i] > highest || stored[4 * i + 1] > highest || stored[4 * i + 2] > highest ||
        stored[4 * i + 3] != 0) {
      return corrupt(
          fmt::format("position {} is not three {}-bit coordinates and a zero", i, p.position_bits));
    }
    for (int k = 0; k < 3; ++k) {
      const std::uint16_t q = stored[4 * i + k];
      mesh.positions[3 * i + k] = p.origin[k] + static_cast<float>(q) * p.step;
      out.stored_min[k] = std::min(out.stored_min[k], q);
      out.stored_max[k] = std::max(out.stored_max[k], q);
    }
  }
  if (p.normal_stride == 4) {
    MTLOD_RETURN_IF_ERROR(decode_normals<std::int8_t>(p.normals, p, mesh.normals));
  } else if (p.normal_stride == 8) {
    MTLOD_RETURN_IF_ERROR(decode_normals<std::int16_t>(p.normals, p, mesh.normals));
  }
  if (p.colors) {
    std::vector<std::uint8_t> rgba;
    MTLOD_RETURN_IF_ERROR(decode_stream(p.colours, "colours", n, 4, rgba));
    mesh.colors.resize(3 * n);
    for (std::size_t i = 0; i < n; ++i) {
      if (rgba[4 * i + 3] != 255)
        return corrupt(fmt::format("colour {} has alpha {}, not 255", i, rgba[4 * i + 3]));
      std::memcpy(&mesh.colors[3 * i], &rgba[4 * i], 3);
    }
  }

  if (p.triangles[0] != kMeshoptIndexStreamHeader) {
    return corrupt("the triangles stream is not a version-1 meshoptimizer index buffer");
  }
  mesh.triangles.resize(3 * std::size_t{p.triangle_count});
  if (const int rc = meshopt_decodeIndexBuffer(mesh.triangles.data(), mesh.triangles.size(), 4,
                                               p.triangles.data(), p.triangles.size())) {
    return corrupt(fmt::format("the triangles stream does not decode (meshoptimizer error {})", rc));
  }
  for (std::size_t c = 0; c < mesh.triangles.size(); ++c) {
    if (mesh.triangles[c] >= n) {
      return corrupt(fmt::format("triangle {} names vertex {} of {}", c / 3, mesh.triangles[c], n));
    }
  }
  return out;
}

}  // namespace mtlod::core::codec

// libFuzzer target: any bytes given to the meshoptimizer payload decoder are refused (kCorrupt or
// kUnsupported) or decode to a mesh that stays inside its own header: indices below the vertex count,
// finite positions on the header's grid, unit normals, and the header's counts.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>

#include "core/codec/meshopt_decode.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace mtlod::core;
  const auto decoded = codec::decode_meshopt(std::span<const std::uint8_t>(data, size));
  if (!decoded.ok()) {
    if (decoded.error().code != mtlod::ErrorCode::kCorrupt &&
        decoded.error().code != mtlod::ErrorCode::kUnsupported)
      __builtin_trap();
    return 0;
  }
  const model::Mesh& mesh = decoded->mesh;
  const std::size_t vertices = mesh.vertex_count();
  for (const std::uint32_t v : mesh.triangles)
    if (v >= vertices) __builtin_trap();
  for (const float p : mesh.positions)
    if (!std::isfinite(p)) __builtin_trap();
  if (!mesh.normals.empty()) {
    if (mesh.normals.size() != mesh.positions.size()) __builtin_trap();
    for (std::size_t v = 0; v < vertices; ++v) {
      const float* n = &mesh.normals[3 * v];
      if (!(std::fabs(n[0] * n[0] + n[1] * n[1] + n[2] * n[2] - 1.0f) < 1e-3f)) __builtin_trap();
    }
  }
  if (!mesh.colors.empty() && mesh.colors.size() != mesh.positions.size()) __builtin_trap();
  return 0;
}

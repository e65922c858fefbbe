// Binary glTF 2.0 (.glb) output of a mesh, for tools that hand cuts to other 3D software: one scene,
// one node, one triangle primitive with POSITION, and NORMAL and COLOR_0 when the mesh has them.
// Either the arrays are stored plainly, or a Draco payload is embedded unchanged under the
// KHR_draco_mesh_compression extension (no uncompressed fallback, so the extension is required).
// The JSON side goes through tinygltf inside gltf.cpp; callers see meshes and byte spans only.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>

#include "core/model/mesh.hpp"
#include "core/result.hpp"

namespace mtlod::core::io {

// Writes `mesh` as .glb with plain accessors: float32 positions, float32 normals scaled to unit
// length (glTF requires it; a zero or non-finite normal, which has no direction, becomes +Z),
// colours as normalised uint8 RGB (the bytes as they are), uint32 indices. Errors: kInvalidArgument
// for a mesh without triangles, an index out of range or a non-finite position; kIoError naming the
// path when it cannot be written.
Status write_glb(const std::filesystem::path& path, const model::Mesh& mesh);

// Writes a Draco triangle mesh (as DracoEncoder or the server produces it) as .glb: the bytes are the
// buffer, unchanged, and the accessors describe what they decode to (counts, position bounds; normals
// and colours when the payload has them; a label attribute is left out, glTF has no meaning for it).
// Errors: kCorrupt when the bytes do not decode, kInvalidArgument without triangles, kIoError as above.
Status write_glb_draco(const std::filesystem::path& path, std::span<const std::uint8_t> draco);

}  // namespace mtlod::core::io

// Binary glTF 2.0 (.glb) output of a mesh, for tools that hand cuts to other 3D software: one scene,
// one node, one triangle primitive with POSITION, and NORMAL and COLOR_0 when the mesh has them.
// Either the arrays are stored plainly, or a payload is embedded unchanged under its extension: Draco
// under KHR_draco_mesh_compression, meshopt's streams under EXT_meshopt_compression with
// KHR_mesh_quantization (no uncompressed fallback, so the extensions are required).
// The JSON side goes through tinygltf inside gltf.cpp; callers see meshes and byte spans only.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>

#include "core/codec/cut_encoder.hpp"
#include "core/model/mesh.hpp"
#include "core/result.hpp"

namespace mtlod::core::io {

// Writes `mesh` as .glb with plain accessors: float32 positions, float32 normals scaled to unit
// length (glTF requires it; a zero or non-finite normal, which has no direction, becomes +Z),
// colours as normalised uint8 RGB (the bytes as they are), uint32 indices. Errors: kInvalidArgument
// for a mesh without triangles, an index out of range or a non-finite position; kIoError naming the
// path when it cannot be written.
Status write_glb(const std::filesystem::path& path, const model::Mesh& mesh);

// One node of a scene: its mesh (model coordinates) and the column-major matrix placing it.
struct GlbInstance {
  const model::Mesh* mesh = nullptr;
  std::array<double, 16> matrix{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  std::string name;
};

// Writes a scene as .glb: a node per instance with its matrix and name, each with its own mesh
// stored as write_glb stores one. Errors as write_glb's, naming the instance; kInvalidArgument for
// no instances.
Status write_glb_scene(const std::filesystem::path& path, std::span<const GlbInstance> instances);

// Writes a Draco triangle mesh (as DracoEncoder or the server produces it) as .glb: the bytes are the
// buffer, unchanged, and the accessors describe what they decode to (counts, position bounds; normals
// and colours when the payload has them; a label attribute is left out, glTF has no meaning for it).
// Errors: kCorrupt when the bytes do not decode, kInvalidArgument without triangles, kIoError as above.
Status write_glb_draco(const std::filesystem::path& path, std::span<const std::uint8_t> draco);

// Writes a meshopt payload (meshopt_encode.hpp's container, as MeshoptEncoder or the server produces
// it) as .glb: its streams, unchanged, are the buffer, each the compressed data of a view of an
// uncompressed fallback buffer that has no bytes: positions as uint16 (KHR_mesh_quantization) under
// a node whose translation and scale are the payload's origin and step, octahedral normals (filter
// OCTAHEDRAL) as normalized int8 or int16, colours as normalized uint8 and uint32 indices (mode
// TRIANGLES). Errors: kCorrupt when the payload does not decode, kIoError as above.
Status write_glb_meshopt(const std::filesystem::path& path, std::span<const std::uint8_t> payload);

// The writer above for `codec`'s payload.
Status write_glb_payload(const std::filesystem::path& path, codec::Codec codec,
                         std::span<const std::uint8_t> payload);

}  // namespace mtlod::core::io

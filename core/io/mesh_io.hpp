// Reading and writing meshes. The only place besides other core/io files that touches the file
// system. Readers go through OpenMesh's IOManager (PLY ASCII/binary, OBJ, OFF, STL) with an importer
// that fills flat arrays directly, so non-manifold scans arrive face for face.
#pragma once

#include <filesystem>

#include "core/model/mesh.hpp"
#include "core/model/mesh_cleanup.hpp"
#include "core/result.hpp"

namespace mtlod::core::io {

struct LoadOptions {
  bool clean = true;  // run clean_mesh (welding is forced on for STL)
  model::CleanupOptions cleanup = {};
};

struct LoadedMesh {
  model::Mesh mesh;
  model::TopologyReport input_topology;   // of the file as read, before clean-up
  model::CleanupSummary cleanup;          // what clean-up changed
  std::size_t polygons_triangulated = 0;  // input faces with more than three corners
};

// Errors name the file and the problem: missing, unreadable, empty, unknown format, truncated,
// index out of range, non-finite coordinates.
Result<LoadedMesh> load_mesh(const std::filesystem::path& path, const LoadOptions& options = {});

// Writes binary little-endian PLY (positions, normals and colours when present) or OBJ, by extension
// (.ply, .obj). OBJ keeps float32 positions exactly (shortest round-trip decimals).
Status save_mesh(const std::filesystem::path& path, const model::Mesh& mesh);

}  // namespace mtlod::core::io

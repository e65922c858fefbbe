// The out-of-core MT build (design: core/build/LARGE_BUILD.md): a PLY file of any size to an .mt file
// whose memory is bounded by a limit, not by the model. The input is read in one streaming pass,
// split into spatial blocks that are simplified with their borders locked and merged pairwise
// level by level, and the MT is assembled from temporary files into the output. The input is cleaned
// as load_mesh cleans it (degenerate and duplicate triangles and unused vertices dropped), and the
// result is an MT like build_mt's (same collapses, same global errors, same file format): with one
// block, the file mtlod-build writes from the same input in memory, byte for byte.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <vector>

#include "core/build/mt_builder.hpp"
#include "core/io/memory_limit.hpp"
#include "core/result.hpp"

namespace mtlod::core::build {

// Called with a phase's name and the fraction of that phase done.
using LargeBuildProgressFn = void (*)(void* user, const char* phase, double fraction);

struct LargeBuildOptions {
  // Collapse rules and min_triangles as for build_mt (its progress callback is not used). With
  // parallel_for set, the blocks of a level are simplified side by side, `threads` at a time.
  BuildOptions build;
  std::size_t threads = 1;
  std::uint64_t memory_limit = 0;   // bytes; 0: default_memory_limit() (memory_limit.hpp)
  std::size_t block_triangles = 0;  // faces per leaf block; 0: the most memory_limit allows
  std::filesystem::path temp_dir;   // where temporary files go; empty: beside the output
  LargeBuildProgressFn progress = nullptr;
  void* progress_user = nullptr;
  // When not null, receives the MT id of every input vertex, kNoVertex for those no kept triangle
  // uses (left out of the file). 4 bytes per vertex: for tests and small models.
  std::vector<std::uint32_t>* vertex_ids = nullptr;
};

struct LargeBuildStats {
  std::uint64_t vertices = 0;
  std::uint64_t input_triangles = 0;     // after triangulating polygons, before dropping any
  std::uint64_t dropped_degenerate = 0;  // a repeated vertex id or zero area
  std::uint64_t dropped_duplicate = 0;   // the same vertex set as an earlier triangle
  std::uint64_t polygons_triangulated = 0;
  std::size_t block_triangles = 0;
  std::size_t blocks = 0;  // leaves
  std::size_t stages = 0;  // simplifications run: leaves and merges
  std::size_t levels = 0;
  std::size_t complex_vertices = 0;    // never collapsed: non-manifold fans (summed over stages)
  std::size_t topology_collapses = 0;  // as in BuildStats (the root stage's)
  float topology_error = std::numeric_limits<float>::infinity();
  std::size_t stacking_collapses = 0;  // likewise
  float stacking_error = std::numeric_limits<float>::infinity();
  bool normals_given = false;          // the PLY has normals
  std::uint64_t normals_computed = 0;  // vertices whose normal was computed (missing, NaN or zero)
  std::uint64_t nodes = 0;
  std::uint64_t mt_triangles = 0;
  std::uint64_t root_triangles = 0;
  float max_error = 0;
  std::uint64_t file_bytes = 0;
  std::uint64_t temp_bytes = 0;  // the most the temporary files held at once
};

// Builds the MT of the PLY file input into output (replaced). Errors name the file and the problem:
// the reader's, a non-finite coordinate, a memory limit too small for the vertex count, counts over
// 32-bit ids, and temporary files that cannot be written.
Status build_mt_file(const std::filesystem::path& input, const std::filesystem::path& output,
                     const LargeBuildOptions& options, LargeBuildStats* stats = nullptr);

}  // namespace mtlod::core::build

// Builds a Multi-Tessellation from an indexed triangle mesh (DESIGN.md §2): half-edge collapses
// (never new vertices) ordered by quadric error, recorded fine → coarse, stored coarse → fine as MT
// nodes with a global error per node in model units.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/mesh.hpp"
#include "core/mt.hpp"
#include "core/result.hpp"

namespace mtlod::core {

// Called between passes with the fraction of the work done in [0, 1]. No I/O happens in core; the
// tool draws the bar.
using BuildProgressFn = void (*)(void* user, double fraction);

// Calls task(context, i) for every i in [0, count), possibly concurrently, and returns when all
// calls have finished. core starts no threads: a caller with cores to spare passes its own runner.
using ParallelForFn = void (*)(void* user, std::size_t count, void (*task)(void* context, std::size_t i),
                               void* context);

struct BuildOptions {
  // Share of each pass's candidate collapses (cheapest first) that is attempted before the next
  // pass re-sorts. Smaller follows the quadric order more closely but takes more passes. (On the
  // shared scans, 0.5 gives cuts within a few percent of 0.3's error at equal triangle count, in
  // 41 passes instead of 48 on the 871k dragon; tests/bench/BENCHMARKS.md, "MT build and refinement".)
  float pass_fraction = 0.5f;
  // A collapse is refused when a surviving triangle's normal turns by more than acos(min_normal_cos).
  float min_normal_cos = 0.2f;
  // Weight of the planes that hold boundary edges in place, relative to the triangles' planes.
  float boundary_weight = 2.0f;
  // Stop when the working mesh has at most this many triangles (0: collapse while any collapse is valid).
  std::size_t min_triangles = 0;
  BuildProgressFn progress = nullptr;
  void* progress_user = nullptr;
  // Runs the independent work of each pass (vertex classification, partner search, the collapses
  // chosen for the pass) in chunks; null runs them in turn. The MT is the same either way.
  ParallelForFn parallel_for = nullptr;
  void* parallel_user = nullptr;
};

struct BuildStats {
  std::size_t input_triangles = 0;
  std::size_t root_triangles = 0;
  std::size_t nodes = 0;         // including the root
  std::size_t mt_triangles = 0;  // all triangles of all nodes
  std::size_t passes = 0;
  std::size_t complex_vertices = 0;  // never collapsed: non-manifold or inconsistently oriented fans
  float max_error = 0.0f;            // largest node error, model units
};

// Builds the MT of mesh. Triangles with a repeated vertex id are kept unchanged (their vertices are
// never collapsed). Normals and colours are copied. Fails with kInvalidArgument on an index out of
// range or a non-finite coordinate, or with kLimitExceeded when counts do not fit 32-bit ids. An
// empty mesh gives an MT of one empty root. stats may be null.
//
// The MT numbers the vertices in its own order (core/mt.hpp); vertex_ids, when not null, receives
// the MT id of every input vertex.
Result<Mt> build_mt(const Mesh& mesh, const BuildOptions& options = {}, BuildStats* stats = nullptr,
                    std::vector<std::uint32_t>* vertex_ids = nullptr);

}  // namespace mtlod::core

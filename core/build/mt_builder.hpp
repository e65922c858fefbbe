// Builds an MT from an indexed triangle mesh (core/ARCHITECTURE.md §2.6): half-edge collapses
// (never new vertices) ordered by quadric error, recorded fine → coarse, stored coarse → fine as MT
// nodes with a global error per node in model units.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "core/model/mesh.hpp"
#include "core/model/mt.hpp"
#include "core/result.hpp"
#include "core/util/grow_only_vector.hpp"

namespace mtlod::core::build {

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
  // Once no collapse that keeps the topology is valid (closed components down to tetrahedra, holes
  // down to triangles, vertices at non-manifold edges or clashing orientations), go on with
  // collapses that may change it: no link condition, and any vertex whose edges all have an even
  // number of faces may collapse into any neighbour (a vertex with an odd edge only into another
  // such vertex, so a cut's boundary and non-manifold edges stay on vertices of the input's). Each
  // such collapse still replaces its faces by faces with the same outline (no crack), passes the
  // normal and degeneracy checks and records its measured error, so a cut changes the topology only
  // where its error allows it: scans with many components, holes or non-manifold edges get small
  // roots. Its last stage also lets a new face repeat one its target has (BuildStats::
  // stacking_collapses): stacked sheets of a scan then still simplify.
  bool coarse_topology = true;
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
  bool normals_given = false;        // the mesh came with normals
  std::size_t normals_computed = 0;  // vertices whose normal was computed (missing, NaN or zero)
  float max_error = 0.0f;            // largest node error, model units
  // Collapses of the coarse_topology phase, and the smallest of their errors (infinity when there
  // are none): a cut to any uniform error below it refines all their nodes and so has the input's
  // topology.
  std::size_t topology_collapses = 0;
  float topology_error = std::numeric_limits<float>::infinity();
  // Of those, the collapses of the phase's last stage, which may leave two faces on the same three
  // vertices (no face, counted mod 2), and the smallest of their errors: cuts to a uniform error
  // below it have no such pair.
  std::size_t stacking_collapses = 0;
  float stacking_error = std::numeric_limits<float>::infinity();
};

// Builds the MT of mesh. Triangles with a repeated vertex id are kept unchanged (their vertices are
// never collapsed). Colours are copied; normals too, made unit length, and computed
// (core/build/vertex_normals.hpp) where the mesh has none or they are not finite or are zero-length.
// Fails with kInvalidArgument on an index out of range or a non-finite coordinate, or with
// kLimitExceeded when counts do not fit 32-bit ids. An empty mesh gives an MT of one empty root.
// stats may be null.
//
// The MT numbers the vertices in its own order (core/model/mt.hpp); vertex_ids, when not null, receives
// the MT id of every input vertex.
Result<model::Mt> build_mt(const model::Mesh& mesh, const BuildOptions& options = {},
                           BuildStats* stats = nullptr, std::vector<std::uint32_t>* vertex_ids = nullptr);

// The MT node of each collapse, given the collapses' errors in the order they were made (fine →
// coarse): nodes by decreasing error, ties by reverse collapse order. This is a topological order
// (a parent's error is at least its child's, and on a tie the parent collapsed later), and it makes
// the static cut for a uniform threshold e a prefix: the root and every node with error > e.
std::vector<std::uint32_t> number_nodes(std::span<const float> collapse_error);

// One block of an out-of-core build (core/build/large_build.hpp, core/build/LARGE_BUILD.md): a part of
// the working mesh, simplified by the same collapses as build_mt with its border vertices locked,
// starting from the state earlier blocks left its faces in.
struct BlockInput {
  model::Mesh mesh;                        // the block's faces over its own vertex ids
  std::vector<std::uint8_t> locked;        // per vertex, 1: never collapsed and never a collapse's target
  std::vector<float> face_error;           // per face, the error of the collapse that made it; empty: 0
  std::vector<std::uint32_t> face_points;  // per face, how many removed input vertices it carries
  util::GrowOnlyVector<float> points;      // their positions (x, y, z), face after face; empty: none
};

// The simplification sequence of one block and the state it leaves. The block's input faces are its
// triangles 0 … F−1, and the collapses make triangles F, F+1, … in order. A collapse is named by
// its tag, its index + 1 (0: none). In MT terms collapse c's node removes the triangles c made and
// creates those c took away.
struct BlockOutput {
  std::vector<std::uint32_t> collapse_u;      // the vertex each collapse removed (block ids)
  std::vector<float> collapse_error;          // global error of each collapse, model units
  std::vector<std::uint32_t> made_triangles;  // 3 block vertex ids per triangle the collapses made
  std::vector<std::uint32_t> made_by;         // per made triangle, the tag of the collapse that made it
  std::vector<std::uint32_t> taken_by;        // per triangle (input, then made), the tag that took it away
  // The faces left, as triangle indices, with their errors and carried points (as in BlockInput).
  std::vector<std::uint32_t> remaining;
  std::vector<float> remaining_error;
  std::vector<std::uint32_t> remaining_points;
  util::GrowOnlyVector<float> points;
  std::size_t passes = 0;
  std::size_t complex_vertices = 0;
  std::size_t topology_collapses = 0;  // as in BuildStats
  float topology_error = std::numeric_limits<float>::infinity();
  std::size_t stacking_collapses = 0;
  float stacking_error = std::numeric_limits<float>::infinity();
};

// Simplifies input until at most target_triangles faces remain or no collapse is valid
// (options.min_triangles is not used). Fails as build_mt does, and with kInvalidArgument when the
// block's arrays do not match its mesh. The points move into the builder and on to the output: a
// block near the top of a large build carries most of the model's removed vertices.
Result<BlockOutput> simplify_block(BlockInput&& input, std::size_t target_triangles,
                                   const BuildOptions& options = {});

}  // namespace mtlod::core::build

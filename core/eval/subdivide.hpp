// Scan-like meshes of any size from a real scan: every triangle split regularly into n² triangles,
// and every vertex displaced along a smooth interpolated normal by smooth 3-D value noise, so the
// result has the scan's shape, holes, pieces and defects with scanner-like roughness instead of flat
// facets. Input for the out-of-core builder's benchmarks (the shared meshes' README suggests
// subdividing the 871k dragon, since no real scan of 1M+ triangles is available to us).
//
// The output is streamed: vertices, then triangles, in chunks handed to a sink, with every id
// computed arithmetically, so memory depends on the base mesh and the chunk sizes, never on n.
// Output vertex ids, for V base vertices, E base edges (unordered vertex-id pairs, numbered in order
// of first use, face by face) and F base triangles, m = (n−1)(n−2)/2:
//   [0, V)                            the base vertices, in order
//   V + e·(n−1) + i, i < n−1          the cuts of edge e, from its endpoint with the smaller position
//                                     (lexicographic x, y, z; ties by id) towards the other
//   V + E·(n−1) + f·m + k, k < m      the interior of triangle f
// Output triangles f·n² .. (f+1)·n²−1 tile base triangle f and keep its orientation.
//
// Nothing is welded or repaired: an edge is shared only by the triangles that share its two vertex
// ids, so boundaries, non-manifold edges, separate components and duplicate positions all carry over.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/model/mesh.hpp"
#include "core/result.hpp"

namespace mtlod::core::eval {

struct SubdivideOptions {
  std::uint32_t split = 2;  // n ≥ 1: every edge cut into n equal segments, n² triangles per triangle
  // Displacement amplitude in mean base edge lengths (the bound on every vertex's displacement);
  // 0 leaves every vertex on its base triangle.
  float noise = 0.0f;
  float wavelength = 1.0f;  // lattice spacing of the coarsest noise octave, in mean base edge lengths
  std::uint32_t seed = 1;   // noise phase: same seed, same output
  std::size_t chunk_vertices = 1 << 16;   // at most this many vertices per sink call
  std::size_t chunk_triangles = 1 << 16;  // at most this many triangles per sink call
};

// Sizes of the base and of the output, known before any output is produced.
struct SubdivisionCounts {
  std::uint64_t base_vertices = 0;
  std::uint64_t base_edges = 0;  // distinct unordered vertex-id pairs of the triangles
  std::uint64_t base_triangles = 0;
  std::uint64_t vertices = 0;   // V + E·(n−1) + F·(n−1)(n−2)/2
  std::uint64_t triangles = 0;  // F·n²
};

// Receives the output: every vertex chunk, in id order, then every triangle chunk, in order.
// A failed Status stops the generation and is returned by Subdivider::run.
class SubdivisionSink {
 public:
  virtual ~SubdivisionSink() = default;
  // positions: x, y, z per vertex; colors: r, g, b per vertex when the base has colours, else empty.
  virtual Status vertices(std::span<const float> positions, std::span<const std::uint8_t> colors) = 0;
  // Three vertex ids per triangle.
  virtual Status triangles(std::span<const std::uint32_t> triangles) = 0;
};

// Holds what the generation needs of the base mesh: its edge table (three edge ids per triangle and
// two endpoints per edge), a unit normal per vertex and the noise scale. Normals are the base's own
// or, when it has none, area-weighted face normals; either way they are summed over vertices with
// the same exact position, so that duplicate vertices move together and a crack between pieces
// that meet stays closed. Output vertices between base vertices take interpolated normals (and
// interpolated colours when the base has colours); the output has no normals.
class Subdivider {
 public:
  // The largest output vertex count: ids are 32-bit.
  static constexpr std::uint64_t kMaxVertices = UINT32_MAX;

  // base must outlive the Subdivider. Its triangles may be degenerate or repeated; its vertex ids
  // must be in range. options.split ≥ 1 and chunk sizes ≥ 1.
  Subdivider(const model::Mesh& base, const SubdivideOptions& options);

  const SubdivisionCounts& counts() const { return counts_; }
  // Whether the output's vertex ids fit in 32 bits (run requires it).
  bool fits() const { return counts_.vertices <= kMaxVertices; }
  bool has_colors() const { return base_.has_colors(); }
  // Mean length of the base edges (each counted once), in model units; 0 without triangles.
  double mean_edge_length() const { return mean_edge_length_; }
  // The displacement bound in model units: options.noise × mean_edge_length().
  double amplitude() const { return amplitude_; }

  // Streams the whole output into sink; the same output on every call. Returns the sink's first
  // error, if any.
  Status run(SubdivisionSink& sink) const;

 private:
  // Adds the displacement of flat point p with (not necessarily unit) normal n.
  void displace(float p[3], const float n[3]) const;
  // The constructor's steps: the edge table, the mean edge length and noise scale, unit normals.
  void number_edges();
  void measure_edges();
  void compute_normals();
  // run's two parts: the vertices (base, then edge cuts, then face interiors), then the triangles.
  Status stream_vertices(SubdivisionSink& sink) const;
  Status stream_triangles(SubdivisionSink& sink) const;

  const model::Mesh& base_;
  SubdivideOptions options_;
  SubdivisionCounts counts_;
  std::vector<std::uint32_t> triangle_edges_;  // three edge ids per triangle: edges v0v1, v1v2, v2v0
  std::vector<std::uint32_t> edge_vertices_;   // two per edge: the cuts run from the first to the second
  std::vector<float> normals_;                 // unit, or zero for a vertex with no normal
  double mean_edge_length_ = 0.0;
  double amplitude_ = 0.0;
  double noise_frequency_ = 0.0;  // coarsest octave's lattice cells per model unit
};

// The whole output in memory, for tests and small meshes. Requires Subdivider(base, options).fits().
model::Mesh subdivide(const model::Mesh& base, const SubdivideOptions& options);

}  // namespace mtlod::core::eval

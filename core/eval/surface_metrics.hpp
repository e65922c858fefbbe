// Object-space error between a mesh and a simplification of it, in the manner of Metro (Cignoni,
// Rocchini and Scopigno 1998) and of the MESH tool (Aspert, Santa-Cruz and Ebrahimi 2002) that the
// silhouette paper cites for its figure 5 (papers/000 §4): dense samples on one surface, the exact
// distance of each sample to the nearest triangle of the other surface, and from those the one-sided
// maximum (Hausdorff), mean and RMS; the symmetric values take the worse of both directions.
// A uniform grid over the triangles answers the nearest-triangle queries, so the 871k dragon against
// a cut runs in seconds. A triangle mask restricts the samples (the error inside a focus region).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace mtlod::core::eval {

// Samples on a surface: their positions and the triangle each lies on.
struct SurfaceSamples {
  std::vector<float> points;                // x, y, z per sample
  std::vector<std::uint32_t> triangle_ids;  // triangle of each sample

  std::size_t size() const { return triangle_ids.size(); }
};

struct SamplingOptions {
  // Points drawn uniformly by area (triangle chosen by area, then a uniform barycentric point).
  std::size_t area_samples = 100000;
  // Also take every corner of every triangle once (the removed vertices are where a simplification
  // usually deviates most, so Metro samples vertices too).
  bool include_vertices = true;
  std::uint64_t seed = 1;  // the same seed gives the same samples
};

// Samples the triangles of (positions, triangles) whose mask entry is non-zero (an empty mask takes
// all), writing into out (cleared first). Degenerate triangles get no area samples. Deterministic for a
// given seed. positions holds x, y, z per vertex; triangles three vertex ids per triangle, in range.
void sample_surface(std::span<const float> positions, std::span<const std::uint32_t> triangles,
                    std::span<const std::uint8_t> triangle_mask, const SamplingOptions& options,
                    SurfaceSamples& out);

// Exact distance from point p to triangle (a, b, c), any triangle including degenerate ones (the
// closest-point regions of Ericson, Real-Time Collision Detection §5.1.5), in double precision.
double point_triangle_distance(const double p[3], const double a[3], const double b[3], const double c[3]);

// Nearest-triangle queries over a fixed triangle mesh: a uniform grid of cubic cells (about twice the
// triangles' mean size, at most 8 cells per triangle), each triangle listed in every cell its bounding box
// overlaps (CSR). A query visits rings of cells around the query's cell until the ring is farther than the
// best distance found, so it is exact. Holds copies of nothing but the spans' data pointers: positions and
// triangles must outlive the index. Queries reuse scratch memory and are not thread-safe.
class TriangleIndex {
 public:
  TriangleIndex(std::span<const float> positions, std::span<const std::uint32_t> triangles);

  // Distance from (x, y, z) to the nearest triangle; +inf when the mesh has no triangle.
  double distance(float x, float y, float z);

  std::size_t triangle_count() const { return triangles_.size() / 3; }

 private:
  // Tests the triangles of cell (i, j, k) against p, updating best.
  void visit_cell(std::uint32_t i, std::uint32_t j, std::uint32_t k, const double p[3], double& best);

  std::span<const float> positions_;
  std::span<const std::uint32_t> triangles_;
  double origin_[3] = {0, 0, 0};
  double cell_size_ = 1.0;
  std::uint32_t dims_[3] = {1, 1, 1};
  std::vector<std::uint32_t> cell_offsets_;  // cell count + 1
  std::vector<std::uint32_t> cell_triangles_;
  std::vector<std::uint32_t> stamp_;  // per triangle: the query that last tested it
  std::uint32_t query_ = 0;
};

// Distances of a set of samples to a surface.
struct DistanceStats {
  double max = 0.0;  // the one-sided Hausdorff distance
  double mean = 0.0;
  double rms = 0.0;
  std::size_t samples = 0;
};

// Distance of every sample to the index's surface; per_sample (empty, or one entry per sample)
// receives each distance. No samples gives all zeros.
DistanceStats sample_distances(const SurfaceSamples& samples, TriangleIndex& to,
                               std::span<float> per_sample = {});

// The same over the samples whose triangle has a non-zero entry in triangle_mask (one entry per
// triangle of the sampled surface): the focus-restricted error.
DistanceStats sample_distances_masked(const SurfaceSamples& samples,
                                      std::span<const std::uint8_t> triangle_mask, TriangleIndex& to);

// Both directions and the symmetric values: Hausdorff = max of both maxima; mean and RMS are those of
// the worse direction (as Metro reports them).
struct SurfaceError {
  DistanceStats a_to_b;
  DistanceStats b_to_a;
  double hausdorff() const { return a_to_b.max > b_to_a.max ? a_to_b.max : b_to_a.max; }
  double rms() const { return a_to_b.rms > b_to_a.rms ? a_to_b.rms : b_to_a.rms; }
  double mean() const { return a_to_b.mean > b_to_a.mean ? a_to_b.mean : b_to_a.mean; }
};

// One-off symmetric comparison of meshes A and B (builds both indices and both sample sets).
SurfaceError compare_surfaces(std::span<const float> positions_a, std::span<const std::uint32_t> triangles_a,
                              std::span<const float> positions_b, std::span<const std::uint32_t> triangles_b,
                              const SamplingOptions& options = {});

}  // namespace mtlod::core::eval

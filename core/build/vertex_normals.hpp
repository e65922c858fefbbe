// Per-vertex normals of the original surface: what a viewer shades every cut with. Half-edge
// collapses keep the input's vertices, so a coarse triangle's corners are points of the original
// surface and carry its normals there; interpolated across the coarse triangle they shade it like
// the surface it stands for rather than like its own flat facet.
//
// A computed normal is the sum of the unit normals of the triangles around the vertex, each
// weighted by the triangle's angle at that vertex (Thürmer and Wüthrich 1998): unlike area
// weighting it does not lean towards the large triangles of an irregular scan, and unlike plain
// averaging it does not depend on how a fan is split into triangles.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "core/model/mt.hpp"
#include "core/result.hpp"

namespace mtlod::core::build {

// Sums normals triangle by triangle into per-vertex sums, then makes them unit vectors. The sums
// are fixed-point integers (2^-32 units): integer addition does not depend on order, so the
// normals are the same bit for bit whatever order, or how many threads, the triangles come in.
class NormalAccumulator {
 public:
  static constexpr double kScale = 4294967296.0;  // 2^32 units per 1; a vertex's sum stays below 2^31
  // positions: x, y, z per vertex; sums: 3 per vertex, zeroed by the caller.
  NormalAccumulator(std::span<const float> positions, std::span<std::int64_t> sums)
      : positions_(positions), sums_(sums) {}
  // Adds triangle (a, b, c), counter-clockwise; degenerate triangles add nothing.
  void add(std::uint32_t a, std::uint32_t b, std::uint32_t c) { add(a, b, c, 0, kAll, false); }
  // The same, safe while other threads add_concurrently() into the same sums.
  void add_concurrently(std::uint32_t a, std::uint32_t b, std::uint32_t c) { add(a, b, c, 0, kAll, true); }
  // Adds the triangle's share to those of its corners in [lo, hi) only: threads that each own a
  // range of vertices can all go over the same triangles without atomic additions, which cost
  // more than the arithmetic (each waits for its cache line).
  void add_within(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t lo, std::uint32_t hi) {
    add(a, b, c, lo, hi, false);
  }
  // Unit normals from the sums (3 floats per vertex); a vertex no triangle gave a direction
  // (isolated, or only degenerate triangles around it) gets +z. Returns how many got +z.
  static std::size_t finish(std::span<const std::int64_t> sums, std::span<float> normals);

 private:
  static constexpr std::uint32_t kAll = 0xffffffff;
  void add(std::uint32_t a, std::uint32_t b, std::uint32_t c, std::uint32_t lo, std::uint32_t hi,
           bool concurrently);
  std::span<const float> positions_;
  std::span<std::int64_t> sums_;
};

// The angle-weighted normals of a triangle mesh (3 floats per vertex).
std::vector<float> vertex_normals(std::span<const float> positions, std::span<const std::uint32_t> triangles);

// The angle-weighted normals of an MT's full-resolution mesh (the triangles no node removes), for
// MTs stored without normals. Reads every node block of a mapped MT, and fails (kCorrupt) on the
// first that fails its check.
Result<std::vector<float>> vertex_normals(const model::Mt& mt);

// Attaches computed normals (vertex_normals(mt)) to an MT stored without them; true when it did.
Result<bool> ensure_normals(model::Mt& mt);

// Whether a given normal can be kept: finite and not zero-length.
bool usable_normal(const float* n);
// Scales a usable normal to unit length (in double: no finite float overflows when squared, and
// none but zero squares to zero).
void make_unit(float* n);

// What repair_normals did.
struct NormalRepair {
  std::size_t computed = 0;  // vertices whose normal was computed (all of them when there were none)
  bool had_normals = false;  // the mesh came with normals
};

// Makes `normals` a unit normal per vertex of the mesh (positions, triangles): the given ones where
// they are finite and not zero-length, computed ones elsewhere (all of them when none are given or
// their count does not match).
NormalRepair repair_normals(std::vector<float>& normals, std::span<const float> positions,
                            std::span<const std::uint32_t> triangles);

}  // namespace mtlod::core::build

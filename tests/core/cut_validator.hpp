// Independent cut checks shared by the MT tests (core/ARCHITECTURE.md §2.3): conformity, topology
// against the input, triangle-set comparison, and the error bound by exact point–triangle distance.
// Nothing here uses the refiner's or the builder's code paths beyond the Mt arrays.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "core/model/mesh.hpp"
#include "core/model/mesh_cleanup.hpp"
#include "core/model/mt.hpp"

namespace mtlod::test {

// A triangle as a rotation-normalised triple (smallest id first, orientation kept).
inline std::array<std::uint32_t, 3> canonical(std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  if (b < a && b < c) return {b, c, a};
  if (c < a && c < b) return {c, a, b};
  return {a, b, c};
}

inline std::vector<std::array<std::uint32_t, 3>> triangle_set(std::span<const std::uint32_t> triangles) {
  std::vector<std::array<std::uint32_t, 3>> set;
  set.reserve(triangles.size() / 3);
  for (std::size_t i = 0; i + 2 < triangles.size(); i += 3)
    set.push_back(canonical(triangles[i], triangles[i + 1], triangles[i + 2]));
  std::sort(set.begin(), set.end());
  return set;
}

inline std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
  return a < b ? (std::uint64_t{a} << 32 | b) : (std::uint64_t{b} << 32 | a);
}

// Directed edges as (undirected key, forward flag), sorted by key: one pass groups each edge's uses.
inline std::vector<std::uint64_t> sorted_edge_uses(std::span<const std::uint32_t> triangles) {
  std::vector<std::uint64_t> uses;
  uses.reserve(triangles.size());
  for (std::size_t i = 0; i + 2 < triangles.size(); i += 3)
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = triangles[i + k], b = triangles[i + (k + 1) % 3];
      // Low bit of the packed pair is free: ids < 2^31 in every test mesh.
      uses.push_back(edge_key(a, b) << 1 | (a < b ? 1u : 0u));
    }
  std::sort(uses.begin(), uses.end());
  return uses;
}

// Undirected edges (sorted keys) that are non-manifold (> 2 faces) or walked twice the same way.
inline std::vector<std::uint64_t> defective_edges(std::span<const std::uint32_t> triangles) {
  const std::vector<std::uint64_t> uses = sorted_edge_uses(triangles);
  std::vector<std::uint64_t> bad;
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i, forward = 0;
    for (; j < uses.size() && (uses[j] >> 1) == (uses[i] >> 1); ++j) forward += uses[j] & 1;
    const std::size_t faces = j - i;
    if (faces > 2 || (faces == 2 && forward != 1)) bad.push_back(uses[i] >> 1);
    i = j;
  }
  return bad;
}

// Vertices on boundary edges (edges with exactly one face).
inline std::vector<std::uint8_t> boundary_vertices(std::size_t vertex_count,
                                                   std::span<const std::uint32_t> triangles) {
  const std::vector<std::uint64_t> uses = sorted_edge_uses(triangles);
  std::vector<std::uint8_t> on(vertex_count, 0);
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i;
    while (j < uses.size() && (uses[j] >> 1) == (uses[i] >> 1)) ++j;
    if (j - i == 1) {
      const std::uint64_t key = uses[i] >> 1;
      on[key >> 32] = on[key & 0xffffffffu] = 1;
    }
    i = j;
  }
  return on;
}

// Vertices on edges with an odd number of faces: boundary edges, and edges with three faces.
inline std::vector<std::uint8_t> odd_vertices(std::size_t vertex_count,
                                              std::span<const std::uint32_t> triangles) {
  const std::vector<std::uint64_t> uses = sorted_edge_uses(triangles);
  std::vector<std::uint8_t> on(vertex_count, 0);
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i;
    while (j < uses.size() && (uses[j] >> 1) == (uses[i] >> 1)) ++j;
    if ((j - i) % 2 == 1) {
      const std::uint64_t key = uses[i] >> 1;
      on[key >> 32] = on[key & 0xffffffffu] = 1;
    }
    i = j;
  }
  return on;
}

// The input of an MT, with the facts a cut is compared against.
struct CutReference {
  const core::model::Mesh* input = nullptr;
  core::model::TopologyReport topology;
  std::vector<std::uint64_t> defects;  // sorted undirected edge keys
  std::vector<std::uint8_t> boundary;
  std::vector<std::uint8_t> odd;
  std::vector<std::uint8_t> used;
  // The MT's coarse levels may change the topology (core::BuildOptions::coarse_topology): its cuts
  // are checked for conformity only.
  bool coarse_topology_changes = false;
  // Its coarsest levels may hold two faces on the same three vertices (core::BuildStats::
  // stacking_collapses): no face, counted mod 2, so they are allowed where this is set; the edge
  // parities below still count both.
  bool stacked_faces = false;
};

inline CutReference make_reference(const core::model::Mesh& input) {
  CutReference ref;
  ref.input = &input;
  ref.topology = core::model::analyze_topology(input.positions, input.triangles);
  ref.defects = defective_edges(input.triangles);
  ref.boundary = boundary_vertices(input.vertex_count(), input.triangles);
  ref.odd = odd_vertices(input.vertex_count(), input.triangles);
  ref.used.assign(input.vertex_count(), 0);
  for (const std::uint32_t v : input.triangles) ref.used[v] = 1;
  return ref;
}

// What every cut must be: whole triangles on used input vertices, none degenerate or repeated
// (repeats allowed where ref.stacked_faces).
// Fills t with the cut's topology for the callers' further checks.
inline ::testing::AssertionResult validate_triangles(const CutReference& ref,
                                                     std::span<const std::uint32_t> cut,
                                                     core::model::TopologyReport& t) {
  const std::size_t vertex_count = ref.input->vertex_count();
  if (cut.size() % 3 != 0)
    return ::testing::AssertionFailure() << "cut size " << cut.size() << " not a multiple of 3";
  for (std::size_t i = 0; i < cut.size(); ++i)
    if (cut[i] >= vertex_count || !ref.used[cut[i]])
      return ::testing::AssertionFailure()
             << "cut corner " << i << " = " << cut[i] << " is not a used input vertex";
  t = core::model::analyze_topology(ref.input->positions, cut);
  if (t.degenerate_triangles != 0)
    return ::testing::AssertionFailure() << t.degenerate_triangles << " degenerate triangles";
  if (t.duplicate_triangles != 0 && !ref.stacked_faces)
    return ::testing::AssertionFailure() << t.duplicate_triangles << " duplicate triangles";
  return ::testing::AssertionSuccess();
}

// A cut is conforming, whatever its topology: vertex ids are used input vertices; no degenerate or
// duplicate triangle (unless ref.stacked_faces); every edge with an odd number of faces (a boundary, or three
// faces) joins vertices that are on such an edge in the input. A crack or a T-junction inside the surface
// would leave an edge with one face between vertices that the input surrounds with faces.
inline ::testing::AssertionResult validate_conforming_cut(const CutReference& ref,
                                                          std::span<const std::uint32_t> cut) {
  const std::size_t vertex_count = ref.input->vertex_count();
  core::model::TopologyReport t;
  if (auto ok = validate_triangles(ref, cut, t); !ok) return ok;
  const std::vector<std::uint8_t> odd = odd_vertices(vertex_count, cut);
  for (std::size_t v = 0; v < vertex_count; ++v)
    if (odd[v] && !ref.odd[v])
      return ::testing::AssertionFailure()
             << "vertex " << v << " is on an edge with an odd number of faces in the cut, not in the input";
  return ::testing::AssertionSuccess();
}

// A cut is conforming and has the input's topology: vertex ids are used input vertices; no edge has
// more than two faces or two faces walking it the same way unless the input had that very defect;
// no degenerate or duplicate triangle; the boundary runs only through input boundary vertices (a
// crack or T-junction would put a boundary edge across the surface); Euler characteristic, boundary
// loops and components equal the input's; a closed manifold input gives a closed manifold cut.
// Where the reference says the MT's coarse levels change the topology, only validate_conforming_cut.
inline ::testing::AssertionResult validate_cut(const CutReference& ref, std::span<const std::uint32_t> cut) {
  if (ref.coarse_topology_changes) return validate_conforming_cut(ref, cut);
  const std::size_t vertex_count = ref.input->vertex_count();
  core::model::TopologyReport t;
  if (auto ok = validate_triangles(ref, cut, t); !ok) return ok;
  for (const std::uint64_t key : defective_edges(cut))
    if (!std::binary_search(ref.defects.begin(), ref.defects.end(), key))
      return ::testing::AssertionFailure() << "edge (" << (key >> 32) << ", " << (key & 0xffffffffu)
                                           << ") is non-manifold or inconsistently oriented in the cut only";
  const std::vector<std::uint8_t> boundary = boundary_vertices(vertex_count, cut);
  for (std::size_t v = 0; v < vertex_count; ++v)
    if (boundary[v] && !ref.boundary[v])
      return ::testing::AssertionFailure()
             << "vertex " << v << " is on the cut's boundary but inside the input";
  if (t.euler_characteristic != ref.topology.euler_characteristic)
    return ::testing::AssertionFailure() << "Euler characteristic " << t.euler_characteristic << ", input "
                                         << ref.topology.euler_characteristic;
  if (t.boundary_loops != ref.topology.boundary_loops)
    return ::testing::AssertionFailure()
           << "boundary loops " << t.boundary_loops << ", input " << ref.topology.boundary_loops;
  if (t.components != ref.topology.components)
    return ::testing::AssertionFailure()
           << "components " << t.components << ", input " << ref.topology.components;
  if (ref.topology.is_closed_manifold() && !t.is_closed_manifold())
    return ::testing::AssertionFailure() << "closed manifold input, cut is not: " << t.summary();
  return ::testing::AssertionSuccess();
}

// Exact squared distance from p to triangle abc (Ericson, Real-Time Collision Detection 5.1.5), in
// double precision.
inline double point_triangle_distance_squared(const double* p, const double* a, const double* b,
                                              const double* c) {
  auto sub = [](const double* x, const double* y) {
    return std::array<double, 3>{x[0] - y[0], x[1] - y[1], x[2] - y[2]};
  };
  auto dot = [](const std::array<double, 3>& x, const std::array<double, 3>& y) {
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
  };
  auto dist2 = [&](const std::array<double, 3>& q) {
    const double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
    return dx * dx + dy * dy + dz * dz;
  };
  const auto ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return dist2({a[0], a[1], a[2]});
  const auto bp = sub(p, b);
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return dist2({b[0], b[1], b[2]});
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double v = d1 / (d1 - d3);
    return dist2({a[0] + v * ab[0], a[1] + v * ab[1], a[2] + v * ab[2]});
  }
  const auto cp = sub(p, c);
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return dist2({c[0], c[1], c[2]});
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double w = d2 / (d2 - d6);
    return dist2({a[0] + w * ac[0], a[1] + w * ac[1], a[2] + w * ac[2]});
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return dist2({b[0] + w * (c[0] - b[0]), b[1] + w * (c[1] - b[1]), b[2] + w * (c[2] - b[2])});
  }
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  return dist2({a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w, a[2] + ab[2] * v + ac[2] * w});
}

// Every used input vertex i must lie within bound[i] of the cut's surface. Exact distances; a grid
// only skips triangles whose box, grown by the largest bound, cannot reach the point (so a skipped
// triangle is always farther than the bound). Returns the first violation.
inline ::testing::AssertionResult every_vertex_within(const core::model::Mesh& input,
                                                      std::span<const std::uint32_t> cut,
                                                      std::span<const double> bound) {
  const std::size_t vertex_count = input.vertex_count();
  std::vector<double> p(input.positions.begin(), input.positions.end());
  double reach = 0;
  for (std::size_t v = 0; v < vertex_count; ++v) reach = std::max(reach, bound[v]);
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (std::size_t v = 0; v < vertex_count; ++v)
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], p[3 * v + k]), hi[k] = std::max(hi[k], p[3 * v + k]);
  const std::size_t tris = cut.size() / 3;
  const int cells = std::max(1, std::min(64, int(std::cbrt(double(tris)) + 1)));
  double size[3];
  for (int k = 0; k < 3; ++k) size[k] = std::max((hi[k] - lo[k]) / cells, 1e-30);
  auto cell = [&](double x, int k) {
    return std::clamp(int(std::floor((x - lo[k]) / size[k])), 0, cells - 1);
  };
  std::vector<std::vector<std::uint32_t>> grid(std::size_t(cells) * cells * cells);
  for (std::size_t t = 0; t < tris; ++t) {
    int c0[3], c1[3];
    for (int k = 0; k < 3; ++k) {
      double a = 1e300, b = -1e300;
      for (int j = 0; j < 3; ++j)
        a = std::min(a, p[3 * cut[3 * t + j] + k]), b = std::max(b, p[3 * cut[3 * t + j] + k]);
      c0[k] = cell(a - reach, k), c1[k] = cell(b + reach, k);
    }
    for (int x = c0[0]; x <= c1[0]; ++x)
      for (int y = c0[1]; y <= c1[1]; ++y)
        for (int z = c0[2]; z <= c1[2]; ++z)
          grid[(std::size_t(x) * cells + y) * cells + z].push_back(std::uint32_t(t));
  }
  std::vector<std::uint8_t> used(vertex_count, 0);
  for (const std::uint32_t v : input.triangles) used[v] = 1;
  for (std::size_t v = 0; v < vertex_count; ++v) {
    if (!used[v]) continue;
    const double* q = &p[3 * v];
    const auto& list = grid[(std::size_t(cell(q[0], 0)) * cells + cell(q[1], 1)) * cells + cell(q[2], 2)];
    double best = 1e300;
    const double limit = bound[v] * bound[v];
    for (const std::uint32_t t : list) {
      best = std::min(best, point_triangle_distance_squared(q, &p[3 * cut[3 * t]], &p[3 * cut[3 * t + 1]],
                                                            &p[3 * cut[3 * t + 2]]));
      if (best <= limit) break;
    }
    if (!(best <= limit))
      return ::testing::AssertionFailure()
             << "vertex " << v << " is " << std::sqrt(best) << " from the cut, bound " << bound[v];
  }
  return ::testing::AssertionSuccess();
}

}  // namespace mtlod::test

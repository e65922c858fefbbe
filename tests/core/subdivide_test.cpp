// Streaming subdivision: the counts promised up front, exact ids on a hand-made triangle, every flat
// vertex on its base triangle, topology carried over (boundaries, non-manifold edges, components,
// Euler characteristic, cracks between duplicate vertices), bounded and seeded noise, chunking that
// does not change the output, and real scans' defects kept.
#include "core/eval/subdivide.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <iterator>
#include <map>
#include <set>
#include <utility>

#include "core/eval/mesh_gen.hpp"
#include "core/io/mesh_io.hpp"
#include "core/model/mesh_cleanup.hpp"
#include "tests/core/test_meshes.hpp"

namespace mtlod::core {
namespace {

using Vec = std::array<double, 3>;

Vec position(const model::Mesh& m, std::uint32_t v) {
  return {m.positions[3 * std::size_t{v}], m.positions[3 * std::size_t{v} + 1],
          m.positions[3 * std::size_t{v} + 2]};
}
Vec sub(const Vec& a, const Vec& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
double dot(const Vec& a, const Vec& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
Vec cross(const Vec& a, const Vec& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double norm(const Vec& a) {
  return std::sqrt(dot(a, a));
}

// Base edges as a set of unordered id pairs, independent of the subdivider's hash table.
std::set<std::pair<std::uint32_t, std::uint32_t>> edge_set(const model::Mesh& m) {
  std::set<std::pair<std::uint32_t, std::uint32_t>> edges;
  for (std::size_t t = 0; t < m.triangle_count(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = m.triangles[3 * t + k], b = m.triangles[3 * t + (k + 1) % 3];
      edges.emplace(std::min(a, b), std::max(a, b));
    }
  }
  return edges;
}

double mean_edge_length(const model::Mesh& m) {
  const auto edges = edge_set(m);
  double sum = 0.0;
  for (const auto& [a, b] : edges) sum += norm(sub(position(m, a), position(m, b)));
  return sum / static_cast<double>(edges.size());
}

double total_area(const model::Mesh& m) {
  double sum = 0.0;
  for (std::size_t t = 0; t < m.triangle_count(); ++t) {
    const Vec a = position(m, m.triangles[3 * t]);
    sum += 0.5 * norm(cross(sub(position(m, m.triangles[3 * t + 1]), a),
                            sub(position(m, m.triangles[3 * t + 2]), a)));
  }
  return sum;
}

model::Mesh generate(eval::Shape shape, std::size_t triangles, float noise = 0.05f) {
  eval::GenerateOptions o;
  o.shape = shape;
  o.target_triangles = triangles;
  o.noise = noise;
  return eval::generate_mesh(o);
}

model::Mesh split(const model::Mesh& base, std::uint32_t n, float noise = 0.0f, std::uint32_t seed = 1) {
  eval::SubdivideOptions o;
  o.split = n;
  o.noise = noise;
  o.seed = seed;
  return eval::subdivide(base, o);
}

// Three triangles on the edge 0–1, a fin: one non-manifold edge, six boundary edges.
model::Mesh fin() {
  model::Mesh m;
  m.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0.5f, 0.3f, 1};
  m.triangles = {0, 1, 2, 1, 0, 3, 0, 1, 4};
  return m;
}

// The unit square's two triangles without shared ids, folded along the diagonal (corner 3 lifted):
// 4 and 5 are copies of corners 2 and 0, so the diagonal is a closed crack between two components
// whose faces, hence per-piece normals, differ. The copies' ids run against the originals' (4 < 5
// but 4 sits at 2's place) to catch cuts ordered by id instead of position.
model::Mesh cracked_square() {
  model::Mesh m;
  m.positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0.5f, 1, 1, 0, 0, 0, 0};
  m.triangles = {0, 1, 2, 5, 4, 3};
  return m;
}

TEST(Subdivide, CountsMatchTheFormulas) {
  const model::Mesh bases[] = {test::tetrahedron(), test::square(), fin(),
                               generate(eval::Shape::kTerrain, 500), generate(eval::Shape::kSphere, 700)};
  for (const model::Mesh& base : bases) {
    const std::uint64_t v = base.vertex_count(), e = edge_set(base).size(), f = base.triangle_count();
    for (std::uint64_t n : {1u, 2u, 3u, 5u, 8u}) {
      SCOPED_TRACE(testing::Message() << "V " << v << " split " << n);
      eval::SubdivideOptions options;
      options.split = static_cast<std::uint32_t>(n);
      const eval::Subdivider subdivider(base, options);
      const std::uint64_t interior = n >= 2 ? (n - 1) * (n - 2) / 2 : 0;
      EXPECT_EQ(subdivider.counts().base_edges, e);
      EXPECT_EQ(subdivider.counts().vertices, v + e * (n - 1) + f * interior);
      EXPECT_EQ(subdivider.counts().triangles, f * n * n);
      const model::Mesh out = eval::subdivide(base, options);
      EXPECT_EQ(out.vertex_count(), subdivider.counts().vertices);
      EXPECT_EQ(out.triangle_count(), subdivider.counts().triangles);
      EXPECT_FALSE(out.has_colors());
      EXPECT_FALSE(out.has_normals());
    }
  }
}

TEST(Subdivide, TriangleSplitInFourHasTheDocumentedIds) {
  // Edges in order of first use: 0–1, 1–2, 2–0. Each is cut from its lexicographically smaller
  // end: 0–1 from 0, 1–2 from 2 (x = 0 < 2), 2–0 from 0; with n = 2 each gets one midpoint.
  model::Mesh base;
  base.positions = {0, 0, 0, 2, 0, 0, 0, 2, 0};
  base.triangles = {0, 1, 2};
  const model::Mesh out = split(base, 2);
  EXPECT_EQ(out.positions, (std::vector<float>{0, 0, 0, 2, 0, 0, 0, 2, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}));
  // Corner 0, the inverted middle, corner 1, corner 2; all counter-clockwise like the base.
  EXPECT_EQ(out.triangles, (std::vector<std::uint32_t>{0, 3, 5, 3, 4, 5, 3, 1, 4, 5, 4, 2}));
}

TEST(Subdivide, ReversedTriangleReusesTheCutsInReverse) {
  // The square's triangles 0 1 2 and 0 2 3 walk the diagonal 2–0 and 0–2. It is the third edge
  // used, so with n = 3 its cuts are 4 + 2·2 = 8 and 9, and both triangles must use exactly those.
  const std::uint32_t n = 3;
  const model::Mesh out = split(test::square(), n);
  std::set<std::uint32_t> first(out.triangles.begin(), out.triangles.begin() + 3 * n * n);
  std::set<std::uint32_t> second(out.triangles.begin() + 3 * n * n, out.triangles.end());
  std::vector<std::uint32_t> shared;
  std::set_intersection(first.begin(), first.end(), second.begin(), second.end(), std::back_inserter(shared));
  EXPECT_EQ(shared, (std::vector<std::uint32_t>{0, 2, 8, 9}));
  const model::TopologyReport r = model::analyze_topology(out.positions, out.triangles);
  EXPECT_EQ(r.boundary_edges, 4 * n);
  EXPECT_EQ(r.inconsistent_edges, 0u);
  EXPECT_EQ(r.duplicate_positions, 0u);
}

TEST(Subdivide, FlatSplitKeepsEveryVertexOnItsBaseTriangleAndTheArea) {
  const model::Mesh bases[] = {test::tetrahedron(), fin(), generate(eval::Shape::kTerrain, 800),
                               generate(eval::Shape::kShell, 1500)};
  for (const model::Mesh& base : bases) {
    for (std::uint32_t n : {2u, 3u, 7u}) {
      SCOPED_TRACE(testing::Message() << "V " << base.vertex_count() << " split " << n);
      const model::Mesh out = split(base, n);
      // float32 coordinates of these unit-sized meshes round at about 1e-7, which is a few 1e-6
      // of their shortest base edges in barycentric terms.
      constexpr double kBarycentricSlack = 1e-4, kPlaneSlack = 1e-6;
      for (std::size_t t = 0; t < out.triangle_count(); ++t) {
        const std::size_t f = t / (std::size_t{n} * n);  // output triangles tile base triangles in order
        const Vec a = position(base, base.triangles[3 * f]);
        const Vec ab = sub(position(base, base.triangles[3 * f + 1]), a);
        const Vec ac = sub(position(base, base.triangles[3 * f + 2]), a);
        const Vec normal = cross(ab, ac);
        const double area2 = dot(normal, normal);
        ASSERT_GT(area2, 0.0);
        for (int k = 0; k < 3; ++k) {
          const Vec q = sub(position(out, out.triangles[3 * t + k]), a);
          const double beta = dot(cross(q, ac), normal) / area2, gamma = dot(cross(ab, q), normal) / area2;
          ASSERT_GE(beta, -kBarycentricSlack);
          ASSERT_GE(gamma, -kBarycentricSlack);
          ASSERT_LE(beta + gamma, 1.0 + kBarycentricSlack);
          ASSERT_LE(std::abs(dot(q, normal)) / std::sqrt(area2), kPlaneSlack);
        }
        // Orientation follows the base triangle.
        const Vec p = position(out, out.triangles[3 * t]);
        const Vec sub_normal = cross(sub(position(out, out.triangles[3 * t + 1]), p),
                                     sub(position(out, out.triangles[3 * t + 2]), p));
        ASSERT_GT(dot(sub_normal, normal), 0.0);
      }
      // Summed in double over float32 corners: relative rounding well under 1e-5.
      EXPECT_NEAR(total_area(out), total_area(base), 1e-5 * total_area(base));
    }
  }
}

// The invariants of a split of a base without duplicate or repeated-id triangles: every base edge
// becomes n edges of the same kind, and V − E + F is unchanged (ΔV = E(n−1) + F(n−1)(n−2)/2,
// ΔE = E(n−1) + 3F·n(n−1)/2, ΔF = F(n²−1) cancel).
void expect_topology_carried_over(const model::Mesh& base, const model::Mesh& out, std::uint32_t n) {
  const model::TopologyReport b = model::analyze_topology(base.positions, base.triangles);
  const model::TopologyReport r = model::analyze_topology(out.positions, out.triangles);
  EXPECT_EQ(r.boundary_edges, n * b.boundary_edges);
  EXPECT_EQ(r.non_manifold_edges, n * b.non_manifold_edges);
  EXPECT_EQ(r.inconsistent_edges, n * b.inconsistent_edges);
  EXPECT_EQ(r.components, b.components);
  EXPECT_EQ(r.euler_characteristic, b.euler_characteristic);
  EXPECT_EQ(r.unused_vertices, b.unused_vertices);
  EXPECT_EQ(r.boundary_loops, b.boundary_loops);
  EXPECT_EQ(r.is_closed_manifold(), b.is_closed_manifold());
}

TEST(Subdivide, TopologyCarriesOver) {
  model::Mesh two_pieces = test::tetrahedron();
  // A second, separate tetrahedron beside the first.
  for (std::size_t i = 0; i < 12; ++i)
    two_pieces.positions.push_back(two_pieces.positions[i] + (i % 3 == 0 ? 5 : 0));
  for (std::size_t i = 0; i < 12; ++i) two_pieces.triangles.push_back(two_pieces.triangles[i] + 4);
  const model::Mesh bases[] = {test::tetrahedron(),
                               test::square(),
                               fin(),
                               two_pieces,
                               generate(eval::Shape::kSphere, 600),
                               generate(eval::Shape::kTerrain, 600),
                               generate(eval::Shape::kShell, 900)};
  for (const model::Mesh& base : bases) {
    for (std::uint32_t n : {1u, 2u, 3u, 6u}) {
      for (float noise : {0.0f, 0.3f}) {
        SCOPED_TRACE(testing::Message()
                     << "V " << base.vertex_count() << " split " << n << " noise " << noise);
        const model::Mesh out = split(base, n, noise);
        expect_topology_carried_over(base, out, n);
        // Each cut is made once and shared by both triangles of its edge: no two vertices in one place.
        const model::TopologyReport r = model::analyze_topology(out.positions, out.triangles);
        EXPECT_EQ(r.duplicate_positions, 0u);
        EXPECT_EQ(r.degenerate_triangles, 0u);
        EXPECT_EQ(r.duplicate_triangles, 0u);
      }
    }
  }
}

TEST(Subdivide, ClosedManifoldStaysClosedWithItsEulerCharacteristic) {
  const model::Mesh base = generate(eval::Shape::kSphere, 2000);
  const model::Mesh out = split(base, 4, 0.2f);
  const model::TopologyReport r = model::analyze_topology(out.positions, out.triangles);
  EXPECT_TRUE(r.is_closed_manifold()) << r.summary();
  EXPECT_EQ(r.euler_characteristic, 2);
  EXPECT_EQ(r.non_manifold_vertices, 0u);
}

TEST(Subdivide, CrackBetweenDuplicateVerticesStaysClosed) {
  const model::Mesh base = cracked_square();
  for (float noise : {0.0f, 0.25f}) {
    const std::uint32_t n = 3;
    const model::Mesh out = split(base, n, noise);
    const model::TopologyReport r = model::analyze_topology(out.positions, out.triangles);
    // The base's 2 duplicates, and the diagonal's n−1 cuts made twice, once per piece.
    EXPECT_EQ(r.duplicate_positions, 2u + (n - 1));
    EXPECT_EQ(r.components, 2u);
    EXPECT_EQ(r.boundary_edges, 6u * n);
    // Duplicate base vertices move together: they share one normal and one noise value.
    EXPECT_EQ(position(out, 4), position(out, 2));
    EXPECT_EQ(position(out, 5), position(out, 0));
  }
}

TEST(Subdivide, NoiseIsBoundedDeterministicAndSeeded) {
  const model::Mesh base = generate(eval::Shape::kShell, 1200);
  const float noise = 0.3f;
  eval::SubdivideOptions options;
  options.split = 5;
  options.noise = noise;
  const eval::Subdivider subdivider(base, options);
  const double amplitude = noise * mean_edge_length(base);
  // Both means are double sums of the same lengths in different orders.
  EXPECT_NEAR(subdivider.amplitude(), amplitude, 1e-12 * amplitude);

  const model::Mesh flat = split(base, 5), noisy = eval::subdivide(base, options);
  ASSERT_EQ(flat.positions.size(), noisy.positions.size());
  EXPECT_EQ(flat.triangles, noisy.triangles);
  double largest = 0.0, sum = 0.0;
  for (std::uint32_t v = 0; v < flat.vertex_count(); ++v) {
    const double d = norm(sub(position(noisy, v), position(flat, v)));
    largest = std::max(largest, d);
    sum += d;
  }
  // The bound plus float32 rounding of coordinates near 1.
  EXPECT_LE(largest, amplitude + 1e-6);
  // Not trivially small: value noise's mean magnitude is a sizeable fraction of its bound.
  EXPECT_GT(sum / static_cast<double>(flat.vertex_count()), 0.05 * amplitude);

  EXPECT_EQ(eval::subdivide(base, options).positions, noisy.positions);
  options.seed = 2;
  const model::Mesh reseeded = eval::subdivide(base, options);
  EXPECT_NE(reseeded.positions, noisy.positions);
  EXPECT_EQ(reseeded.triangles, noisy.triangles);
}

TEST(Subdivide, NoiseIsSmoothAcrossTheSurface) {
  // The noise is Lipschitz. Per octave, in its own lattice units, |∂/∂x| ≤ 2 · max fade' = 2 · 15/8,
  // so the gradient is at most 3.75·√3 ≈ 6.5; octave o has frequency 2^o and weight 2^-o / 1.875, so
  // four octaves give at most 4 · 6.5 / 1.875 < 14 per coarsest-lattice unit (the wavelength). The
  // displacement's length is amplitude · |noise| along a unit normal, so along every output edge
  // it changes by at most amplitude · 14 · (flat edge length) / wavelength; white noise would not.
  const model::Mesh base = generate(eval::Shape::kSphere, 300, 0.0f);
  eval::SubdivideOptions options;
  options.split = 12;
  options.noise = 0.5f;
  options.wavelength = 4.0f;
  const model::Mesh noisy = eval::subdivide(base, options);
  const model::Mesh flat = split(base, options.split);
  const double amplitude = 0.5 * mean_edge_length(base), wavelength = 4.0 * mean_edge_length(base);
  double largest_ratio = 0.0;
  for (std::size_t t = 0; t < flat.triangle_count(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = flat.triangles[3 * t + k], b = flat.triangles[3 * t + (k + 1) % 3];
      const double da = norm(sub(position(noisy, a), position(flat, a)));
      const double db = norm(sub(position(noisy, b), position(flat, b)));
      const double length = norm(sub(position(flat, a), position(flat, b)));
      // 1e-6: float32 rounding of coordinates near 1 in both meshes.
      ASSERT_LE(std::abs(da - db), amplitude * 14.0 * length / wavelength + 1e-6);
      largest_ratio = std::max(largest_ratio, std::abs(da - db) / amplitude);
    }
  }
  EXPECT_GT(largest_ratio, 0.0);
}

TEST(Subdivide, TetrahedronCornersMoveAlongTheirRadialNormals) {
  // A regular tetrahedron centred on the origin: by symmetry each corner's area-weighted normal
  // points away from the centre, so a displaced corner stays on its ray.
  const model::Mesh base = test::tetrahedron();
  const model::Mesh out = split(base, 3, 0.4f);
  const double amplitude = 0.4 * mean_edge_length(base);
  for (std::uint32_t v = 0; v < 4; ++v) {
    const Vec before = position(base, v), after = position(out, v);
    EXPECT_LT(norm(cross(before, after)) / dot(before, before), 1e-6);
    EXPECT_LE(std::abs(norm(after) - norm(before)), amplitude + 1e-6);
  }
}

TEST(Subdivide, ColoursAreInterpolated) {
  model::Mesh base;
  base.positions = {0, 0, 0, 3, 0, 0, 0, 3, 0};
  base.colors = {0, 0, 0, 255, 90, 30, 0, 30, 201};
  base.triangles = {0, 1, 2};
  const model::Mesh out = split(base, 3, 0.1f);
  ASSERT_EQ(out.colors.size(), out.positions.size());
  EXPECT_TRUE(std::equal(base.colors.begin(), base.colors.end(), out.colors.begin()));
  // Edge 0–1 is cut from 0 (x = 0 < 3): cuts at 1/3 and 2/3 of the way to corner 1.
  EXPECT_EQ(std::vector<std::uint8_t>(out.colors.begin() + 9, out.colors.begin() + 15),
            (std::vector<std::uint8_t>{85, 30, 10, 170, 60, 20}));
  // The single interior point is the centroid: (255 + 0 + 0) / 3, (90 + 30) / 3, (30 + 201) / 3.
  const std::size_t interior = out.vertex_count() - 1;
  EXPECT_EQ(std::vector<std::uint8_t>(out.colors.begin() + 3 * interior, out.colors.end()),
            (std::vector<std::uint8_t>{85, 40, 77}));
}

// Records every call, copying the chunks, and can fail on a chosen triangle call.
struct RecordingSink final : eval::SubdivisionSink {
  model::Mesh mesh;
  std::size_t largest_vertex_chunk = 0, largest_triangle_chunk = 0, triangle_calls = 0;
  bool vertices_after_triangles = false;
  std::size_t fail_on_triangle_call = SIZE_MAX;
  Status vertices(std::span<const float> positions, std::span<const std::uint8_t> colors) override {
    vertices_after_triangles |= triangle_calls != 0;
    largest_vertex_chunk = std::max(largest_vertex_chunk, positions.size() / 3);
    EXPECT_TRUE(colors.empty());
    mesh.positions.insert(mesh.positions.end(), positions.begin(), positions.end());
    return Ok{};
  }
  Status triangles(std::span<const std::uint32_t> triangles) override {
    if (triangle_calls++ == fail_on_triangle_call) return make_error(ErrorCode::kIoError, "disk full");
    largest_triangle_chunk = std::max(largest_triangle_chunk, triangles.size() / 3);
    mesh.triangles.insert(mesh.triangles.end(), triangles.begin(), triangles.end());
    return Ok{};
  }
};

TEST(Subdivide, ChunkSizesDoNotChangeTheOutput) {
  const model::Mesh base = generate(eval::Shape::kTerrain, 300);
  eval::SubdivideOptions options;
  options.split = 4;
  options.noise = 0.1f;
  const model::Mesh whole = eval::subdivide(base, options);
  for (std::size_t chunk : {1u, 7u, 1000u}) {
    options.chunk_vertices = chunk;
    options.chunk_triangles = chunk + 2;
    RecordingSink sink;
    ASSERT_TRUE(eval::Subdivider(base, options).run(sink).ok());
    EXPECT_EQ(sink.mesh.positions, whole.positions);
    EXPECT_EQ(sink.mesh.triangles, whole.triangles);
    EXPECT_FALSE(sink.vertices_after_triangles);
    EXPECT_LE(sink.largest_vertex_chunk, chunk);
    EXPECT_LE(sink.largest_triangle_chunk, chunk + 2);
  }
}

TEST(Subdivide, SinkErrorStopsTheRun) {
  eval::SubdivideOptions options;
  options.split = 4;
  options.chunk_triangles = 5;
  RecordingSink sink;
  sink.fail_on_triangle_call = 2;
  const Status status = eval::Subdivider(generate(eval::Shape::kSphere, 200), options).run(sink);
  ASSERT_FALSE(status.ok());
  EXPECT_EQ(status.error().message, "disk full");
  EXPECT_EQ(sink.triangle_calls, 3u);
}

// Triangles grouped by vertex set: the number of sets used more than once.
std::size_t repeated_vertex_sets(const model::Mesh& m) {
  std::map<std::array<std::uint32_t, 3>, std::size_t> uses;
  for (std::size_t t = 0; t < m.triangle_count(); ++t) {
    std::array<std::uint32_t, 3> key{m.triangles[3 * t], m.triangles[3 * t + 1], m.triangles[3 * t + 2]};
    std::sort(key.begin(), key.end());
    ++uses[key];
  }
  return static_cast<std::size_t>(
      std::count_if(uses.begin(), uses.end(), [](const auto& u) { return u.second > 1; }));
}

TEST(Subdivide, RealScansKeepTheirDefects) {
  const auto dir = test::shared_meshes_dir();
  if (!std::filesystem::exists(dir / "dragon-vrip-res4-11k.ply"))
    GTEST_SKIP() << "no shared meshes at " << dir;

  // The open bunny: holes, unused vertices, no duplicate triangles, so every invariant holds.
  {
    auto loaded = io::load_mesh(dir / "bunny-zipper-69k.ply", {.clean = false});
    ASSERT_TRUE(loaded.ok()) << loaded.error().message;
    const model::Mesh& base = loaded->mesh;
    const model::Mesh out = split(base, 2, 0.1f);
    expect_topology_carried_over(base, out, 2);
    EXPECT_GT(model::analyze_topology(base.positions, base.triangles).boundary_edges, 0u);
  }
  // The non-manifold dragon with 502 duplicate triangles. A triangle and its copies share their
  // edges' cuts, so at each corner the edge between the two first cuts, used by two triangles of
  // each copy, becomes non-manifold, and is one edge instead of one per copy: 3 non-manifold edges
  // per repeated vertex set, and 3 fewer edges (Euler +3) per duplicate. For n ≥ 3 the three corner
  // triangles repeat too (for n = 2 the middle one also does).
  {
    auto loaded = io::load_mesh(dir / "dragon-vrip-res4-11k.ply", {.clean = false});
    ASSERT_TRUE(loaded.ok()) << loaded.error().message;
    const model::Mesh& base = loaded->mesh;
    const model::TopologyReport b = model::analyze_topology(base.positions, base.triangles);
    ASSERT_GT(b.non_manifold_edges, 0u);
    ASSERT_GT(b.duplicate_triangles, 0u);
    ASSERT_EQ(b.degenerate_triangles, 0u);
    const std::uint32_t n = 3;
    const model::Mesh out = split(base, n, 0.1f);
    const model::TopologyReport r = model::analyze_topology(out.positions, out.triangles);
    EXPECT_EQ(r.non_manifold_edges, n * b.non_manifold_edges + 3 * repeated_vertex_sets(base));
    EXPECT_EQ(r.euler_characteristic,
              b.euler_characteristic + 3 * static_cast<std::int64_t>(b.duplicate_triangles));
    EXPECT_EQ(r.duplicate_triangles, 3 * b.duplicate_triangles);
    EXPECT_EQ(r.boundary_edges, n * b.boundary_edges);
    EXPECT_EQ(r.inconsistent_edges, n * b.inconsistent_edges);
    EXPECT_EQ(r.components, b.components);
    EXPECT_EQ(r.unused_vertices, b.unused_vertices);
  }
}

}  // namespace
}  // namespace mtlod::core

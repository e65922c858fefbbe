// MT builder (core/ARCHITECTURE.md §2.6): greedy half-edge collapse by quadric error, done in
// passes of independent collapses (as meshoptimizer's simplifier does), each collapse recorded as
// one MT node.
//
// Per pass: rebuild vertex→face adjacency (CSR), classify every vertex (interior / boundary /
// complex), give each collapsible vertex u its cheapest partner v, sort, and choose collapses in
// cost order while no earlier choice of the same pass changed u's fan or changed v's fan in a way
// that matters to the checks, so the adjacency read at the start of the pass gives every tried
// collapse the answer the current mesh would. The chosen collapses change disjoint fans and then
// run in any order. With BuildOptions::parallel_for these steps run on several threads; every
// shared position (collapse tags, MT triangles, pool blocks) is fixed before, so the MT is the same
// byte for byte.
//
// Two phases. The first keeps the topology (link condition; boundary vertices slide along their
// boundary; non-manifold and inconsistently oriented fans are never touched). When it has no valid
// collapse left, the topology phase (BuildOptions::coarse_topology) drops the link condition and
// collapses any vertex whose edges all have an even number of faces into any neighbour, and any
// other vertex into a neighbour that is also on an odd edge. Counted mod 2, the outline of the
// faces a collapse of an even vertex creates is that of the faces it removes (the faces holding u
// and v cancel), so no crack opens; an odd vertex only moves its odd edges onto vertices already
// on odd edges, so a cut's odd edges stay on vertices of the input's odd edges. Its collapses come
// last, with errors measured like any other, so a cut changes the topology only where its error
// allows. Without the link condition a vertex's cheapest partner is often refused while another
// is valid, so refused pairs are remembered and the next pass tries the next partner. When even
// that phase is stuck, its last stage also lets a new face land on three vertices that already
// have a face (in the opposite orientation as a rule: two sheets of a scan's stacked or pinched
// surface meeting). Counted mod 2 the pair is no face, so the outline argument still holds and a
// later collapse of one of its vertices removes both; the format cannot say that a node removes a
// face around another vertex, so the pair stays in the cuts between. Without this stage scans
// whose non-manifold edges were split finely (the 105M dragon of BENCHMARKS.md) stop at thousands
// of faces in stacks of small closed pieces where every collapse repeats a face.
//
// Global error (the Jade method's): every original vertex removed so far is assigned to one working
// face. A collapse hands u and the vertices of u's faces to faces of the new fan, and its error is
// the largest exact distance from those vertices to their faces, raised to the fan's largest error
// so errors never grow from a node to its children. In any cut, each original vertex's chain of
// assigned faces meets exactly one cut triangle (or the vertex is a corner of the cut), so every
// original vertex lies within that triangle's error of the cut.
#include "core/build/mt_builder.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cassert>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "core/build/vertex_normals.hpp"
#include "core/model/bounds.hpp"
#include "core/util/grow_only_vector.hpp"
#include "core/util/radix_sort.hpp"

namespace mtlod::core::build {
namespace {

// kLocked: a block's border vertex in an out-of-core build, kept as it is (simplify_block).
// kEven and kOdd: the kinds of the topology phase (BuildOptions::coarse_topology), where a vertex is
// even when every edge at it has an even number of faces and odd otherwise (a boundary, or an edge
// with three faces); kComplex there is a vertex that a face holds twice.
enum VertexKind : std::uint8_t {
  kUnused = 0,
  kInterior = 1,
  kBoundary = 2,
  kComplex = 3,
  kLocked = 4,
  kEven = 5,
  kOdd = 6
};

// Fans larger than this are treated as complex: they never occur on scans except at defects.
constexpr std::uint32_t kMaxFan = 64;

// Concurrent phases split their range into at most kChunks chunks of at least kMinChunk items.
constexpr std::size_t kChunks = 16;
constexpr std::size_t kMinChunk = 2048;
// Collapse chunks: a collapse's fixed cost in moved-point equivalents, and the least work a chunk
// of collapses gets (about 0.2 ms of one core): less, and handing chunks out costs more than it saves.
constexpr std::size_t kFanWork = 16;
constexpr std::size_t kMinChunkWork = 4096;
// How far ahead loops over scattered vertices prefetch.
constexpr std::size_t kPrefetchAhead = 8;
// How far ahead of the chooser the guesser starts when it falls behind.
constexpr std::size_t kGuessLead = 16;
// The assigned points' pool is compacted once it holds more than this many times the points that
// can be assigned at once: more slack means fewer compactions, less means less memory (a block of an
// out-of-core build may carry most of the model's points).
constexpr std::size_t kPoolSlack = 5;
constexpr std::size_t kBlockPoolSlack = 2;
constexpr std::size_t kKeptMovingPoints = std::size_t{1} << 16;

// Zero when value-initialised (Quadric{}); left unset by default so big arrays of them are not
// filled on one thread before the concurrent loop that writes them.
struct Quadric {
  float a00, a01, a02, a11, a12, a22;
  float b0, b1, b2, c;
};

void add_plane(Quadric& q, float nx, float ny, float nz, float d, float w) {
  q.a00 += w * nx * nx;
  q.a01 += w * nx * ny;
  q.a02 += w * nx * nz;
  q.a11 += w * ny * ny;
  q.a12 += w * ny * nz;
  q.a22 += w * nz * nz;
  q.b0 += w * nx * d;
  q.b1 += w * ny * d;
  q.b2 += w * nz * d;
  q.c += w * d * d;
}

void add_quadric(Quadric& q, const Quadric& r) {
  q.a00 += r.a00, q.a01 += r.a01, q.a02 += r.a02, q.a11 += r.a11, q.a12 += r.a12, q.a22 += r.a22;
  q.b0 += r.b0, q.b1 += r.b1, q.b2 += r.b2, q.c += r.c;
}

float evaluate(const Quadric& q, const float* p) {
  const float x = p[0], y = p[1], z = p[2];
  const float r = x * (q.a00 * x + 2 * (q.a01 * y + q.a02 * z + q.b0)) +
                  y * (q.a11 * y + 2 * (q.a12 * z + q.b1)) + z * (q.a22 * z + 2 * q.b2) + q.c;
  return r > 0 ? r : 0;  // rounding can make a positive semi-definite form slightly negative
}

struct Vec3 {
  double x, y, z;
};
Vec3 sub(const float* a, const float* b) {
  return {double{a[0]} - b[0], double{a[1]} - b[1], double{a[2]} - b[2]};
}
Vec3 sub(const float* a, const Vec3& b) {
  return {a[0] - b.x, a[1] - b.y, a[2] - b.z};
}
Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
double dot(const Vec3& a, const Vec3& b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}

// Squared distance from p to triangle abc, exact in double (closest-point regions as in Ericson,
// Real-Time Collision Detection §5.1.5).
double point_triangle_distance_squared(const float* pf, const float* af, const float* bf, const float* cf) {
  const double p[3] = {pf[0], pf[1], pf[2]}, a[3] = {af[0], af[1], af[2]};
  const double b[3] = {bf[0], bf[1], bf[2]}, c[3] = {cf[0], cf[1], cf[2]};
  const double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  const double ap[3] = {p[0] - a[0], p[1] - a[1], p[2] - a[2]};
  auto d3 = [](const double* x, const double* y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; };
  auto dist2 = [p](double x, double y, double z) {
    return (p[0] - x) * (p[0] - x) + (p[1] - y) * (p[1] - y) + (p[2] - z) * (p[2] - z);
  };
  const double d1 = d3(ab, ap), d2 = d3(ac, ap);
  if (d1 <= 0 && d2 <= 0) return dist2(a[0], a[1], a[2]);
  const double bp[3] = {p[0] - b[0], p[1] - b[1], p[2] - b[2]};
  const double e3 = d3(ab, bp), e4 = d3(ac, bp);
  if (e3 >= 0 && e4 <= e3) return dist2(b[0], b[1], b[2]);
  const double vc = d1 * e4 - e3 * d2;
  if (vc <= 0 && d1 >= 0 && e3 <= 0) {
    const double t = d1 / (d1 - e3);
    return dist2(a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]);
  }
  const double cp[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
  const double e5 = d3(ab, cp), e6 = d3(ac, cp);
  if (e6 >= 0 && e5 <= e6) return dist2(c[0], c[1], c[2]);
  const double vb = e5 * d2 - d1 * e6;
  if (vb <= 0 && d2 >= 0 && e6 <= 0) {
    const double t = d2 / (d2 - e6);
    return dist2(a[0] + t * ac[0], a[1] + t * ac[1], a[2] + t * ac[2]);
  }
  const double va = e3 * e6 - e5 * e4;
  if (va <= 0 && (e4 - e3) >= 0 && (e5 - e6) >= 0) {
    const double t = (e4 - e3) / ((e4 - e3) + (e5 - e6));
    return dist2(b[0] + t * (c[0] - b[0]), b[1] + t * (c[1] - b[1]), b[2] + t * (c[2] - b[2]));
  }
  const double denom = 1.0 / (va + vb + vc);
  const double s = vb * denom, t = vc * denom;
  return dist2(a[0] + ab[0] * s + ac[0] * t, a[1] + ab[1] * s + ac[1] * t, a[2] + ab[2] * s + ac[2] * t);
}

// A cheap sufficient test for "the squared distance from p to triangle abc, as
// point_triangle_distance_squared computes it, is at most r2": p projects inside the triangle and
// its squared plane distance, with slack for rounding (relative 1e-9, plus 1e-12 of the longest
// edge squared), is at most r2. Inputs are floats, so the differences below are exact in double.
class WithinTest {
 public:
  void set(const float* a, const float* b, const float* c) {
    a_ = {a[0], a[1], a[2]}, b_ = {b[0], b[1], b[2]}, c_ = {c[0], c[1], c[2]};
    const Vec3 ab = sub(b, a), bc = sub(c, b), ca = sub(a, c);
    n_ = cross(ab, bc);  // ab × ac: ac = ab + bc
    inward_[0] = cross(n_, ab);
    inward_[1] = cross(n_, bc);
    inward_[2] = cross(n_, ca);
    n2_ = dot(n_, n_);
    const double longest = std::max({dot(ab, ab), dot(bc, bc), dot(ca, ca)});
    slack_ = 1e-12 * longest * n2_;
    // A sliver's normal says little: leave it to the exact distance.
    usable_ = n2_ > 1e-12 * longest * longest;
  }
  bool within(const float* p, double r2) const {
    if (!usable_) return false;
    const Vec3 ap = sub(p, a_);
    if (dot(ap, inward_[0]) < 0 || dot(sub(p, b_), inward_[1]) < 0 || dot(sub(p, c_), inward_[2]) < 0)
      return false;
    const double s = dot(ap, n_);
    return s * s * (1 + 1e-9) + slack_ <= r2 * n2_;
  }

 private:
  Vec3 a_, b_, c_;
  Vec3 n_;
  Vec3 inward_[3];  // n × edge for edges ab, bc, ca: towards the opposite corner
  double n2_ = 0, slack_ = 0;
  bool usable_ = false;
};

struct Candidate {
  float cost;
  std::uint32_t u;
  std::uint32_t v;
};

// By cost, stably, so equal costs keep vertex order and the build stays deterministic.
void sort_by_cost(util::GrowOnlyVector<Candidate>& items, util::GrowOnlyVector<Candidate>& scratch) {
  util::radix_sort(items, scratch, [](const Candidate& c) {
    std::uint32_t bits;
    std::memcpy(&bits, &c.cost, 4);
    return bits;
  });
}

class Builder {
 public:
  Builder(const model::Mesh& mesh, const BuildOptions& options, BlockInput* block = nullptr)
      : mesh_(mesh), options_(options), block_(block) {}

  Result<model::Mt> run(BuildStats* stats, std::vector<std::uint32_t>* vertex_ids);
  Result<BlockOutput> run_block(std::size_t target_triangles);

 private:
  Status prepare();
  Status check_mesh() const;  // the mesh's arrays: sizes, ids, finite positions
  Status check_block() const;
  // The pass loop and its steps, in order.
  void simplify();
  void classify_vertices();
  std::size_t collect_candidates();  // returns how many vertices have a partner
  std::size_t pass_quota();
  void place_collapses();  // tags, MT triangles, pool blocks and work chunks of the chosen collapses
  void run_collapses();

  const float* position(std::uint32_t v) const { return &mesh_.positions[3 * std::size_t{v}]; }

  void init_quadrics();
  Quadric gather_quadric(std::uint32_t u) const;
  struct Plane {
    float nx, ny, nz, d, w;
  };
  util::GrowOnlyVector<Plane> face_planes_;  // while the quadrics are built: each face's plane and weight
  void build_adjacency();
  // Per-chunk scratch of the concurrent phases.
  struct Moving {
    float position[3];
    std::uint32_t old_face;  // index into the new faces of its old face when that survives, else kNoFace
    std::uint32_t new_face;  // index into the new faces
  };
  struct Scratch {
    std::vector<Moving> moving;
    std::vector<std::uint32_t> new_faces;
    std::vector<std::uint32_t> new_face_ends;
    std::vector<WithinTest> within;  // per new face
  };
  // A collapse chosen for the current pass: its tag (index + 1), first MT triangle and first
  // assigned point are fixed before the collapses run, so the result does not depend on which
  // chunk runs when.
  struct Chosen {
    std::uint32_t u, v, tag, first_triangle;
    std::uint32_t first_point;  // until the collapses are placed: the number of points moved
  };

  // Calls body(chunk, begin, end) over [0, count) split into at most kChunks ranges, concurrently
  // when options_.parallel_for is set.
  template <class Body>
  void for_chunks(std::size_t count, const Body& body);
  // How many chunks for_chunks splits count items into (the same with or without a runner).
  static std::size_t chunk_count(std::size_t count) {
    return count < kMinChunk ? 1 : std::min(kChunks, count / kMinChunk);
  }
  // Runs count_chunk(chunk, begin, end), the number of outputs of that chunk, over the chunks of
  // [0, count) as for_chunks does, and turns the numbers into each chunk's first output position
  // (chunk_counts_), so a second for_chunks can place the outputs in order. Returns their total.
  template <class Count>
  std::size_t chunk_starts(std::size_t count, const Count& count_chunk);
  // Calls body(i) for i in [0, count), concurrently when options_.parallel_for is set and the
  // ranges together cover at least kMinChunk items (`items`); in turn otherwise.
  template <class Body>
  void for_ranges(std::size_t count, std::size_t items, const Body& body);
  // Drops the items keep(item, half) refuses from list, keeping the order; the two halves of the
  // list are visited concurrently. Returns how many of the kept items came from the first half.
  template <class Keep>
  std::size_t filter_in_halves(std::vector<std::uint32_t>& list, const Keep& keep);
  VertexKind classify(std::uint32_t u, std::uint32_t& boundary_next, std::uint32_t& boundary_prev) const;
  VertexKind classify_parity(std::uint32_t u) const;
  // Whether v may take u's place: in the first phase an interior or boundary vertex; in the
  // topology phase any even or odd vertex for an even u, an odd one for an odd u.
  bool is_target(VertexKind u_kind, VertexKind v_kind) const {
    if (!topology_phase_) return v_kind == kInterior || v_kind == kBoundary;
    return v_kind == kOdd || (v_kind == kEven && u_kind == kEven);
  }
  void find_partner(std::uint32_t u, const std::uint32_t* boundary_ends);
  // Scratch marks of can_collapse, one set per thread that calls it.
  struct Stamps {
    std::vector<std::uint32_t> link;
    std::uint32_t stamp = 0;
  };
  bool can_collapse(std::uint32_t u, std::uint32_t v, Stamps& stamps) const;
  void choose_collapses(std::size_t quota);
  void collapse(const Chosen& chosen, Scratch& scratch);
  void prefetch_fan(std::uint32_t u) const {
    for (std::uint32_t i = adjacency_begin_[u]; i < adjacency_end_[u]; ++i) {
      const std::uint32_t f = adjacency_[i].face;
      __builtin_prefetch(&working_[3 * std::size_t{f}]);
      __builtin_prefetch(&face_mt_[f]);
      __builtin_prefetch(&face_points_[f]);
      __builtin_prefetch(&face_first_point_[f]);
    }
  }
  void prefetch_fan_data(std::uint32_t u) {
    for (std::uint32_t i = adjacency_begin_[u]; i < adjacency_end_[u]; ++i) {
      const std::uint32_t f = adjacency_[i].face;
      __builtin_prefetch(&creating_collapse_[face_mt_[f]], 1);
      if (face_points_[f] > 0) __builtin_prefetch(&points_[3 * std::size_t{face_first_point_[f]}]);
    }
  }
  void prefetch_collapse(const Chosen& chosen) const {
    __builtin_prefetch(&quadrics_[chosen.u]);
    __builtin_prefetch(&quadrics_[chosen.v]);
    __builtin_prefetch(&adjacency_[adjacency_begin_[chosen.u]]);
  }
  model::Mt assemble(std::vector<std::uint32_t>* vertex_ids);
  // assemble's steps: vertex ids in node order, triangles sorted by creating node, parent lists.
  std::vector<std::uint32_t> number_vertices(const std::vector<std::uint32_t>& node_of) const;
  void place_triangles(model::MtArrays& mt, const util::GrowOnlyVector<std::uint32_t>& creators,
                       const util::GrowOnlyVector<std::uint32_t>& removers,
                       const std::vector<std::uint32_t>& vertex_id);
  void link_parents(model::MtArrays& mt, const std::vector<std::uint32_t>& node_of,
                    const util::GrowOnlyVector<std::uint32_t>& creators);
  BlockOutput export_block();
  // Collapses from `first` on (a phase that started there) and their smallest error.
  void phase_stats(bool started, std::size_t first, std::size_t& collapses, float& error) const {
    if (!started) return;
    collapses = collapse_u_.size() - first;
    for (std::size_t c = first; c < collapse_error_.size(); ++c) error = std::min(error, collapse_error_[c]);
  }
  // BuildStats::topology_* and stacking_*.
  template <class Stats>
  void topology_stats(Stats& s) const {
    phase_stats(topology_phase_, topology_first_, s.topology_collapses, s.topology_error);
    phase_stats(stacking_, stacking_first_, s.stacking_collapses, s.stacking_error);
  }

  const model::Mesh& mesh_;
  NormalRepair normal_repair_;
  BuildOptions options_;
  BlockInput* block_;
  std::size_t target_triangles_ = 0;  // stop once at most this many faces are alive
  std::size_t vertex_count_ = 0;
  std::size_t face_count_ = 0;
  std::size_t alive_faces_ = 0;

  util::GrowOnlyVector<float> unit_positions_;  // positions scaled to the unit box, for quadrics
  util::GrowOnlyVector<Quadric> quadrics_;
  std::vector<std::uint32_t> working_;  // 3 vertex ids per face slot
  std::vector<std::uint8_t> face_alive_;
  std::vector<std::uint32_t> face_mt_;  // MT triangle currently in each face slot
  std::vector<float> face_error_;       // its error: that of the collapse that made it, 0 for input

  // MT triangles in order of appearance: vertices, and the collapses (index + 1, 0 = none) whose
  // MT nodes remove and create them. A collapse's node undoes it: it removes the triangles the
  // collapse made and creates those the collapse took away.
  // Grown once per pass for the chosen collapses, which write every new slot: no zero fill first.
  util::GrowOnlyVector<std::uint32_t> mt_vertices_;
  util::GrowOnlyVector<std::uint32_t> removing_collapse_;
  util::GrowOnlyVector<std::uint32_t> creating_collapse_;
  std::vector<std::uint32_t> collapse_u_;
  std::vector<float> collapse_error_;

  // Vertex → faces over the alive faces, rebuilt each pass; valid for alive vertices only. Each
  // entry holds the face's other two corners, so fan walks never read the faces themselves.
  struct Corner {
    std::uint32_t face;
    std::uint32_t next;  // corner after the vertex, counter-clockwise
    std::uint32_t prev;  // corner before it
  };
  std::vector<std::uint32_t> adjacency_begin_;
  std::vector<std::uint32_t> adjacency_end_;
  std::vector<std::uint32_t> second_half_;  // build_adjacency's counts and cursors of its second half
  util::GrowOnlyVector<Corner> adjacency_;
  std::vector<std::uint32_t> alive_face_list_;
  std::vector<std::uint32_t> alive_vertex_list_;  // used by an alive face (may lag one pass)
  std::vector<std::uint8_t> vertex_dead_;
  std::vector<std::uint8_t> kind_;
  std::vector<std::uint32_t> touched_;  // pass number that last changed a vertex's fan
  // For a vertex touched in the current pass only as a corner of one chosen collapse's fan: that
  // collapse's v; kNoVertex when it is an end of a chosen collapse or in two chosen fans.
  std::vector<std::uint32_t> ring_target_;
  std::uint32_t pass_ = 0;
  // The topology phase (BuildOptions::coarse_topology) starts once the first phase has no valid
  // collapse left, at pass topology_pass_; its collapses are those from topology_first_ on.
  bool topology_phase_ = false;
  // The topology phase's last stage: a new face may repeat a face its target already has.
  bool stacking_ = false;
  std::size_t stacking_first_ = 0;
  std::uint32_t topology_pass_ = 0;
  std::size_t topology_first_ = 0;
  // Pairs (u << 32 | v) that can_collapse refused in the topology phase, with the pass: u's next
  // search skips v until u or v is touched. Without the link condition a vertex's cheapest partner
  // is often invalid while another is not; a pass that only refuses still makes progress.
  std::unordered_map<std::uint64_t, std::uint32_t> refused_;
  std::vector<std::uint64_t> refused_now_;  // by the chooser, during a pass
  bool is_refused(std::uint32_t u, std::uint32_t v) const {
    const auto it = refused_.find(std::uint64_t{u} << 32 | v);
    return it != refused_.end() && touched_[u] < it->second && touched_[v] < it->second;
  }
  Stamps chooser_stamps_, guesser_stamps_;
  std::vector<std::uint8_t> verdicts_;      // per candidate: 0 not known yet, 1 can collapse, 2 cannot
  std::uint32_t chosen_triangles_end_ = 0;  // MT triangle count once the chosen collapses have run
  std::vector<Candidate> best_;             // per vertex: cheapest partner found when it was last evaluated
  util::GrowOnlyVector<Candidate> candidates_;
  util::GrowOnlyVector<Candidate> candidate_scratch_;
  std::vector<std::size_t> chunk_counts_;   // chunk_starts' result
  std::vector<std::size_t> chunk_complex_;  // per chunk of the partner search: complex vertices met
  // Jade-style assignment of removed original vertices to working faces. Only their positions are
  // needed, kept as one contiguous run per face slot in a pool (x, y, z per point) that each pass
  // appends to and that is compacted when it grows past a few times the points alive.
  void compact_assigned_points();
  // points_.resize(size), with a reallocation's copy done in concurrent chunks.
  void grow_pool(std::size_t size);
  std::vector<std::uint32_t> face_first_point_;
  std::vector<std::uint32_t> face_points_;
  util::GrowOnlyVector<float> points_;
  util::GrowOnlyVector<float> points_scratch_;
  std::size_t used_vertices_ = 0;
  // At most this many points are assigned at any time: the block's carried points and every used
  // vertex (each is assigned once it is removed).
  std::size_t points_bound_ = 0;
  std::vector<Scratch> scratch_;
  std::vector<Chosen> chosen_;
  std::vector<Chosen> chosen_scratch_;
  std::vector<std::size_t> collapse_chunk_begin_;  // chunk k of the pass's collapses starts here
  std::size_t collapse_work_ = 0;                  // the pass's collapses' work, in moved points
  std::vector<std::uint32_t> boundary_ends_;       // per vertex: its boundary neighbours, when a boundary one
  std::size_t complex_vertices_ = 0;
};

void Builder::init_quadrics() {
  const model::Bounds box = model::bounds_of(mesh_.positions);
  const std::array<float, 3>& lo = box.lo;
  const float extent = box.largest_side();
  // Quadrics in float lose precision on large coordinates; the unit box keeps them well scaled.
  const float scale = extent > 0 ? 1.0f / extent : 1.0f;
  unit_positions_.resize(3 * vertex_count_);
  for_chunks(vertex_count_, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t v = begin; v < end; ++v)
      for (int k = 0; k < 3; ++k) unit_positions_[3 * v + k] = (mesh_.positions[3 * v + k] - lo[k]) * scale;
  });

  // Face planes first, one per face (faces run concurrently); then each vertex sums its own from
  // its fan (vertices run concurrently). Fans list their faces in face order, and each vertex adds
  // its face planes and then its boundary planes in that order, exactly as one pass over the faces
  // scattering to their corners would.
  face_planes_.resize(face_count_);
  for_chunks(face_count_, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t f = begin; f < end; ++f) {
      const std::uint32_t* t = &working_[3 * f];
      const float* p0 = &unit_positions_[3 * std::size_t{t[0]}];
      const Vec3 n = cross(sub(&unit_positions_[3 * std::size_t{t[1]}], p0),
                           sub(&unit_positions_[3 * std::size_t{t[2]}], p0));
      const double length = std::sqrt(dot(n, n));
      if (length == 0) {
        face_planes_[f] = {0, 0, 0, 0, 0};  // no area, no plane (weight 0 marks it)
        continue;
      }
      const float nx = float(n.x / length), ny = float(n.y / length), nz = float(n.z / length);
      face_planes_[f] = {nx, ny, nz, -(nx * p0[0] + ny * p0[1] + nz * p0[2]), float(length * 0.5)};
    }
  });
  // Every vertex, used or not: a vertex without faces gets the zero quadric.
  quadrics_.resize(vertex_count_);
  for_chunks(vertex_count_, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t v = begin; v < end; ++v) quadrics_[v] = gather_quadric(std::uint32_t(v));
  });
  util::GrowOnlyVector<Plane>().swap(face_planes_);
}

Quadric Builder::gather_quadric(std::uint32_t u) const {
  Quadric q{};
  const std::uint32_t begin = adjacency_begin_[u], end = adjacency_end_[u];
  // A face that holds u twice is listed twice in a row; it has no area, so it adds no face plane,
  // and its boundary edges are visited once through its first listing.
  auto first_listing = [&](std::uint32_t i) {
    return i == begin || adjacency_[i].face != adjacency_[i - 1].face;
  };
  auto position = [&](std::uint32_t v) { return &unit_positions_[3 * std::size_t{v}]; };
  for (std::uint32_t i = begin; i < end; ++i) {
    if (!first_listing(i)) continue;
    const Plane& p = face_planes_[adjacency_[i].face];
    if (p.w != 0) add_plane(q, p.nx, p.ny, p.nz, p.d, p.w);
  }
  // Boundary edges: a plane through the edge, perpendicular to its face, holds the outline. An edge
  // (a, b) of face f is a boundary when no other face holds both a and b, which u's own fan tells
  // when u is one of them. (An edge with a = b adds nothing: its plane has no direction.)
  auto shared = [&](std::uint32_t f, std::uint32_t other) {
    for (std::uint32_t j = begin; j < end; ++j) {
      const Corner& g = adjacency_[j];
      if (g.face != f && (g.next == other || g.prev == other)) return true;
    }
    return false;
  };
  for (std::uint32_t i = begin; i < end; ++i) {
    if (!first_listing(i)) continue;
    const Corner& c = adjacency_[i];
    // Usual case: u once in the face, and both its edges shared.
    if (c.next != u && c.prev != u && shared(c.face, c.next) && shared(c.face, c.prev)) continue;
    const std::uint32_t* t = &working_[3 * std::size_t{c.face}];
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t a = t[k], b = t[(k + 1) % 3];
      if ((a != u && b != u) || a == b || shared(c.face, a == u ? b : a)) continue;
      const float* pa = position(a);
      const float* p0 = position(t[0]);
      const Vec3 e = sub(position(b), pa);
      const Vec3 n = cross(sub(position(t[1]), p0), sub(position(t[2]), p0));
      Vec3 m = cross(e, n);
      const double length = std::sqrt(dot(m, m));
      if (length == 0) continue;
      m = {m.x / length, m.y / length, m.z / length};
      const float d = float(-(m.x * pa[0] + m.y * pa[1] + m.z * pa[2]));
      const float w = float(dot(e, e)) * options_.boundary_weight;
      add_plane(q, float(m.x), float(m.y), float(m.z), d, w);
    }
  }
  return q;
}

template <class Keep>
std::size_t Builder::filter_in_halves(std::vector<std::uint32_t>& list, const Keep& keep) {
  // Each half keeps its survivors at the start of its own range (so the halves never write each
  // other's items), then the second half's are moved down behind the first's.
  const std::size_t count = list.size(), middle = count / 2;
  std::size_t kept[2];
  for_ranges(2, count, [&](std::size_t half) {
    const std::size_t begin = half == 0 ? 0 : middle, end = half == 0 ? middle : count;
    std::size_t out = begin;
    for (std::size_t i = begin; i < end; ++i)
      if (keep(list[i], half)) list[out++] = list[i];
    kept[half] = out - begin;
  });
  if (kept[0] != middle)
    std::copy(list.begin() + middle, list.begin() + middle + kept[1], list.begin() + kept[0]);
  list.resize(kept[0] + kept[1]);
  return kept[0];
}

void Builder::build_adjacency() {
  // Only what is alive is visited, so late passes over a small mesh cost little. The surviving
  // vertices get both their counts cleared on the way.
  filter_in_halves(alive_vertex_list_, [&](std::uint32_t v, std::size_t) {
    if (vertex_dead_[v]) return false;
    adjacency_end_[v] = 0, second_half_[v] = 0;
    return true;
  });
  // Two halves of the face list are filtered, counted and placed concurrently, each with its own
  // counts (adjacency_end_ and second_half_), so every vertex lists its faces in face order: the
  // first half's, then the second's.
  auto counts = [&](std::size_t half) { return half == 0 ? adjacency_end_.data() : second_half_.data(); };
  const std::size_t split = filter_in_halves(alive_face_list_, [&](std::uint32_t f, std::size_t half) {
    if (!face_alive_[f]) return false;
    std::uint32_t* count = counts(half);
    const std::uint32_t* t = &working_[3 * std::size_t{f}];
    ++count[t[0]], ++count[t[1]], ++count[t[2]];
    return true;
  });
  // Each vertex's list starts after those of the vertices before it in alive_vertex_list_: chunks
  // sum their vertices' counts, then lay out their lists after the earlier chunks'.
  const std::size_t vertices = alive_vertex_list_.size();
  const std::size_t total = chunk_starts(vertices, [&](std::size_t, std::size_t begin, std::size_t end) {
    std::size_t corners = 0;
    for (std::size_t i = begin; i < end; ++i) {
      const std::uint32_t v = alive_vertex_list_[i];
      corners += adjacency_end_[v] + second_half_[v];
    }
    return corners;
  });
  for_chunks(vertices, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
    auto next = std::uint32_t(chunk_counts_[chunk]);
    for (std::size_t i = begin; i < end; ++i) {
      const std::uint32_t v = alive_vertex_list_[i];
      adjacency_begin_[v] = next;
      const std::uint32_t first = adjacency_end_[v], second = second_half_[v];
      adjacency_end_[v] = next;        // where the first half's faces go
      second_half_[v] = next + first;  // where the second half's go
      next += first + second;
    }
  });
  adjacency_.resize(total);  // not filled: the halves write every slot
  for_ranges(2, alive_face_list_.size(), [&](std::size_t half) {
    std::uint32_t* cursor = counts(half);
    const std::size_t begin = half == 0 ? 0 : split, end = half == 0 ? split : alive_face_list_.size();
    for (std::size_t i = begin; i < end; ++i) {
      const std::uint32_t f = alive_face_list_[i];
      const std::uint32_t* t = &working_[3 * std::size_t{f}];
      for (int k = 0; k < 3; ++k) adjacency_[cursor[t[k]]++] = {f, t[(k + 1) % 3], t[(k + 2) % 3]};
    }
  });
  // The second half's cursors stopped at the end of each list.
  for_chunks(vertices, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i)
      adjacency_end_[alive_vertex_list_[i]] = second_half_[alive_vertex_list_[i]];
  });
}

VertexKind Builder::classify(std::uint32_t u, std::uint32_t& boundary_next,
                             std::uint32_t& boundary_prev) const {
  const std::uint32_t begin = adjacency_begin_[u], end = adjacency_end_[u];
  const std::uint32_t degree = end - begin;
  if (degree == 0) return kUnused;
  if (degree > kMaxFan) return kComplex;
  // Corners a (after u) and b (before u) of each face. Fans hold about 6 faces, so scanning these
  // small arrays beats marking shared per-vertex stamps, and leaves no state shared between chunks.
  std::array<std::uint32_t, kMaxFan> a, b, next;
  std::uint64_t has_previous = 0;  // bit j: some face's b is a[j]
  for (std::uint32_t i = 0; i < degree; ++i) {
    a[i] = adjacency_[begin + i].next;
    b[i] = adjacency_[begin + i].prev;
    // u exactly once in the face, and a face, not a segment.
    if (a[i] == u || b[i] == u || a[i] == b[i]) return kComplex;
    // Manifold fan: each edge (u, w) is walked at most once in each direction.
    for (std::uint32_t j = 0; j < i; ++j)
      if (a[j] == a[i] || b[j] == b[i]) return kComplex;
  }
  // next[i]: the face across edge (u, b[i]), whose a is b[i] (unique, as the a are distinct).
  int starts = 0, ends = 0;
  for (std::uint32_t i = 0; i < degree; ++i) {
    next[i] = kMaxFan;
    for (std::uint32_t j = 0; j < degree; ++j)
      if (a[j] == b[i]) {
        next[i] = j;
        break;
      }
    if (next[i] == kMaxFan)
      ++ends;
    else
      has_previous |= std::uint64_t{1} << next[i];
  }
  std::uint32_t start = 0;
  for (std::uint32_t i = 0; i < degree; ++i)
    if (!(has_previous >> i & 1)) ++starts, start = i;  // edge u→a has no face on its other side
  if (!((starts == 0 && ends == 0) || (starts == 1 && ends == 1))) return kComplex;
  // One fan, not several glued at u: walking across edges visits every face.
  std::uint32_t current = start, visited = 1;
  for (; visited < degree; ++visited) {
    if (next[current] == kMaxFan || next[current] == start) break;
    current = next[current];
  }
  if (visited != degree) return kComplex;
  if (starts == 0) return kInterior;
  boundary_next = a[start];
  boundary_prev = b[current];  // edge b[last]→u has no face on its other side either
  return kBoundary;
}

VertexKind Builder::classify_parity(std::uint32_t u) const {
  const std::uint32_t begin = adjacency_begin_[u], end = adjacency_end_[u];
  const std::uint32_t degree = end - begin;
  if (degree == 0) return kUnused;
  // Each face gives the edges (u, next) and (u, prev): sorted, a run of odd length is an odd edge.
  std::array<std::uint32_t, 2 * kMaxFan> small;
  std::vector<std::uint32_t> large;
  std::uint32_t* ends = small.data();
  if (degree > kMaxFan) {
    large.resize(2 * std::size_t{degree});
    ends = large.data();
  }
  for (std::uint32_t i = 0; i < degree; ++i) {
    const Corner& c = adjacency_[begin + i];
    if (c.next == u || c.prev == u || c.next == c.prev) return kComplex;
    ends[2 * i] = c.next;
    ends[2 * i + 1] = c.prev;
  }
  std::sort(ends, ends + 2 * std::size_t{degree});
  for (std::uint32_t i = 0; i < 2 * degree;) {
    std::uint32_t j = i;
    while (j < 2 * degree && ends[j] == ends[i]) ++j;
    if ((j - i) % 2 != 0) return kOdd;
    i = j;
  }
  return kEven;
}

template <class Body>
void Builder::for_ranges(std::size_t count, std::size_t items, const Body& body) {
  auto task = [](void* opaque, std::size_t i) { (*static_cast<const Body*>(opaque))(i); };
  if (options_.parallel_for == nullptr || items < kMinChunk) {
    for (std::size_t i = 0; i < count; ++i) task(const_cast<Body*>(&body), i);
  } else {
    options_.parallel_for(options_.parallel_user, count, task, const_cast<Body*>(&body));
  }
}

template <class Body>
void Builder::for_chunks(std::size_t count, const Body& body) {
  // Small ranges are not worth a hand-off; the chunk count does not depend on the runner.
  const std::size_t chunks = chunk_count(count);
  struct Context {
    const Body* body;
    std::size_t count, chunks;
  } context{&body, count, chunks};
  auto task = [](void* opaque, std::size_t chunk) {
    const Context& c = *static_cast<const Context*>(opaque);
    (*c.body)(chunk, c.count * chunk / c.chunks, c.count * (chunk + 1) / c.chunks);
  };
  if (chunks == 1 || options_.parallel_for == nullptr) {
    for (std::size_t chunk = 0; chunk < chunks; ++chunk) task(&context, chunk);
  } else {
    options_.parallel_for(options_.parallel_user, chunks, task, &context);
  }
}

template <class Count>
std::size_t Builder::chunk_starts(std::size_t count, const Count& count_chunk) {
  chunk_counts_.resize(chunk_count(count));
  for_chunks(count, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
    chunk_counts_[chunk] = count_chunk(chunk, begin, end);
  });
  std::size_t total = 0;
  for (std::size_t& n : chunk_counts_) total += std::exchange(n, total);
  return total;
}

void Builder::find_partner(std::uint32_t u, const std::uint32_t* boundary_ends) {
  Candidate& best = best_[u];
  // The partner's cost Q_u(v) only changes when u's quadric or fan does, i.e. when u was touched;
  // a cached partner that stopped being collapsible forces a new search too.
  const VertexKind kind = VertexKind(kind_[u]);
  const bool stale = pass_ == 1 || pass_ == topology_pass_ || touched_[u] == pass_ - 1 ||
                     (best.v != u && !is_target(kind, VertexKind(kind_[best.v]))) ||
                     (topology_phase_ && best.v != u && is_refused(u, best.v));
  if (!stale) return;
  best = Candidate{std::numeric_limits<float>::infinity(), u, u};
  auto consider = [&](std::uint32_t v) {
    const float cost = evaluate(quadrics_[u], &unit_positions_[3 * std::size_t{v}]);
    if (cost < best.cost) best.cost = cost, best.v = v;
  };
  if (kind == kEven || kind == kOdd) {
    for (std::uint32_t i = adjacency_begin_[u]; i < adjacency_end_[u]; ++i)
      for (const std::uint32_t w : {adjacency_[i].next, adjacency_[i].prev})
        if (is_target(kind, VertexKind(kind_[w])) && !is_refused(u, w)) consider(w);
  } else if (kind_[u] == kInterior) {
    for (std::uint32_t i = adjacency_begin_[u]; i < adjacency_end_[u]; ++i) {
      const std::uint32_t a = adjacency_[i].next;
      if (kind_[a] == kInterior || kind_[a] == kBoundary) consider(a);
    }
  } else if (kind_[u] == kBoundary) {
    // A boundary vertex only slides along its boundary, onto another boundary vertex.
    for (int e = 0; e < 2; ++e)
      if (kind_[boundary_ends[2 * u + e]] == kBoundary) consider(boundary_ends[2 * u + e]);
  }
}

// Asked for every candidate on the chooser's path: the checks share the link marks and one walk of
// u's fan, and each returns at the first failure, so they stay one function.
bool Builder::can_collapse(std::uint32_t u, std::uint32_t v, Stamps& stamps) const {
  std::vector<std::uint32_t>& link_stamp = stamps.link;
  const std::uint32_t link = ++stamps.stamp;
  link_stamp[v] = link;
  for (std::uint32_t i = adjacency_begin_[v]; i < adjacency_end_[v]; ++i)
    link_stamp[adjacency_[i].next] = link_stamp[adjacency_[i].prev] = link;
  std::uint32_t opposite[2] = {0, 0};
  int opposites = 0;
  if (!topology_phase_)
    for (std::uint32_t i = adjacency_begin_[u]; i < adjacency_end_[u]; ++i) {
      const std::uint32_t a = adjacency_[i].next, b = adjacency_[i].prev;
      if (a == v || b == v) {
        if (opposites == 2) return false;
        opposite[opposites++] = a == v ? b : a;
      }
    }
  // Link condition (first phase only): the only common neighbours of u and v are the corners
  // opposite edge uv. The topology phase drops it and keeps the geometric checks below.
  int survivors = 0;
  const float* pu = position(u);
  const float* pv = position(v);
  for (std::uint32_t i = adjacency_begin_[u]; i < adjacency_end_[u]; ++i) {
    const std::uint32_t a = adjacency_[i].next, b = adjacency_[i].prev;
    if (a == v || b == v) continue;
    // (A common neighbour met twice gets the same answer twice.)
    if (!topology_phase_)
      for (const std::uint32_t w : {a, b})
        if (link_stamp[w] == link &&
            !((opposites > 0 && w == opposite[0]) || (opposites > 1 && w == opposite[1])))
          return false;
    ++survivors;
    const float* pa = position(a);
    const float* pb = position(b);
    const Vec3 old_normal = cross(sub(pa, pu), sub(pb, pu));
    const Vec3 new_normal = cross(sub(pa, pv), sub(pb, pv));
    const double old_length = std::sqrt(dot(old_normal, old_normal));
    const double new_length = std::sqrt(dot(new_normal, new_normal));
    // Degenerate: area tiny against the longest edge squared (a sliver or a zero-area triangle).
    const Vec3 ab = sub(pb, pa), av = sub(pv, pa), bv = sub(pv, pb);
    const double longest = std::max({dot(ab, ab), dot(av, av), dot(bv, bv)});
    if (!(new_length > 1e-6 * longest)) return false;
    if (!(dot(old_normal, new_normal) > options_.min_normal_cos * old_length * new_length)) return false;
    // The new face (v, a, b) must not repeat a face v already has (a tetrahedron folding flat),
    // except in the last stage of the topology phase.
    if (!stacking_ && link_stamp[a] == link && link_stamp[b] == link) {
      for (std::uint32_t j = adjacency_begin_[v]; j < adjacency_end_[v]; ++j) {
        const Corner& t = adjacency_[j];  // the face (v, next, prev)
        const bool has_a = v == a || t.next == a || t.prev == a;
        const bool has_b = v == b || t.next == b || t.prev == b;
        if (has_a && has_b) return false;
      }
    }
    // Nor may two new faces share their corners a and b (a fan that holds one edge twice).
    if (topology_phase_ && !stacking_)
      for (std::uint32_t j = adjacency_begin_[u]; j < i; ++j) {
        const Corner& t = adjacency_[j];
        if (t.next != v && t.prev != v && ((t.next == a && t.prev == b) || (t.next == b && t.prev == a)))
          return false;
      }
  }
  // A collapse that leaves no face would make a node that removes nothing (detached from the DAG).
  if (survivors == 0) return false;
  // Every corner of u's fan must stay on a face the collapse makes (the link condition sees to it in
  // the first phase). A corner left only on faces that vanish would tie the node to no later
  // collapse of that corner, and a cut could then hold the node's faces after that corner's
  // collapse: a face on a vertex the cut no longer has.
  if (topology_phase_)
    for (std::uint32_t i = adjacency_begin_[u]; i < adjacency_end_[u]; ++i) {
      const std::uint32_t a = adjacency_[i].next, b = adjacency_[i].prev;
      if (a != v && b != v) continue;
      const std::uint32_t x = a == v ? b : a;
      bool kept = false;
      for (std::uint32_t j = adjacency_begin_[u]; j < adjacency_end_[u] && !kept; ++j) {
        const Corner& t = adjacency_[j];
        kept = t.next != v && t.prev != v && (t.next == x || t.prev == x);
      }
      if (!kept) return false;
    }
  return true;
}

// The chooser and the guesser are lambdas over one frame: they share the pass's atomics and the
// blocked test, which as members would be passed by reference into the per-candidate loop.
void Builder::choose_collapses(std::size_t quota) {
  // The chooser walks the candidates in cost order. can_collapse only reads the pass's starting
  // adjacency, so its answer for a candidate never depends on the choices before it: a guesser
  // (when a second thread runs it) answers candidates just ahead of the chooser, skipping those
  // already blocked, and the chooser asks can_collapse itself only where no answer is there yet.
  // The choice is therefore the same whether the guesser runs, lags or never starts.
  verdicts_.assign(candidates_.size(), 0);
  std::atomic<std::size_t> chooser_at{0};
  std::atomic<bool> chooser_done{false};
  auto is_touched = [this](std::uint32_t x) {
    return std::atomic_ref<std::uint32_t>(touched_[x]).load(std::memory_order_relaxed) == pass_;
  };
  auto touch = [this](std::uint32_t x) {
    std::atomic_ref<std::uint32_t>(touched_[x]).store(pass_, std::memory_order_relaxed);
  };
  auto target_of = [this](std::uint32_t x) {
    return std::atomic_ref<std::uint32_t>(ring_target_[x]).load(std::memory_order_relaxed);
  };
  auto set_target = [this](std::uint32_t x, std::uint32_t target) {
    std::atomic_ref<std::uint32_t>(ring_target_[x]).store(target, std::memory_order_relaxed);
  };
  // A candidate is blocked when an earlier choice of the pass changed u's fan, or v's fan in a
  // way can_collapse would not see: v is an end of a chosen collapse, or in two chosen fans, or in
  // the fan of a collapse into a neighbour w of u (then w becomes a common neighbour of u and v).
  // A fan that only had one neighbour x of v replaced by w, with w not next to u, gives the same
  // link, the same faces around u and so the same can_collapse answer as at the pass's start.
  auto blocked = [&](const Candidate& c) {
    if (is_touched(c.u)) return true;
    if (!is_touched(c.v)) return false;
    // Without the link condition a changed fan of v may matter however it changed.
    if (topology_phase_) return true;
    const std::uint32_t w = target_of(c.v);
    if (w == model::kNoVertex) return true;
    for (std::uint32_t j = adjacency_begin_[c.u]; j < adjacency_end_[c.u]; ++j)
      if (adjacency_[j].next == w || adjacency_[j].prev == w) return true;
    return false;
  };
  auto choose = [&] {
    std::size_t ordered = 0;
    std::uint32_t tag = std::uint32_t(collapse_u_.size()) + 1;
    std::uint32_t triangle = std::uint32_t(removing_collapse_.size());
    chosen_.clear();
    for (std::size_t i = 0; i < candidates_.size() && ordered < quota; ++i) {
      chooser_at.store(i, std::memory_order_relaxed);
      if (i + kPrefetchAhead < candidates_.size()) {
        const Candidate& ahead = candidates_[i + kPrefetchAhead];
        __builtin_prefetch(&touched_[ahead.u]);
        __builtin_prefetch(&touched_[ahead.v]);
        __builtin_prefetch(&adjacency_begin_[ahead.u]);
        __builtin_prefetch(&adjacency_begin_[ahead.v]);
        __builtin_prefetch(&adjacency_end_[ahead.u]);
      }
      // A chosen candidate marks its fan's corners: fetch, in stages, the fan of a nearer one
      // and then the marks of its corners (a candidate always has a face).
      if (i + kPrefetchAhead / 2 < candidates_.size()) {
        const Candidate& ahead = candidates_[i + kPrefetchAhead / 2];
        __builtin_prefetch(&adjacency_[adjacency_begin_[ahead.u]]);
        __builtin_prefetch(&adjacency_[adjacency_end_[ahead.u] - 1]);
      }
      if (i + 2 < candidates_.size()) {
        const Candidate& ahead = candidates_[i + 2];
        if (!is_touched(ahead.u))
          for (std::uint32_t j = adjacency_begin_[ahead.u]; j < adjacency_end_[ahead.u]; ++j) {
            __builtin_prefetch(&touched_[adjacency_[j].next]);
            __builtin_prefetch(&ring_target_[adjacency_[j].next]);
          }
      }
      const Candidate& c = candidates_[i];
      if (blocked(c)) {
        ++ordered;
        continue;
      }
      const std::uint8_t verdict =
          std::atomic_ref<std::uint8_t>(verdicts_[i]).load(std::memory_order_relaxed);
      if (verdict == 2 || (verdict == 0 && !can_collapse(c.u, c.v, chooser_stamps_))) {
        if (topology_phase_) refused_now_.push_back(std::uint64_t{c.u} << 32 | c.v);
        continue;
      }
      chosen_.push_back({c.u, c.v, tag++, triangle, 1});  // u joins the points (its fan's: counted later)
      for (const std::uint32_t x : {c.u, c.v}) {
        touch(x);
        set_target(x, model::kNoVertex);
      }
      auto ring_touch = [&](std::uint32_t x) {
        if (!is_touched(x)) {
          touch(x);
          set_target(x, c.v);
        } else if (target_of(x) != c.v) {
          set_target(x, model::kNoVertex);
        }
      };
      for (std::uint32_t j = adjacency_begin_[c.u]; j < adjacency_end_[c.u]; ++j) {
        const Corner& t = adjacency_[j];  // the face (u, next, prev)
        ring_touch(t.next);
        ring_touch(t.prev);
        if (t.next == c.v || t.prev == c.v)
          --alive_faces_;
        else
          ++triangle;
      }
      ++ordered;
      if (alive_faces_ <= target_triangles_) break;
    }
    chosen_triangles_end_ = triangle;
    chooser_done.store(true, std::memory_order_relaxed);
  };
  auto guess = [&] {
    // Stays a little ahead of the chooser; alone (run before or after it) it does little or nothing.
    const std::size_t end = std::min(candidates_.size(), 2 * quota);
    for (std::size_t i = 0; i < end && !chooser_done.load(std::memory_order_relaxed); ++i) {
      const std::size_t at = chooser_at.load(std::memory_order_relaxed);
      if (i <= at) i = at + kGuessLead;
      if (i >= end) break;
      if (i + kPrefetchAhead < end) {
        const Candidate& ahead = candidates_[i + kPrefetchAhead];
        for (const std::uint32_t x : {ahead.u, ahead.v}) {
          __builtin_prefetch(&adjacency_begin_[x]);
          __builtin_prefetch(&adjacency_end_[x]);
          __builtin_prefetch(position(x));
        }
      }
      if (i + kPrefetchAhead / 2 < end) {
        const Candidate& ahead = candidates_[i + kPrefetchAhead / 2];
        for (const std::uint32_t x : {ahead.u, ahead.v}) __builtin_prefetch(&adjacency_[adjacency_begin_[x]]);
      }
      const Candidate& c = candidates_[i];
      if (blocked(c)) continue;
      const std::uint8_t verdict = can_collapse(c.u, c.v, guesser_stamps_) ? 1 : 2;
      std::atomic_ref<std::uint8_t>(verdicts_[i]).store(verdict, std::memory_order_relaxed);
    }
  };
  if (options_.parallel_for == nullptr || candidates_.size() < kMinChunk) {
    choose();
    return;
  }
  for_ranges(2, candidates_.size(), [&](std::size_t task) { task == 0 ? choose() : guess(); });
}

// One collapse, the builder's hottest code: the fan rewrite, the points' distances and their
// placement share the moving points, the new faces and the running error of one fan.
void Builder::collapse(const Chosen& chosen, Scratch& scratch) {
  // Only faces of u's fan and vertices assigned to them are written, and the pass's choice keeps
  // the fans of its collapses disjoint, so collapses of one pass may run concurrently.
  const std::uint32_t u = chosen.u, v = chosen.v, tag = chosen.tag;
  std::vector<Moving>& moving = scratch.moving;
  std::vector<std::uint32_t>& new_faces_ = scratch.new_faces;
  // Errors never drop from a node to its children, so the fan's largest error is a floor.
  float fan_error = 0;
  // Original vertices that leave with the fan: u itself and those assigned to u's faces.
  moving.clear();
  moving.push_back({{position(u)[0], position(u)[1], position(u)[2]}, model::kNoFace, 0});
  new_faces_.clear();
  std::uint32_t triangle = chosen.first_triangle;
  for (std::uint32_t i = adjacency_begin_[u]; i < adjacency_end_[u]; ++i) {
    const std::uint32_t f = adjacency_[i].face;
    std::uint32_t* t = &working_[3 * std::size_t{f}];
    creating_collapse_[face_mt_[f]] = tag;
    fan_error = std::max(fan_error, face_error_[f]);
    const bool survives = !(t[0] == v || t[1] == v || t[2] == v);
    const std::uint32_t local = survives ? std::uint32_t(new_faces_.size()) : model::kNoFace;
    const float* run = &points_[3 * std::size_t{face_first_point_[f]}];
    for (std::uint32_t k = 0; k < face_points_[f]; ++k, run += 3)
      moving.push_back({{run[0], run[1], run[2]}, local, 0});
    face_points_[f] = 0;
    if (!survives) {
      face_alive_[f] = 0;
      continue;
    }
    for (int k = 0; k < 3; ++k)
      if (t[k] == u) t[k] = v;
    new_faces_.push_back(f);
    face_mt_[f] = triangle;
    std::copy(t, t + 3, &mt_vertices_[3 * std::size_t{triangle}]);
    removing_collapse_[triangle] = tag;
    creating_collapse_[triangle] = 0;
    ++triangle;
  }

  // Jade-style global error: each moving vertex goes to a new face and the error is the largest
  // exact distance. A vertex stays on its own face (or takes the first face found) when that is
  // already within the running maximum, since a nearer face could not lower the maximum.
  // Most points stay within the running maximum of the face they try first; WithinTest tells that
  // from the point's plane distance, and the exact distance is computed only when it cannot.
  std::vector<WithinTest>& within = scratch.within;
  within.resize(new_faces_.size());
  for (std::size_t i = 0; i < new_faces_.size(); ++i) {
    const std::uint32_t* t = &working_[3 * std::size_t{new_faces_[i]}];
    within[i].set(position(t[0]), position(t[1]), position(t[2]));
  }
  double measured = fan_error;
  for (Moving& m : moving) {
    const float* p = m.position;
    std::uint32_t best_face = model::kNoFace;
    double best = std::numeric_limits<double>::infinity();
    const double floor2 = measured * measured;
    auto try_face = [&](std::uint32_t i) {
      // Reached only while best > floor2, so a face within floor2 is the exact answer's choice too.
      if (within[i].within(p, floor2)) {
        best = floor2, best_face = i;
        return;
      }
      const std::uint32_t* t = &working_[3 * std::size_t{new_faces_[i]}];
      const double d2 = point_triangle_distance_squared(p, position(t[0]), position(t[1]), position(t[2]));
      if (d2 < best) best = d2, best_face = i;
    };
    if (m.old_face != model::kNoFace) try_face(m.old_face);
    for (std::uint32_t i = 0; i < new_faces_.size() && !(best <= floor2); ++i)
      if (i != m.old_face) try_face(i);
    // best <= measured² gives sqrt(best) <= measured (sqrt is correctly rounded): no sqrt on the
    // running maximum's chain for the usual point that stays within it.
    if (!(best <= floor2)) measured = std::max(measured, std::sqrt(best));
    m.new_face = best_face;
  }
  // Each new face's run, in the chosen block of the pool, in reversed order of arrival. The order
  // decides which faces later collapses try first for each point, and so the errors: another
  // order gives other (equally valid) .mt files.
  std::vector<std::uint32_t>& ends = scratch.new_face_ends;
  ends.assign(new_faces_.size(), 0);
  for (const Moving& m : moving) ++ends[m.new_face];
  std::uint32_t next_point = chosen.first_point;
  for (std::size_t i = 0; i < new_faces_.size(); ++i) {
    face_first_point_[new_faces_[i]] = next_point;
    face_points_[new_faces_[i]] = ends[i];
    next_point += ends[i];
    ends[i] = next_point;
  }
  for (const Moving& m : moving)
    std::copy(m.position, m.position + 3, &points_[3 * std::size_t{--ends[m.new_face]}]);
  // Round up so the float bound is never below the computed distance.
  const float error = std::nextafter(float(measured), std::numeric_limits<float>::max());

  for (const std::uint32_t f : new_faces_) face_error_[f] = error;
  add_quadric(quadrics_[v], quadrics_[u]);
  vertex_dead_[u] = 1;
  collapse_u_[tag - 1] = u;
  collapse_error_[tag - 1] = error;
}

void Builder::grow_pool(std::size_t size) {
  if (size <= points_.capacity()) {
    points_.resize(size);
    return;
  }
  // A big pool's copy and the first touch of its new pages are worth doing on every thread.
  util::GrowOnlyVector<float> bigger;
  bigger.reserve(std::max(size, 2 * points_.capacity()));
  bigger.resize(size);
  for_chunks(points_.size(), [&](std::size_t, std::size_t begin, std::size_t end) {
    std::copy(points_.begin() + std::ptrdiff_t(begin), points_.begin() + std::ptrdiff_t(end),
              bigger.begin() + std::ptrdiff_t(begin));
  });
  points_.swap(bigger);
}

void Builder::compact_assigned_points() {
  // Runs in face order: each chunk of faces sums its points, then copies its runs after the
  // earlier chunks'.
  const std::size_t total = chunk_starts(face_count_, [&](std::size_t, std::size_t begin, std::size_t end) {
    std::size_t points = 0;
    for (std::size_t f = begin; f < end; ++f) points += face_points_[f];
    return points;
  });
  points_scratch_.resize(3 * total);
  for_chunks(face_count_, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
    std::size_t next = chunk_counts_[chunk];
    for (std::size_t f = begin; f < end; ++f) {
      if (face_points_[f] == 0) continue;
      const auto run = points_.begin() + 3 * std::ptrdiff_t{face_first_point_[f]};
      std::copy(run, run + 3 * std::ptrdiff_t{face_points_[f]},
                points_scratch_.begin() + 3 * std::ptrdiff_t(next));
      face_first_point_[f] = std::uint32_t(next);
      next += face_points_[f];
    }
  });
  points_.swap(points_scratch_);
  // A block of an out-of-core build may carry most of the model's points: it gives the old pool
  // back rather than keep it for the next compaction (peak: the pool, its slack and one copy).
  if (block_) util::GrowOnlyVector<float>().swap(points_scratch_);
}

model::Mt Builder::assemble(std::vector<std::uint32_t>* vertex_ids) {
  model::MtArrays mt;
  mt.positions = mesh_.positions;
  mt.normals = mesh_.normals;
  normal_repair_ = repair_normals(mt.normals, mesh_.positions, mesh_.triangles);
  mt.colors = mesh_.colors;

  const std::uint32_t k = std::uint32_t(collapse_u_.size());
  const std::size_t node_count = std::size_t{k} + 1;
  const std::size_t mt_count = removing_collapse_.size();
  // Cuts walk the node arrays front to back instead of jumping around (number_nodes).
  const std::vector<std::uint32_t> node_of = number_nodes(collapse_error_);
  // Creator and remover node of every triangle, looked up once.
  util::GrowOnlyVector<std::uint32_t> creators(mt_count), removers(mt_count);  // written below
  for_chunks(mt_count, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t t = begin; t < end; ++t) {
      creators[t] = creating_collapse_[t] == 0 ? 0u : node_of[creating_collapse_[t] - 1];
      removers[t] = removing_collapse_[t] == 0 ? model::kNoNode : node_of[removing_collapse_[t] - 1];
    }
  });

  std::vector<std::uint32_t> vertex_id = number_vertices(node_of);
  const auto renumber = [&](auto& values) {
    if (values.empty()) return;
    auto by_id = values;
    for (std::uint32_t v = 0; v < vertex_count_; ++v)
      std::copy_n(&values[3 * std::size_t{v}], 3, &by_id[3 * std::size_t{vertex_id[v]}]);
    values = std::move(by_id);
  };
  renumber(mt.positions);
  renumber(mt.normals);
  renumber(mt.colors);

  mt.node_vertex.resize(node_count);
  mt.node_error.resize(node_count);
  mt.node_vertex[0] = model::kNoVertex;
  mt.node_error[0] = 0;
  for (std::uint32_t c = 0; c < k; ++c) {
    mt.node_vertex[node_of[c]] = vertex_id[collapse_u_[c]];
    mt.node_error[node_of[c]] = collapse_error_[c];
  }

  place_triangles(mt, creators, removers, vertex_id);
  link_parents(mt, node_of, creators);
  if (vertex_ids) *vertex_ids = std::move(vertex_id);
  return model::Mt(std::move(mt));
}

std::vector<std::uint32_t> Builder::number_vertices(const std::vector<std::uint32_t>& node_of) const {
  const std::uint32_t k = std::uint32_t(collapse_u_.size());
  // Vertex ids follow the nodes: the root mesh's vertices first (by input id), then node n's split
  // vertex as id R + n − 1, then the vertices no triangle uses. A refinement reads each node's
  // split vertex (its position, its allowed error) as it reaches the node, and it reaches nodes
  // roughly in id order, so these reads walk the vertex arrays as they walk the node arrays.
  std::vector<std::uint32_t> vertex_id(vertex_count_, model::kNoVertex);
  std::vector<std::uint8_t> kind(vertex_count_, 0);  // 0 unused, 1 in the root mesh, 2 split
  for (const std::uint32_t v : mesh_.triangles) kind[v] = 1;
  for (const std::uint32_t u : collapse_u_) kind[u] = 2;
  std::uint32_t next = 0;
  for (std::uint32_t v = 0; v < vertex_count_; ++v)
    if (kind[v] == 1) vertex_id[v] = next++;
  for (std::uint32_t c = 0; c < k; ++c) vertex_id[collapse_u_[c]] = next + node_of[c] - 1;
  next += k;
  for (std::uint32_t v = 0; v < vertex_count_; ++v)
    if (kind[v] == 0) vertex_id[v] = next++;
  return vertex_id;
}

void Builder::place_triangles(model::MtArrays& mt, const util::GrowOnlyVector<std::uint32_t>& creators,
                              const util::GrowOnlyVector<std::uint32_t>& removers,
                              const std::vector<std::uint32_t>& vertex_id) {
  const std::size_t node_count = collapse_u_.size() + 1;
  const std::size_t mt_count = removing_collapse_.size();
  // Counting sort of triangles by creating node.
  mt.node_triangle_offsets.assign(node_count + 1, 0);
  for (std::size_t t = 0; t < mt_count; ++t) ++mt.node_triangle_offsets[creators[t] + 1];
  for (std::size_t n = 0; n < node_count; ++n) mt.node_triangle_offsets[n + 1] += mt.node_triangle_offsets[n];
  std::vector<std::uint32_t> next(mt.node_triangle_offsets.begin(), mt.node_triangle_offsets.end() - 1);
  util::GrowOnlyVector<std::uint32_t> new_id(mt_count);  // written below
  for (std::size_t t = 0; t < mt_count; ++t) new_id[t] = next[creators[t]]++;

  const std::size_t root_count = mt.node_triangle_offsets[1];
  // The two big arrays are zero-filled by their resize: concurrently.
  for_ranges(2, mt_count, [&](std::size_t array) {
    if (array == 0) {
      mt.triangle_corners.resize(2 * mt_count);
    } else {
      mt.root_first_corner.resize(root_count);
      mt.triangle_remover.resize(mt_count);
    }
  });
  // Each triangle writes its own slots: triangles run concurrently.
  for_chunks(mt_count, [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t t = begin; t < end; ++t) {
      const std::uint32_t n = creators[t], id = new_id[t];
      const std::uint32_t tv[3] = {vertex_id[mt_vertices_[3 * t]], vertex_id[mt_vertices_[3 * t + 1]],
                                   vertex_id[mt_vertices_[3 * t + 2]]};
      int first = 0;
      if (n == 0) {
        mt.root_first_corner[id] = tv[0];
      } else {
        // Every triangle of node n surrounded its split vertex before the collapse.
        first = tv[0] == mt.node_vertex[n] ? 0 : (tv[1] == mt.node_vertex[n] ? 1 : 2);
        assert(tv[first] == mt.node_vertex[n]);
      }
      mt.triangle_corners[2 * std::size_t{id}] = tv[(first + 1) % 3];
      mt.triangle_corners[2 * std::size_t{id} + 1] = tv[(first + 2) % 3];
      mt.triangle_remover[id] = removers[t];
    }
  });
}

void Builder::link_parents(model::MtArrays& mt, const std::vector<std::uint32_t>& node_of,
                           const util::GrowOnlyVector<std::uint32_t>& creators) {
  const std::uint32_t k = std::uint32_t(collapse_u_.size());
  const std::size_t node_count = std::size_t{k} + 1;
  const std::size_t mt_count = removing_collapse_.size();
  // Parents: distinct creators of each node's removed triangles, sorted. The triangles a collapse
  // made are one run, and the runs follow collapse order (after the input's triangles), so each
  // node's list comes from one run; runs are independent.
  std::vector<std::uint32_t> run_begin(std::size_t{k} + 1, std::uint32_t(mt_count));
  for (std::size_t t = mt_count; t-- > 0;)
    if (removing_collapse_[t] != 0) run_begin[removing_collapse_[t] - 1] = std::uint32_t(t);
  for (std::uint32_t c = k; c-- > 0;) run_begin[c] = std::min(run_begin[c], run_begin[c + 1]);
  const std::uint32_t parents_base = run_begin[0];  // mt_count when there are no collapses
  std::vector<std::uint32_t> parents(mt_count - parents_base);
  std::vector<std::uint32_t> parent_count(node_count, 0);
  for_chunks(k, [&](std::size_t, std::size_t first, std::size_t last) {
    for (std::size_t c = first; c < last; ++c) {
      // Sorted distinct creators, written at the start of the run's own slice of parents.
      std::uint32_t* out = parents.data() + (run_begin[c] - parents_base);
      std::uint32_t* const start = out;
      for (std::uint32_t t = run_begin[c]; t < run_begin[c + 1]; ++t) {
        assert(removing_collapse_[t] == c + 1);
        *out++ = creators[t];
      }
      std::sort(start, out);
      parent_count[node_of[c]] = std::uint32_t(std::unique(start, out) - start);
    }
  });
  mt.node_parent_offsets.assign(node_count + 1, 0);
  for (std::size_t n = 0; n < node_count; ++n)
    mt.node_parent_offsets[n + 1] = mt.node_parent_offsets[n] + parent_count[n];
  mt.node_parents.resize(mt.node_parent_offsets[node_count]);
  for_chunks(k, [&](std::size_t, std::size_t first, std::size_t last) {
    for (std::size_t c = first; c < last; ++c) {
      const std::uint32_t n = node_of[c];
      std::copy_n(parents.data() + (run_begin[c] - parents_base), parent_count[n],
                  mt.node_parents.data() + mt.node_parent_offsets[n]);
    }
  });
}

Status Builder::check_mesh() const {
  if (mesh_.positions.size() % 3 != 0 || mesh_.triangles.size() % 3 != 0)
    return make_error(ErrorCode::kInvalidArgument, "mesh arrays are not multiples of 3");
  if (!mesh_.normals.empty() && mesh_.normals.size() != mesh_.positions.size())
    return make_error(ErrorCode::kInvalidArgument, "mesh normals do not match its vertex count");
  if (!mesh_.colors.empty() && mesh_.colors.size() != mesh_.positions.size())
    return make_error(ErrorCode::kInvalidArgument, "mesh colors do not match its vertex count");
  // Each collapse adds fewer faces than the input has corners, so 5 × triangles bounds every count.
  if (vertex_count_ >= model::kNoVertex || face_count_ * 15 >= model::kNoFace)
    return make_error(ErrorCode::kLimitExceeded,
                      "mesh with " + std::to_string(face_count_) + " triangles exceeds 32-bit MT ids");
  for (std::size_t i = 0; i < mesh_.positions.size(); ++i)
    if (!std::isfinite(mesh_.positions[i]))
      return make_error(ErrorCode::kInvalidArgument,
                        "vertex " + std::to_string(i / 3) + " has a non-finite coordinate");
  for (std::size_t i = 0; i < mesh_.triangles.size(); ++i)
    if (mesh_.triangles[i] >= vertex_count_)
      return make_error(ErrorCode::kInvalidArgument, "triangle " + std::to_string(i / 3) + " has vertex id " +
                                                         std::to_string(mesh_.triangles[i]) +
                                                         " >= vertex count " + std::to_string(vertex_count_));
  return Ok{};
}

Status Builder::prepare() {
  vertex_count_ = mesh_.vertex_count();
  face_count_ = mesh_.triangle_count();
  MTLOD_RETURN_IF_ERROR(check_mesh());
  if (block_) MTLOD_RETURN_IF_ERROR(check_block());

  alive_faces_ = face_count_;
  // Three independent groups of arrays (each first touched here), filled concurrently.
  for_ranges(3, face_count_, [&](std::size_t group) {
    if (group == 0) {
      working_ = mesh_.triangles;
      mt_vertices_.reserve(9 * face_count_);
      mt_vertices_.assign(mesh_.triangles.begin(), mesh_.triangles.end());
    } else if (group == 1) {
      face_alive_.assign(face_count_, 1);
      face_mt_.resize(face_count_);
      std::iota(face_mt_.begin(), face_mt_.end(), 0u);
      alive_face_list_.resize(face_count_);
      std::iota(alive_face_list_.begin(), alive_face_list_.end(), 0u);
      if (block_ && !block_->face_error.empty()) {
        face_error_ = block_->face_error;
      } else {
        face_error_.assign(face_count_, 0.0f);
      }
      removing_collapse_.reserve(3 * face_count_);
      creating_collapse_.reserve(3 * face_count_);
      removing_collapse_.assign(face_count_, 0);
      creating_collapse_.assign(face_count_, 0);
      face_first_point_.assign(face_count_, 0);
      face_points_.assign(face_count_, 0);
      if (block_ && !block_->face_points.empty()) {
        face_points_ = block_->face_points;
        std::uint32_t first = 0;
        for (std::size_t f = 0; f < face_count_; ++f) face_first_point_[f] = first, first += face_points_[f];
        points_ = std::move(block_->points);
      }
    } else {
      // Vertices no face uses never enter the lists.
      std::vector<std::uint8_t> used(vertex_count_, 0);
      for (const std::uint32_t v : mesh_.triangles) used[v] = 1;
      for (std::uint32_t v = 0; v < vertex_count_; ++v)
        if (used[v]) alive_vertex_list_.push_back(v);
      used_vertices_ = alive_vertex_list_.size();
      collapse_u_.reserve(vertex_count_);
      collapse_error_.reserve(vertex_count_);
      kind_.assign(vertex_count_, kUnused);
      adjacency_begin_.assign(vertex_count_, 0);
      adjacency_end_.assign(vertex_count_, 0);
      second_half_.assign(vertex_count_, 0);
      vertex_dead_.assign(vertex_count_, 0);
      touched_.assign(vertex_count_, 0);
      ring_target_.assign(vertex_count_, model::kNoVertex);
      for (Stamps* stamps : {&chooser_stamps_, &guesser_stamps_}) stamps->link.assign(vertex_count_, 0);
      best_.assign(vertex_count_, Candidate{0, 0, 0});
    }
  });
  scratch_.resize(kChunks);
  points_bound_ = points_.size() / 3 + used_vertices_;
  if (block_) {
    for (std::uint32_t v = 0; v < vertex_count_; ++v)
      if (block_->locked[v]) kind_[v] = kLocked;
  }
  return Ok{};
}

void Builder::simplify() {
  build_adjacency();
  init_quadrics();
  boundary_ends_.resize(2 * vertex_count_);
  const double initial_faces = double(std::max<std::size_t>(face_count_, 1));
  for (;;) {
    ++pass_;
    if (pass_ > 1) build_adjacency();
    classify_vertices();
    std::size_t collapses = 0, refusals = 0;
    if (collect_candidates() > 0) {
      refused_now_.clear();
      choose_collapses(pass_quota());
      collapses = chosen_.size();
      refusals = refused_now_.size();
      for (const std::uint64_t pair : refused_now_) refused_[pair] = pass_;
      place_collapses();
      run_collapses();
      if (options_.progress)
        options_.progress(options_.progress_user, 1.0 - double(alive_faces_) / initial_faces);
    }
    if (alive_faces_ <= target_triangles_) break;
    if (collapses == 0 && refusals == 0) {
      if (stacking_ || !options_.coarse_topology) break;
      // Nothing that keeps the topology is left: go on with collapses that may change it, and
      // when those are stuck too, with collapses that may stack a face on another. The next pass
      // classifies every vertex and finds every partner again.
      if (topology_phase_) {
        stacking_ = true;
        stacking_first_ = collapse_u_.size();
        refused_.clear();
      } else {
        topology_phase_ = true;
        topology_first_ = collapse_u_.size();
      }
      topology_pass_ = pass_ + 1;
    }
  }
}

void Builder::classify_vertices() {
  // A vertex's kind only changes when its fan does, i.e. when the last pass touched it. An
  // interior vertex touched only as a corner of one collapse stays interior: its cycle of
  // neighbours had u replaced by v, or lost u next to v, and the link condition kept v out of
  // the rest of the cycle.
  for_chunks(alive_vertex_list_.size(), [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      const std::uint32_t u = alive_vertex_list_[i];
      if (kind_[u] == kLocked) continue;
      if (topology_phase_) {
        if (pass_ == topology_pass_ || touched_[u] == pass_ - 1) kind_[u] = classify_parity(u);
      } else if (pass_ == 1 || (touched_[u] == pass_ - 1 &&
                                (kind_[u] != kInterior || ring_target_[u] == model::kNoVertex))) {
        kind_[u] = classify(u, boundary_ends_[2 * u], boundary_ends_[2 * u + 1]);
      }
    }
  });
}

std::size_t Builder::collect_candidates() {
  // Each chunk of vertices counts its candidates, then places them after the earlier chunks':
  // the candidates are in vertex order before the sort.
  const std::size_t vertices = alive_vertex_list_.size();
  chunk_complex_.resize(chunk_count(vertices));
  const std::size_t total =
      chunk_starts(vertices, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
        std::size_t found = 0, complex = 0;
        for (std::size_t i = begin; i < end; ++i) {
          const std::uint32_t u = alive_vertex_list_[i];
          find_partner(u, boundary_ends_.data());
          found += best_[u].v != u;
          complex += kind_[u] == kComplex;
        }
        chunk_complex_[chunk] = complex;
        return found;
      });
  complex_vertices_ = std::accumulate(chunk_complex_.begin(), chunk_complex_.end(), std::size_t{0});
  if (total == 0) return 0;
  candidates_.resize(total);
  for_chunks(vertices, [&](std::size_t chunk, std::size_t begin, std::size_t end) {
    std::size_t next = chunk_counts_[chunk];
    for (std::size_t i = begin; i < end; ++i)
      if (const std::uint32_t u = alive_vertex_list_[i]; best_[u].v != u) candidates_[next++] = best_[u];
  });
  sort_by_cost(candidates_, candidate_scratch_);
  return total;
}

std::size_t Builder::pass_quota() {
  // Choose in cost order; the quota counts candidates that took part in the order (chosen, or
  // blocked by an earlier choice of this pass); invalid ones are skipped without using it up.
  // A chosen collapse changes u's fan, so its corners are marked touched; a later choice never
  // writes a face it wrote, and can_collapse's answer from the pass's start still holds (see
  // choose_collapses).
  return std::max<std::size_t>(1, std::size_t(double(candidates_.size()) * options_.pass_fraction));
}

void Builder::place_collapses() {
  // Each pass moves every assigned point at most once; room for that keeps the pool's indices
  // valid while chunks append to their chosen blocks.
  if (points_.size() / 3 + points_bound_ > (block_ ? kBlockPoolSlack : kPoolSlack) * points_bound_)
    compact_assigned_points();
  std::uint32_t point = std::uint32_t(points_.size() / 3);
  const std::uint32_t tag = std::uint32_t(collapse_u_.size() + chosen_.size()) + 1;
  const std::uint32_t triangle = chosen_triangles_end_;
  // Run the collapses in vertex order: neighbouring collapses then share cache lines, and the
  // pool's blocks follow the mesh. Tags and triangles keep the cost order. (A vertex is u of
  // at most one collapse.)
  util::radix_sort(chosen_, chosen_scratch_, [](const Chosen& c) { return c.u; });
  // The points each collapse moves, counted concurrently.
  for_chunks(chosen_.size(), [&](std::size_t, std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      Chosen& c = chosen_[i];
      for (std::uint32_t j = adjacency_begin_[c.u]; j < adjacency_end_[c.u]; ++j)
        c.first_point += face_points_[adjacency_[j].face];
    }
  });
  // Collapses are chunked by work, not by count: the late passes make a few hundred collapses
  // that each move thousands of assigned points. A collapse costs about as much as moving
  // kFanWork points, besides the points it moves. Each gets its block of the pool meanwhile.
  collapse_work_ = 0;
  for (const Chosen& c : chosen_) collapse_work_ += c.first_point + kFanWork;
  const std::size_t chunks = std::clamp<std::size_t>(collapse_work_ / kMinChunkWork, 1, kChunks);
  collapse_chunk_begin_.assign(1, 0);
  std::size_t work = 0;
  for (std::size_t i = 0; i < chosen_.size(); ++i) {
    Chosen& c = chosen_[i];
    work += c.first_point + kFanWork;
    if (collapse_chunk_begin_.size() < chunks &&
        work * chunks >= collapse_chunk_begin_.size() * collapse_work_)
      collapse_chunk_begin_.push_back(i + 1);
    const std::uint32_t count = c.first_point;
    c.first_point = point;
    point += count;
  }
  collapse_chunk_begin_.push_back(chosen_.size());
  collapse_u_.resize(tag - 1);
  collapse_error_.resize(tag - 1);
  mt_vertices_.resize(3 * std::size_t{triangle});
  removing_collapse_.resize(triangle);
  creating_collapse_.resize(triangle);
  grow_pool(3 * std::size_t{point});
}

void Builder::run_collapses() {
  for_ranges(collapse_chunk_begin_.size() - 1, collapse_work_, [&](std::size_t chunk) {
    const std::size_t begin = collapse_chunk_begin_[chunk], end = collapse_chunk_begin_[chunk + 1];
    for (std::size_t i = begin; i < end; ++i) {
      // The collapses' data is scattered: ask for the next ones' early, in stages that each
      // read what the stage before fetched.
      if (i + 3 * kPrefetchAhead < end) prefetch_collapse(chosen_[i + 3 * kPrefetchAhead]);
      if (i + 2 * kPrefetchAhead < end) prefetch_fan(chosen_[i + 2 * kPrefetchAhead].u);
      if (i + kPrefetchAhead < end) prefetch_fan_data(chosen_[i + kPrefetchAhead].u);
      collapse(chosen_[i], scratch_[chunk]);
    }
  });
  // Near the top of a large build one collapse can move millions of points; a block does not keep
  // that much scratch per chunk for the passes after.
  if (block_)
    for (Scratch& scratch : scratch_)
      if (scratch.moving.capacity() > kKeptMovingPoints) std::vector<Moving>().swap(scratch.moving);
}

Status Builder::check_block() const {
  const BlockInput& block = *block_;
  auto invalid = [](const std::string& what) {
    return make_error(ErrorCode::kInvalidArgument, "block: " + what);
  };
  if (block.locked.size() != vertex_count_) return invalid("locked flags do not match the vertex count");
  if (!block.face_error.empty()) {
    if (block.face_error.size() != face_count_) return invalid("face errors do not match the face count");
    for (const float e : block.face_error)
      if (!(e >= 0 && std::isfinite(e))) return invalid("a face error is negative or not finite");
  }
  std::uint64_t points = 0;
  if (!block.face_points.empty()) {
    if (block.face_points.size() != face_count_) return invalid("point counts do not match the face count");
    for (const std::uint32_t n : block.face_points) points += n;
  }
  if (3 * points != block.points.size()) return invalid("points do not match their counts");
  if (points + vertex_count_ >= model::kNoVertex) return invalid("too many points for 32-bit ids");
  for (const float x : block.points)
    if (!std::isfinite(x)) return invalid("a point has a non-finite coordinate");
  return Ok{};
}

BlockOutput Builder::export_block() {
  BlockOutput out;
  topology_stats(out);
  out.collapse_u = std::move(collapse_u_);
  out.collapse_error = std::move(collapse_error_);
  out.made_triangles.assign(mt_vertices_.begin() + 3 * std::ptrdiff_t(face_count_), mt_vertices_.end());
  out.made_by.assign(removing_collapse_.begin() + std::ptrdiff_t(face_count_), removing_collapse_.end());
  out.taken_by.assign(creating_collapse_.begin(), creating_collapse_.end());
  for (std::size_t f = 0; f < face_count_; ++f) {
    if (!face_alive_[f]) continue;
    out.remaining.push_back(face_mt_[f]);
    out.remaining_error.push_back(face_error_[f]);
    out.remaining_points.push_back(face_points_[f]);
  }
  // Compacted, the pool holds the alive faces' runs in face order (the dead ones hold none).
  compact_assigned_points();
  util::GrowOnlyVector<float>().swap(points_scratch_);
  out.points = std::move(points_);
  out.passes = pass_;
  out.complex_vertices = complex_vertices_;
  return out;
}

Result<BlockOutput> Builder::run_block(std::size_t target_triangles) {
  target_triangles_ = target_triangles;
  MTLOD_RETURN_IF_ERROR(prepare());
  simplify();
  return export_block();
}

Result<model::Mt> Builder::run(BuildStats* stats, std::vector<std::uint32_t>* vertex_ids) {
  target_triangles_ = options_.min_triangles;
  MTLOD_RETURN_IF_ERROR(prepare());
  simplify();
  if (stats) topology_stats(*stats);
  model::Mt mt = assemble(vertex_ids);
  if (stats) {
    stats->input_triangles = face_count_;
    stats->root_triangles = mt.root_triangle_count();
    stats->nodes = mt.node_count();
    stats->mt_triangles = mt.triangle_count();
    stats->passes = pass_;
    stats->complex_vertices = complex_vertices_;
    stats->normals_given = normal_repair_.had_normals;
    stats->normals_computed = normal_repair_.computed;
    stats->max_error = 0;
    for (const float e : mt.node_error) stats->max_error = std::max(stats->max_error, e);
  }
  if (options_.progress) options_.progress(options_.progress_user, 1.0);
  return mt;
}

}  // namespace

Result<model::Mt> build_mt(const model::Mesh& mesh, const BuildOptions& options, BuildStats* stats,
                           std::vector<std::uint32_t>* vertex_ids) {
  Builder builder(mesh, options);
  return builder.run(stats, vertex_ids);
}

std::vector<std::uint32_t> number_nodes(std::span<const float> collapse_error) {
  const std::uint32_t k = std::uint32_t(collapse_error.size());
  std::vector<std::uint32_t> order(k), order_scratch;
  for (std::uint32_t c = 0; c < k; ++c) order[c] = k - 1 - c;  // coarsest collapse first
  util::radix_sort(order, order_scratch, [&](std::uint32_t c) {
    // Errors are never negative, so their bits order like them (-0 taken as 0).
    const float e = collapse_error[c];
    std::uint32_t bits = 0;
    if (e > 0) std::memcpy(&bits, &e, sizeof bits);
    return ~bits;
  });
  std::vector<std::uint32_t> node_of(k);
  for (std::uint32_t i = 0; i < k; ++i) node_of[order[i]] = i + 1;
  return node_of;
}

Result<BlockOutput> simplify_block(BlockInput&& input, std::size_t target_triangles,
                                   const BuildOptions& options) {
  Builder builder(input.mesh, options, &input);
  return builder.run_block(target_triangles);
}

}  // namespace mtlod::core::build

// Selective refinement of a Multi-Tessellation (core/ARCHITECTURE.md §2.3 "Cuts", §2.4: static,
// budgeted, dynamic and on-demand refinement).
//
// A triangle t passes when error(t) ≤ allowed(t). allowed(t) is either one uniform value or the
// minimum of a per-vertex array over t's three vertices (core/ARCHITECTURE.md §1.4: the papers label
// a triangle with its vertices' smallest label; for laws non-decreasing in the label both agree).
//
// Static refinement returns the unique minimal cut whose triangles all pass: starting from the root,
// a failing triangle forces the node that removes it, and that node's missing ancestors. Any cut in
// which all triangles pass contains every forced node, so the result does not depend on the order.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "core/model/mt.hpp"
#include "core/util/zeroed_array.hpp"

namespace mtlod::core::cut {

// A place in the budgeted refinement's worst-first order: triangles whose allowed error is positive
// rank by error / allowed (tier 0), above all of them those whose allowed error is ≤ 0 by error
// alone (tier 1).
struct Rank {
  std::uint32_t tier = 0;
  float key = 1.0f;
  friend bool operator<(Rank x, Rank y) { return x.tier != y.tier ? x.tier < y.tier : x.key < y.key; }
  friend bool operator==(Rank x, Rank y) { return x.tier == y.tier && x.key == y.key; }
};

// The allowed error per triangle, in model units.
struct AllowedError {
  float uniform = 0.0f;               // used when per_vertex is empty
  std::span<const float> per_vertex;  // empty, or one value per MT vertex (mt.vertex_count())
  // A triangle fails when its error exceeds its allowed error and its rank is above this threshold
  // (at least {0, 1}, the plain test). The budgeted dynamic refinement keeps the minimal cut of a
  // threshold (Refinement::move with a budget).
  Rank threshold;

  static AllowedError everywhere(float error) { return {error, {}, {}}; }
  static AllowedError from_vertices(std::span<const float> vertex_allowed_error) {
    return {0.0f, vertex_allowed_error, {}};
  }
  // Of a triangle with corners a, b, c: the uniform value, or the smallest of theirs.
  float of_triangle(std::uint32_t a, std::uint32_t b, std::uint32_t c) const {
    if (per_vertex.empty()) return uniform;
    const float* field = per_vertex.data();
    return std::min(field[a], std::min(field[b], field[c]));
  }
  // Whether a triangle of this error and allowed error fails. At the plain threshold the division
  // agrees with error > allowed (for allowed > 0 both are true together), so it is skipped.
  bool exceeded_by(float error, float allowed) const {
    if (!(error > allowed)) return false;
    if (threshold.tier == 0 && threshold.key == 1.0f) return true;
    if (!(allowed > 0.0f)) return threshold.tier == 0 || error > threshold.key;
    return threshold.tier == 0 && error / allowed > threshold.key;
  }
};

// Allowed errors vertex by vertex, for Refiner::refine_on_demand.
class VertexErrorSource {
 public:
  virtual float vertex_allowed_error(std::uint32_t vertex) const = 0;
  // field[v] = vertex_allowed_error(v) for every v of `vertices` (a source may do several at once).
  virtual void fill(std::span<const std::uint32_t> vertices, std::span<float> field) const {
    for (const std::uint32_t v : vertices) field[v] = vertex_allowed_error(v);
  }

 protected:
  ~VertexErrorSource() = default;
};

// What one refinement is asked for, as a value: where it starts, what stops it, and where the
// allowed error comes from. Refiner::refine and refine_view take it and choose the algorithm from it
// in one place. Made by the factories below, e.g.
//   Refinement::from_root(allowed)                      the minimal cut in which every triangle passes
//   Refinement::from_root(allowed).within(n)            worst first, at most n triangles
//   Refinement::from_root(source, field).within(n).keeping()   on demand, kept for later moves
//   Refinement::move(allowed, changed)                  the kept cut moved to a new field
struct Refinement {
  enum class Start : std::uint8_t {
    kRoot,  // from the root. Without a budget the cut is kept for later moves anyway (its
            // witnesses cost nothing extra); with one, nothing is kept.
    kKeep,  // from the root, keeping the cut for later moves (with a budget: the cut of a
            // threshold a little below it, see Refiner::refine_view)
    kMove,  // from the kept cut, moved to the new allowed error (from the root when none is kept)
  };
  Start start = Start::kRoot;
  // On demand: views `field`. Its threshold holds for a refinement from the root without a budget,
  // on demand or not: the minimal cut of that threshold, a cut the worst-first order passes through
  // (how a scene shares one budget among its instances, core/view/scene_extract.hpp).
  AllowedError allowed;
  std::optional<std::size_t> budget;  // at most this many triangles, worst error/allowed first
  // On demand: the allowed error is asked of `source` for only the vertices the refinement reads
  // and written to `field` (one entry per MT vertex, the caller's scratch; other entries are left
  // as they were). A move on demand needs `field` to hold every vertex read since the cut was
  // started from the root, updated to the new view, and `changed` to list those that changed.
  const VertexErrorSource* source = nullptr;
  std::span<float> field;
  // kMove: the vertices whose allowed error changed since the previous refinement (every other
  // vertex must have the same value as then; duplicates are fine). Unset: found by comparing with
  // a copy of the previous field (error-bound moves without a source only).
  std::optional<std::span<const std::uint32_t>> changed;

  static Refinement from_root(const AllowedError& allowed) {
    Refinement r;
    r.allowed = allowed;
    return r;
  }
  static Refinement from_root(const VertexErrorSource& source, std::span<float> field) {
    Refinement r = from_root(AllowedError::from_vertices(field));
    r.source = &source;
    r.field = field;
    return r;
  }
  static Refinement move(const AllowedError& allowed) {
    Refinement r = from_root(allowed);
    r.start = Start::kMove;
    return r;
  }
  static Refinement move(const AllowedError& allowed, std::span<const std::uint32_t> changed) {
    Refinement r = move(allowed);
    r.changed = changed;
    return r;
  }
  static Refinement move(const VertexErrorSource& source, std::span<float> field,
                         std::span<const std::uint32_t> changed) {
    Refinement r = from_root(source, field);
    r.start = Start::kMove;
    r.changed = changed;
    return r;
  }
  Refinement& within(std::size_t max_triangles) {
    budget = max_triangles;
    return *this;
  }
  Refinement& keeping() {
    if (start == Start::kRoot) start = Start::kKeep;
    return *this;
  }
};

struct CutSpan;

// A cut's mesh, ready for an encoder. Caller-owned and reused between calls.
struct CutMesh {
  std::vector<std::uint32_t> triangles;  // 3 vertex ids per triangle (CCW), ids into mt.positions; any order
  std::vector<std::uint32_t> ids;        // the MT triangle id of each triangle (same order): stable names
                                         // a client can keep between cuts (see core/cut/cut_delta.hpp)
  std::size_t node_count = 0;            // nodes in the cut, root included
  float max_error = 0.0f;                // largest error(t) over the cut's triangles, model units
  bool within_budget = true;             // false only when a budget is below the root's size

  std::size_t triangle_count() const { return triangles.size() / 3; }
  // Becomes a copy of `view` (which may be a view of this mesh).
  void assign(const CutSpan& view);
};

// A read-only span of a cut, with CutMesh's fields: into a CutMesh, or into a refiner's kept mesh
// (valid until that refiner's next call).
struct CutSpan {
  std::span<const std::uint32_t> triangles;
  std::span<const std::uint32_t> ids;
  std::size_t node_count = 0;
  float max_error = 0.0f;
  bool within_budget = true;

  std::size_t triangle_count() const { return triangles.size() / 3; }
  static CutSpan of(const CutMesh& m) {
    return {m.triangles, m.ids, m.node_count, m.max_error, m.within_budget};
  }
};

inline void CutMesh::assign(const CutSpan& view) {
  if (view.triangles.data() != triangles.data())
    triangles.assign(view.triangles.begin(), view.triangles.end());
  if (view.ids.data() != ids.data()) ids.assign(view.ids.begin(), view.ids.end());
  node_count = view.node_count;
  max_error = view.max_error;
  within_budget = view.within_budget;
}

// Keeps a cut and its scratch memory between requests (one per worker or client session). No
// allocation once the buffers have grown to the model's size.
class Refiner {
 public:
  explicit Refiner(const model::Mt& mt);

  // Refines as `what` asks and writes the cut to `out`. Fails (kCorrupt) when the refinement reaches
  // a block of a mapped file that fails its check (model::MtBlockCheck); the refiner then holds the
  // root alone and keeps no cut, and `out` is not a result.
  Status refine(const Refinement& what, CutMesh& out);
  // The same without copying a moved cut out: a view of the refiner's kept mesh, or of `scratch`
  // when the cut was written there (valid until the refiner's next call).
  //
  // What each kind of refinement gives:
  // - From the root without a budget: the unique minimal cut whose triangles all pass. It records
  //   witnesses (the failing triangle that forced each node), so a later move starts from it.
  // - On demand: the same cut, asking the source only for the vertices the refinement reads: the
  //   root's and the split vertices of the cut's nodes (every corner of a triangle a node creates
  //   belongs to the root or to one of its ancestors).
  // - With a budget from the root: repeatedly refines the failing triangle with the largest
  //   error/allowed ratio (allowed ≤ 0 ranks by error alone) and stops before the next refinement
  //   would take the mesh over the budget; out.within_budget is false when the root alone is larger.
  // - A move without a budget: the kept cut goes to the minimal cut for the new allowed error, by
  //   dropping the nodes whose reason to be in the cut no longer holds and refining from what is
  //   left; the same triangles as from the root (the order differs). Without a kept cut (the first
  //   call, or after a uniform field or a budget from the root, which keep none) it refines from the
  //   root and keeps that cut. Without a list of changed vertices they are found by comparing with a
  //   copy of the previous field (one sequential O(vertices) pass); everything else costs O(cut) in
  //   sequential passes plus work proportional to the change.
  // - Kept or moved with a budget: the same cut as from the root with that budget, found from the
  //   kept cut. The refiner keeps the minimal cut of a threshold in that order (see
  //   AllowedError::threshold) a little below the budget: the root's worst-first refinement passes
  //   through exactly that cut, so refining worst first from it gives the same result. A move takes
  //   the kept cut to the new field's minimal cut for the same threshold; past the budget the
  //   threshold rises until it fits, far below it the threshold falls to where the refinement
  //   passed. The field must be per vertex at the plain threshold, and a move needs the list of
  //   changed vertices.
  Result<CutSpan> refine_view(const Refinement& what, CutMesh& scratch);

  // The threshold of the kept cut after a budgeted update (none when no threshold's cut fitted).
  std::optional<Rank> budget_threshold() const { return budget_threshold_; }
  // Budgeted updates that raised the threshold to fit the budget, and that refined from the root.
  std::size_t budget_raises() const { return budget_raises_; }
  std::size_t budget_starts() const { return budget_starts_; }

  // Nodes of the kept cut, in the order they were added (parents before children).
  std::span<const std::uint32_t> cut_nodes() const { return cut_; }
  // Calls f(v) for every vertex whose allowed error the kept cut depends on (what its on-demand
  // refinement asks for): the root's vertices, then the split vertices of the cut's other nodes.
  template <class F>
  void for_each_cut_vertex(F&& f) {
    find_root_vertices();
    for (const std::uint32_t v : root_vertices_) f(v);
    for (const std::uint32_t n : cut_)
      if (n != 0) f(mt_.node_vertex[n]);
  }

  // Updates that found it cheaper to refine afresh than to move the kept cut (a quarter of the cut's
  // nodes dropped, or the nodes a move added outnumbered a third of those kept): forcing from the
  // nodes in the cut by then, as a static refinement forces from the root. Their result is the same.
  std::size_t restarts() const { return restarts_; }
  // Updates that moved the kept cut (the others refined afresh, or found nothing changed).
  std::size_t moves() const { return moves_; }
  // Updates given an empty list of changed vertices after a cut this refiner moved before: the
  // kept mesh is returned as it is.
  std::size_t unchanged_updates() const { return unchanged_; }

  // Bytes this refiner holds (buffer capacities): the memory a session's cut costs.
  std::size_t memory_bytes() const;

 private:
  // The kinds of refine_view, one per Refinement it dispatches.
  void refine_minimal(const AllowedError& allowed, CutMesh& out);
  void refine_on_demand(const VertexErrorSource& source, std::span<float> field, Rank threshold,
                        CutMesh& out);
  void refine_budget(const AllowedError& allowed, std::size_t max_triangles, CutMesh& out);
  void refine_budget_on_demand(const VertexErrorSource& source, std::span<float> field,
                               std::size_t max_triangles, CutMesh& out);
  void start_budget(const AllowedError& allowed, std::size_t max_triangles, CutMesh& out);
  void start_budget_on_demand(const VertexErrorSource& source, std::span<float> field,
                              std::size_t max_triangles, CutMesh& out);
  void update_compared(const AllowedError& allowed, CutMesh& out);
  CutSpan update_view(const AllowedError& allowed, std::span<const std::uint32_t> changed_vertices,
                      CutMesh& scratch);
  CutSpan update_view_on_demand(const VertexErrorSource& source, std::span<float> field,
                                std::span<const std::uint32_t> changed_vertices, CutMesh& scratch);
  void update_budget(const AllowedError& allowed, std::span<const std::uint32_t> changed_vertices,
                     std::size_t max_triangles, CutMesh& out);
  void update_budget_on_demand(const VertexErrorSource& source, std::span<float> field,
                               std::span<const std::uint32_t> changed_vertices, std::size_t max_triangles,
                               CutMesh& out);
  void refine_uniform(float allowed_error, CutMesh& out);
  // The cut of nodes [0, end): the uniform static and budgeted results.
  void refine_prefix(std::uint32_t end, CutMesh& out);
  // Calls f(t, p) for every triangle t node x removes, p being t's creator (one of x's parents).
  template <class F>
  void for_each_removed(std::uint32_t x, F&& f) const;
  // Triangles node x removes.
  std::size_t removed_count(std::uint32_t x) const;
  // refine_on_demand's source and the field it fills (allowed.per_vertex views the same floats).
  struct OnDemand {
    const VertexErrorSource& source;
    std::span<float> field;
  };
  // The source of an on-demand update, for the duration of the call (also when it throws).
  class Filling {
   public:
    Filling(const OnDemand*& slot, const OnDemand& on_demand) : slot_(slot) { slot_ = &on_demand; }
    ~Filling() { slot_ = nullptr; }
    Filling(const Filling&) = delete;
    Filling& operator=(const Filling&) = delete;

   private:
    const OnDemand*& slot_;
  };
  const OnDemand* filling_ = nullptr;
  // refine_forced from the root, on demand when on_demand is set.
  void refine_from_root(const AllowedError& allowed, CutMesh& out, const OnDemand* on_demand);
  // The root mesh's vertices (listed in root_vertices_ on first use), and the split vertices of
  // cut_ from position `first` on.
  void find_root_vertices();
  void fill_root_vertices(const OnDemand& on_demand);
  void fill_split_vertices(const OnDemand& on_demand, std::size_t first);
  // Static refinement by forcing from the root; records witnesses so update can start from it.
  // from_cut: start from the nodes in cut_ instead (a subset of the new minimal cut, with their
  // witnesses, parents and witness creators before them).
  // out null (from_cut only): the cut's mesh stays in passing_ for the caller to take (kept_ is
  // kPassing), the field stays known.
  // kept_nodes (from_cut only): the first kept_nodes nodes of cut_ were in the kept cut, whose mesh
  // is still in mesh_*, and the field differs from its field only at the vertices in changed_bits_
  // (anywhere when all_changed) with a threshold no lower. Their triangles whose corners did not
  // change and whose remover did not drop (dropped nodes marked in node_changed_) passed then and
  // pass now: they are neither tested nor listed in passing_ (merge_kept_mesh takes them from the
  // kept mesh).
  void refine_forced(const AllowedError& allowed, CutMesh* out, const OnDemand* on_demand = nullptr,
                     bool from_cut = false, std::size_t kept_nodes = 0, bool all_changed = true);
  // Prefetches what refine_forced will read for the nodes queued after cut_[i].
  void fetch_ahead(std::size_t i, const float* field, bool on_demand) const;
  bool fails(std::uint32_t t, std::uint32_t creator, const AllowedError& allowed) const;
  bool fails_at(std::uint32_t remover, const std::uint32_t* corners, const AllowedError& allowed) const;
  void reset_to_root();
  // Takes the nodes from position `length` of cut_ on out of the cut (the last ones added).
  void truncate_cut(std::size_t length);
  // Adds node r and its missing ancestors, parents first; witness_triangle forced r.
  // Adds node r and its missing ancestors. When one of them lies in a block that fails its check,
  // adds none of them and records the node in failed_node_; every later force returns at once.
  void force(std::uint32_t r, std::uint32_t witness_triangle, std::uint32_t witness_creator);
  // The refinement of refine_view, by kind.
  CutSpan run(const Refinement& what, CutMesh& scratch);
  // Adds node x, forced by witness_triangle (created by witness_creator, removed by a node of
  // error witness_error).
  void add_node(std::uint32_t x, std::uint32_t witness_triangle, std::uint32_t witness_creator,
                float witness_error);
  void examine(std::uint32_t n, const AllowedError& allowed);
  // Examines cut_ from position first on, forcing what fails (asking filling_ for the split
  // vertices of those nodes first); false, leaving the rest unexamined, once cut_ holds more than
  // max_nodes.
  bool close_over(const AllowedError& allowed, std::size_t first, std::size_t max_nodes);
  void emit(CutMesh& out) const;
  // The kept mesh (maintained by move_cut) as a cut, and its largest error.
  CutSpan kept_view() const;
  float kept_max_error() const;
  // The field of the kept cut: its kind and threshold, and with `copy` its values (for update
  // without a list of changes).
  void remember_field(const AllowedError& allowed, bool copy);
  // Takes the mesh of the cut refine_forced left from its passing list, once move_cut's witness
  // pass has run (kept nodes kIn, dropped kDropped), before the cut is moved or refined afresh.
  void take_kept_mesh();
  // Truncates the kept mesh's arrays (all five) to this many triangles.
  void resize_kept_mesh(std::size_t triangles);
  void mesh_push(std::uint32_t t, std::uint32_t creator, std::uint32_t remover, const std::uint32_t* corners,
                 float error);
  // Moves the kept cut, or refines it afresh from the nodes that stay; the kept mesh holds the result.
  // all_changed: every triangle is tested again. raised: the field is the same and the threshold
  // higher, so only the witnesses are (a triangle that passed still passes).
  void move_cut(const AllowedError& allowed, bool all_changed, bool raised = false);
  // update(allowed, changed, ·) up to the output: true when the kept mesh holds the result (false:
  // a static refinement wrote `out`, there being no kept cut to move).
  bool update_kept(const AllowedError& allowed, std::span<const std::uint32_t> changed_vertices,
                   CutMesh& out);
  bool vertex_changed(std::uint32_t v) const { return util::test_bit(changed_bits_, v); }

  const model::Mt& mt_;
  util::PagedArray<std::uint8_t> in_cut_;  // per node: 0 out, 1 in, 2 being added, 3 dropped
  std::vector<std::uint32_t> cut_;         // nodes in the cut, in the order added
  // Per entry of cut_ (same index): the failing triangle that forced the node, its creator, its
  // three corners and its error, so moving the cut tests it again from one sequential pass (the
  // triangle's remover and that node's error are scattered reads in the model).
  struct Witness {
    std::uint32_t triangle, creator, corners[3];
    float error;
  };
  std::vector<Witness> witnesses_;
  std::vector<std::uint32_t> batch_;          // split vertices computed together (on demand)
  std::vector<std::uint32_t> root_vertices_;  // distinct corners of the root's triangles (on demand)
  std::vector<std::uint32_t> stack_;          // DFS over missing ancestors: node, next parent index
  // What the refiner keeps between calls: which cut, and where its mesh is. It says where the
  // next update starts.
  enum class Kept : std::uint8_t {
    kNone,       // no cut to move (none yet, or one without witnesses): the next update refines
                 // from the root
    kPassing,    // a forced refinement's minimal cut, with witnesses; its mesh is among passing_
    kThreshold,  // start_budget's cut of a threshold, with witnesses; its mesh not built yet
    kMesh,       // a minimal cut with witnesses, and its mesh in mesh_*
    kAdding,     // within a move: nodes are being added; mesh_* is the cut's mesh before them
  };
  Kept kept_ = Kept::kNone;
  // A node of a block that failed its check during the current refinement (model::kNoNode: none).
  std::uint32_t failed_node_ = model::kNoNode;
  // What the refiner knows of the field its kept cut is minimal for (at previous_threshold_).
  enum class Field : std::uint8_t {
    kUnknown,  // nothing: the next update retests every triangle of the cut
    kUniform,  // one value, previous_uniform_
    kListed,   // per vertex; the caller lists the vertices that change
    kCopied,   // per vertex, with its values in previous_field_ (update without a list compares)
  };
  Field field_ = Field::kUnknown;
  std::vector<float> previous_field_;
  float previous_uniform_ = 0.0f;
  std::size_t restarts_ = 0;
  std::size_t moves_ = 0;
  std::size_t unchanged_ = 0;
  // The kept cut's mesh, maintained by update: per triangle its id, creator, remover (kNoNode for
  // an input triangle), corners and error (for the cut's max error).
  std::vector<std::uint32_t> mesh_triangles_;
  std::vector<std::uint32_t> mesh_creators_;
  std::vector<std::uint32_t> mesh_removers_;
  std::vector<std::uint32_t> mesh_corners_;
  std::vector<float> mesh_errors_;
  util::ZeroedArray<std::uint64_t> changed_bits_;  // per vertex, during update (clear between)
  std::vector<std::uint32_t> dropped_;             // nodes dropped during one update
  std::vector<std::uint32_t> seeds_;               // uncovered triangle, creator pairs of one update
  // Per node: dropped or added by the update; in move_cut's witness pass, a parent dropped. Clear
  // between uses.
  util::ZeroedArray<std::uint64_t> node_changed_;
  // Triangles seen passing in refine_forced, with what the output needs of them.
  struct Passing {
    std::uint32_t triangle, creator, remover, corners[3];
    float error;  // 0 for an input triangle
  };
  std::vector<Passing> passing_;
  struct HeapEntry {
    std::uint32_t tier;  // 1: allowed ≤ 0, ranked by error; 0: ranked by error / allowed
    float key;
    std::uint32_t triangle;
    std::uint32_t creator;
  };
  HeapEntry heap_entry(std::uint32_t t, std::uint32_t creator, const AllowedError& allowed) const;
  static bool heap_less(const HeapEntry& x, const HeapEntry& y);
  // heap_less for the heap algorithms: a function object's call is inlined, a function pointer's not.
  struct HeapLess {
    bool operator()(const HeapEntry& x, const HeapEntry& y) const { return heap_less(x, y); }
  };
  // Pushes node n's triangles that fail and are in the mesh.
  void push_failing(std::uint32_t n, const AllowedError& allowed);
  // Worst ratio first from the cut, heap_ holding its mesh's failing triangles (count of them in
  // all): refines until the next refinement would take the mesh over max_triangles or nothing fails.
  // At each new smallest ratio ℓ popped, the cut is the minimal cut of
  // threshold ℓ: the last such ℓ whose cut had at most `target` triangles, and the cut's length
  // then, are written to level and level_end (left as they were when there is none).
  void fill_budget(const AllowedError& allowed, std::size_t count, std::size_t max_triangles,
                   std::size_t target, Rank& level, std::size_t& level_end,
                   const OnDemand* on_demand = nullptr);
  // Worst first from the root (fill_budget); returns level_end and sets level. on_demand: the
  // field is filled as nodes are added.
  std::size_t budget_from_root(const AllowedError& allowed, std::size_t max_triangles, std::size_t target,
                               const OnDemand* on_demand, Rank& level, CutMesh& out);
  void start_budget_from(const AllowedError& allowed, std::size_t max_triangles, const OnDemand* on_demand,
                         CutMesh& out);
  // The size a changed threshold's cut aims at: a little below the budget.
  std::size_t budget_target(std::size_t max_triangles) const;
  // The threshold at which at least `nodes` of the cut's nodes lose their witness.
  Rank threshold_dropping(const AllowedError& allowed, std::size_t nodes);
  // Writes the kept mesh with the nodes of cut_ from position `added` on refined into it.
  void write_refined(std::size_t added, std::size_t max_triangles, CutMesh& out);
  // Extends the kept mesh after nodes were dropped (dropped_, their uncovered triangles in seeds_)
  // or added (cut_ from position `added` on): move_cut's last step.
  void rebuild_kept_mesh(std::size_t added);
  // Takes the mesh of a cut refined afresh from the kept nodes (dropped_ dropped and already marked
  // in node_changed_, cut_ from position `added` on forced) while the old kept mesh is still in mesh_*: the
  // old mesh keeps its order less what changed, and the passing triangles it lacks follow, so a client's cut
  // is diffed in order (core/cut/cut_delta.hpp).
  void merge_kept_mesh(std::size_t added);
  // Marks in node_changed_ the nodes of dropped_ and of cut_ from position `added` on, or clears
  // those marks.
  void mark_changed_nodes(std::size_t added);
  void clear_changed_nodes(std::size_t added);
  // Drops from the kept mesh, keeping the order of the rest, the triangles whose creator or remover
  // is marked changed (their creator dropped or came back, or their remover was added).
  void compact_kept_mesh();
  // The kept mesh of the whole cut (after start_budget, before the next move).
  void kept_mesh_from_cut();
  std::vector<HeapEntry> heap_;
  // A budgeted update's failing triangles ranked below deferred_below_, out of the heap until the
  // fill reaches them; fill_floor_ is the lowest rank the last fill popped (above all: none).
  std::vector<HeapEntry> deferred_;
  Rank deferred_below_;
  Rank fill_floor_{2, 0.0f};
  std::vector<Rank> ranks_;               // threshold_dropping's scratch
  std::optional<Rank> budget_threshold_;  // the kept cut's threshold for budget_max_
  std::size_t budget_max_ = 0;
  std::size_t budget_raises_ = 0;
  std::size_t budget_starts_ = 0;
  Rank previous_threshold_;  // the threshold of the kept cut (unless field_ is kUnknown)
};

// One-off static refinement of an MT held in memory (allocates a Refiner).
void refine_static(const model::Mt& mt, const AllowedError& allowed, CutMesh& out);
// One-off budgeted refinement of an MT held in memory.
void refine_budget(const model::Mt& mt, const AllowedError& allowed, std::size_t max_triangles, CutMesh& out);

}  // namespace mtlod::core::cut

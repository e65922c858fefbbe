// Selective refinement (core/ARCHITECTURE.md §2.4): static, budgeted and dynamic cuts of an MT.
//
// Dynamic refinement keeps, for every node of the cut, the "witness" that put it there: the failing
// triangle t (and t's creator) that forced it, either as t's remover or as one of that remover's
// missing ancestors. Nodes are kept in the order they were added, so a witness creator and all
// parents come before the node. On a new allowed-error field one pass in that order keeps a node only
// while its witness creator is kept, its witness triangle still fails and its parents are kept; by
// induction every kept node is forced again by the new field, so what is left lies inside the new
// minimal cut. Refining from there (examining only triangles that changed or were uncovered) reaches
// exactly the static result, and cycles of mutual support (a node kept only because its child is,
// the child only because the parent's triangle fails) cannot survive, because no witness points
// forward.
#include "core/cut/refine.hpp"

#include <algorithm>
#include <cassert>
#include <cstring>
#include <limits>

namespace mtlod::core::cut {
namespace {

enum : std::uint8_t { kOut = 0, kIn = 1, kAdding = 2, kDropped = 3 };

// The output of the static paths: sizes a CutMesh for an upper bound of triangles, writes each
// triangle's corners and id unchecked, then trims the arrays to what was written.
class MeshWriter {
 public:
  MeshWriter(const model::Mt& mt, CutMesh& out, std::size_t capacity)
      : corners_(mt.triangle_corners.data()), out_(out) {
    out.triangles.resize(3 * capacity);
    out.ids.resize(capacity);
    write_ = out.triangles.data();
    id_ = out.ids.data();
  }
  // Triangle t, whose first corner is `first` (its creator's split vertex, or its root entry).
  void add(std::uint32_t t, std::uint32_t first) {
    write_[0] = first;
    write_[1] = corners_[2 * std::size_t{t}];
    write_[2] = corners_[2 * std::size_t{t} + 1];
    write_ += 3;
    *id_++ = t;
  }
  // Triangle t with its three corners already known.
  void add(std::uint32_t t, const std::uint32_t* corners) {
    write_[0] = corners[0];
    write_[1] = corners[1];
    write_[2] = corners[2];
    write_ += 3;
    *id_++ = t;
  }
  void finish(std::size_t node_count, float max_error) {
    out_.triangles.resize(std::size_t(write_ - out_.triangles.data()));
    out_.ids.resize(std::size_t(id_ - out_.ids.data()));
    out_.node_count = node_count;
    out_.max_error = max_error;
  }

 private:
  const std::uint32_t* corners_;
  CutMesh& out_;
  std::uint32_t* write_ = nullptr;
  std::uint32_t* id_ = nullptr;
};

// A triangle's place in the budget's worst-first order. allowed ≤ 0 would divide by zero: such
// triangles rank above all others, by error.
Rank rank_of(float error, float allowed) {
  return allowed > 0.0f ? Rank{0, error / allowed} : Rank{1, error};
}

// Triangles the nodes create and no node of the cut removes.
std::size_t created_by(const model::Mt& mt, std::span<const std::uint32_t> nodes) {
  std::size_t created = 0;
  for (const std::uint32_t n : nodes)
    created += mt.node_triangle_offsets[n + 1] - mt.node_triangle_offsets[n];
  return created;
}

// Writes what `nodes` create and no node of the cut (in_cut == kIn) removes; returns their largest
// error.
float write_created(const model::Mt& mt, const util::PagedArray<std::uint8_t>& in_cut,
                    std::span<const std::uint32_t> nodes, MeshWriter& writer) {
  const std::uint32_t* remover = mt.triangle_remover.data();
  float max_error = 0.0f;
  for (const std::uint32_t n : nodes) {
    const std::uint32_t end = mt.node_triangle_offsets[n + 1];
    const std::uint32_t first = n == 0 ? model::kNoVertex : mt.node_vertex[n];
    for (std::uint32_t t = mt.node_triangle_offsets[n]; t < end; ++t) {
      const std::uint32_t r = remover[t];
      if (r != model::kNoNode) {
        if (in_cut[r] == kIn) continue;
        max_error = std::max(max_error, mt.node_error[r]);
      }
      writer.add(t, n == 0 ? mt.root_first_corner[t] : first);
    }
  }
  return max_error;
}

}  // namespace

// A fresh refiner's state is all kOut, as a fresh mapping is all zero.
static_assert(kOut == 0);

Refiner::Refiner(const model::Mt& mt)
    : mt_(mt),
      in_cut_(mt.node_count()),
      changed_bits_((mt.vertex_count() + 63) / 64),
      node_changed_((mt.node_count() + 63) / 64) {
  assert(mt.node_count() > 0);
}

bool Refiner::fails(std::uint32_t t, std::uint32_t creator, const AllowedError& allowed) const {
  const std::uint32_t corners[3] = {mt_.first_corner(model::TriangleId{t}, model::NodeId{creator}),
                                    mt_.triangle_corners[2 * std::size_t{t}],
                                    mt_.triangle_corners[2 * std::size_t{t} + 1]};
  return fails_at(mt_.triangle_remover[t], corners, allowed);
}

bool Refiner::fails_at(std::uint32_t r, const std::uint32_t* corners, const AllowedError& allowed) const {
  if (r == model::kNoNode) return false;  // an input triangle: nothing finer exists
  return allowed.exceeded_by(mt_.node_error[r], allowed.of_triangle(corners[0], corners[1], corners[2]));
}

Refiner::HeapEntry Refiner::heap_entry(std::uint32_t t, std::uint32_t creator,
                                       const AllowedError& allowed) const {
  const float a = allowed.of_triangle(mt_.first_corner(model::TriangleId{t}, model::NodeId{creator}),
                                      mt_.triangle_corners[2 * std::size_t{t}],
                                      mt_.triangle_corners[2 * std::size_t{t} + 1]);
  // The remover's block is not checked here: only failing triangles enter the heap, so its error
  // is a number (NaN fails nothing) and the order is total whatever a damaged block holds. The block
  // is checked when the node is forced. Checking it here would check, on a large model's first
  // view, the blocks of every root triangle's remover: nearly the whole file.
  const Rank rank = rank_of(mt_.node_error[mt_.triangle_remover[t]], a);
  return {rank.tier, rank.key, t, creator};
}

void Refiner::truncate_cut(std::size_t length) {
  for (std::size_t i = length; i < cut_.size(); ++i) in_cut_.set(cut_[i], kOut);
  cut_.resize(length);
  witnesses_.resize(length);
}

void Refiner::reset_to_root() {
  kept_ = Kept::kNone;
  for (const std::uint32_t n : cut_) in_cut_.set(n, kOut);
  cut_.clear();
  witnesses_.clear();
  in_cut_.set(0, kIn);
  cut_.push_back(0);
  witnesses_.push_back({model::kNoNode,
                        model::kNoNode,
                        {model::kNoNode, model::kNoNode, model::kNoNode},
                        0.0f});  // the root needs none
}

template <class F>
void Refiner::for_each_removed(std::uint32_t x, F&& f) const {
  for (std::uint32_t j = mt_.node_parent_offsets[x]; j < mt_.node_parent_offsets[x + 1]; ++j) {
    const std::uint32_t p = mt_.node_parents[j];
    for (std::uint32_t t = mt_.node_triangle_offsets[p]; t < mt_.node_triangle_offsets[p + 1]; ++t)
      if (mt_.triangle_remover[t] == x) f(t, p);
  }
}

void Refiner::add_node(std::uint32_t x, std::uint32_t witness_triangle, std::uint32_t witness_creator,
                       float witness_error) {
  // Nodes are added with the kept mesh set aside (refine_forced and refine_budget emit at the end,
  // move_cut rebuilds the mesh once for all its additions).
  assert(kept_ != Kept::kMesh);
  in_cut_.set(x, kIn);
  cut_.push_back(x);
  // The witness's corners were just read to find it failing: cheap to keep now.
  witnesses_.push_back(
      {witness_triangle,
       witness_creator,
       {mt_.first_corner(model::TriangleId{witness_triangle}, model::NodeId{witness_creator}),
        mt_.triangle_corners[2 * std::size_t{witness_triangle}],
        mt_.triangle_corners[2 * std::size_t{witness_triangle} + 1]},
       witness_error});
}

void Refiner::force(std::uint32_t r, std::uint32_t witness_triangle, std::uint32_t witness_creator) {
  // Every node whose parents are read is checked first (a mapped file's block on first use); so
  // is every node add_node gets. After a failed check the refinement only runs to its end.
  if (failed_node_ != model::kNoNode) return;
  if (!mt_.require_node(r)) {
    failed_node_ = r;
    return;
  }
  const std::uint32_t* offsets = mt_.node_parent_offsets.data();
  const std::uint32_t* parents = mt_.node_parents.data();
  // Usual case: every parent is already in the cut.
  bool parents_in = true;
  for (std::uint32_t i = offsets[r]; i < offsets[r + 1] && parents_in; ++i)
    parents_in = in_cut_[parents[i]] == kIn;
  // r removes the witness: every node added here has its error (just read to find it failing).
  const float witness_error = mt_.node_error[r];
  if (parents_in) return add_node(r, witness_triangle, witness_creator, witness_error);
  stack_.clear();
  stack_.push_back(r);
  stack_.push_back(offsets[r]);
  in_cut_.set(r, kAdding);
  while (!stack_.empty()) {
    const std::size_t top = stack_.size() - 2;
    const std::uint32_t x = stack_[top];
    const std::uint32_t i = stack_[top + 1];
    if (i < offsets[x + 1]) {
      stack_[top + 1] = i + 1;
      const std::uint32_t p = parents[i];
      if (in_cut_[p] == kOut || in_cut_[p] == kDropped) {
        if (!mt_.require_node(p)) {
          // None of the nodes on the stack is added: the cut stays a cut.
          failed_node_ = p;
          for (std::size_t k = 0; k < stack_.size(); k += 2) in_cut_.set(stack_[k], kOut);
          stack_.clear();
          return;
        }
        in_cut_.set(p, kAdding);
        stack_.push_back(p);
        stack_.push_back(offsets[p]);
      }
      continue;
    }
    stack_.resize(top);
    add_node(x, witness_triangle, witness_creator, witness_error);
  }
}

[[gnu::always_inline]] inline void Refiner::fetch_ahead(std::size_t i, const float* field,
                                                        bool on_demand) const {
  // The queue ahead is known, so its nodes' data is fetched in stages and the misses overlap:
  // 12 nodes ahead where its triangles are, 6 ahead those triangles, 3 ahead what they point to.
  // On demand also the split vertex 20 ahead and, 16 ahead, its position (computed 3–11 ahead).
  const std::uint32_t* offsets = mt_.node_triangle_offsets.data();
  const std::uint32_t* removers = mt_.triangle_remover.data();
  const std::uint32_t* corners = mt_.triangle_corners.data();
  if (on_demand && i + 20 < cut_.size()) __builtin_prefetch(mt_.node_vertex.data() + cut_[i + 20]);
  if (on_demand && i + 16 < cut_.size()) {
    const std::uint32_t ahead = cut_[i + 16];
    if (ahead != 0) __builtin_prefetch(mt_.positions.data() + 3 * std::size_t{mt_.node_vertex[ahead]});
  }
  if (i + 12 < cut_.size()) {
    const std::uint32_t ahead = cut_[i + 12];
    __builtin_prefetch(offsets + ahead);
    __builtin_prefetch(mt_.node_vertex.data() + ahead);
  }
  if (i + 6 < cut_.size()) {
    const std::uint32_t ahead = cut_[i + 6];
    const std::uint32_t first = offsets[ahead], last = offsets[ahead + 1];
    __builtin_prefetch(removers + first);
    __builtin_prefetch(removers + last - 1);
    __builtin_prefetch(corners + 2 * std::size_t{first});
    __builtin_prefetch(corners + 2 * std::size_t{last} - 1);
    if (ahead != 0) {
      const std::uint32_t split = mt_.node_vertex[ahead];
      __builtin_prefetch(field + split);
    }
  }
  if (i + 3 < cut_.size()) {
    const std::uint32_t ahead = cut_[i + 3];
    for (std::uint32_t t = offsets[ahead]; t < offsets[ahead + 1]; ++t) {
      const std::uint32_t r = removers[t];
      if (r == model::kNoNode) continue;
      __builtin_prefetch(in_cut_.address(r));
      __builtin_prefetch(mt_.node_error.data() + r);
      __builtin_prefetch(mt_.node_parent_offsets.data() + r);  // for force()
      __builtin_prefetch(field + corners[2 * std::size_t{t}]);
      __builtin_prefetch(field + corners[2 * std::size_t{t} + 1]);
    }
  }
}

void Refiner::examine(std::uint32_t n, const AllowedError& allowed) {
  const std::uint32_t end = mt_.node_triangle_offsets[n + 1];
  for (std::uint32_t t = mt_.node_triangle_offsets[n]; t < end; ++t) {
    const std::uint32_t r = mt_.triangle_remover[t];
    if (r == model::kNoNode || in_cut_[r] == kIn) continue;
    if (fails(t, n, allowed)) force(r, t, n);
  }
}

bool Refiner::close_over(const AllowedError& allowed, std::size_t first, std::size_t max_nodes) {
  // cut_ grows while we walk it: every added node gets its own triangles examined.
  const bool uniform = allowed.per_vertex.empty();
  std::size_t filled = first;  // on demand: positions of cut_ whose split vertex has its value
  for (std::size_t i = first; i < cut_.size(); ++i) {
    if (cut_.size() > max_nodes) return false;
    if (filling_ && filled <= i) {
      // Everything added since the last fill, before any of its triangles is read.
      fill_split_vertices(*filling_, filled);
      filled = cut_.size();
    }
    if (!uniform) fetch_ahead(i, allowed.per_vertex.data(), false);
    examine(cut_[i], allowed);
  }
  return true;
}

void Refiner::emit(CutMesh& out) const {
  // Upper bound first (everything the cut's nodes create), then one unchecked write per corner.
  MeshWriter writer(mt_, out, created_by(mt_, cut_));
  writer.finish(cut_.size(), write_created(mt_, in_cut_, cut_, writer));
}

void Refiner::remember_field(const AllowedError& allowed, bool copy) {
  field_ = allowed.per_vertex.empty() ? Field::kUniform : copy ? Field::kCopied : Field::kListed;
  previous_uniform_ = allowed.uniform;
  previous_threshold_ = allowed.threshold;
  if (field_ == Field::kCopied) previous_field_.assign(allowed.per_vertex.begin(), allowed.per_vertex.end());
}

Status Refiner::refine(const Refinement& what, CutMesh& out) {
  MTLOD_TRY(const CutSpan cut, refine_view(what, out));
  out.assign(cut);
  return Ok{};
}

Result<CutSpan> Refiner::refine_view(const Refinement& what, CutMesh& scratch) {
  failed_node_ = model::kNoNode;
  const CutSpan cut = run(what, scratch);
  if (failed_node_ == model::kNoNode) return cut;
  // The cut holds none of the damaged block's nodes, but it is not the one asked for: start over.
  Status why = mt_.check_node(failed_node_);
  reset_to_root();
  failed_node_ = model::kNoNode;
  if (why.ok())  // checked by another thread since: the next refinement will do
    return make_error(ErrorCode::kInternal, "a node block's check failed, then passed");
  return why.take_error();
}

CutSpan Refiner::run(const Refinement& what, CutMesh& scratch) {
  using Start = Refinement::Start;
  const bool on_demand = what.source != nullptr;
  assert(!on_demand || what.field.size() == mt_.vertex_count());
  // On demand and budgeted moves are told what changed; only an error-bound move may compare.
  assert(what.start != Start::kMove || what.changed || (!on_demand && !what.budget));
  if (what.budget) {
    const std::size_t budget = *what.budget;
    switch (what.start) {
      case Start::kRoot:
        on_demand ? refine_budget_on_demand(*what.source, what.field, budget, scratch)
                  : refine_budget(what.allowed, budget, scratch);
        break;
      case Start::kKeep:
        on_demand ? start_budget_on_demand(*what.source, what.field, budget, scratch)
                  : start_budget(what.allowed, budget, scratch);
        break;
      case Start::kMove:
        on_demand ? update_budget_on_demand(*what.source, what.field, *what.changed, budget, scratch)
                  : update_budget(what.allowed, *what.changed, budget, scratch);
        break;
    }
    return CutSpan::of(scratch);
  }
  if (what.start != Start::kMove) {
    on_demand ? refine_on_demand(*what.source, what.field, what.allowed.threshold, scratch)
              : refine_minimal(what.allowed, scratch);
    return CutSpan::of(scratch);
  }
  if (on_demand) return update_view_on_demand(*what.source, what.field, *what.changed, scratch);
  if (what.changed) return update_view(what.allowed, *what.changed, scratch);
  update_compared(what.allowed, scratch);
  return CutSpan::of(scratch);
}

void Refiner::refine_minimal(const AllowedError& allowed, CutMesh& out) {
  assert(allowed.per_vertex.empty() || allowed.per_vertex.size() == mt_.vertex_count());
  if (allowed.per_vertex.empty()) return refine_uniform(allowed.uniform, out);
  refine_forced(allowed, &out);
}

void Refiner::refine_uniform(float allowed_error, CutMesh& out) {
  // Nodes are stored by decreasing error and errors never grow from parent to child (checked when
  // a file is loaded), so the minimal cut is the root plus the prefix of nodes with error above the
  // bound.
  const float* errors = mt_.node_error.data();
  refine_prefix(std::uint32_t(std::partition_point(errors + 1, errors + mt_.node_count(),
                                                   [&](float e) { return e > allowed_error; }) -
                              errors),
                out);
}

void Refiner::refine_prefix(std::uint32_t end, CutMesh& out) {
  // The cut of nodes [0, end) (every prefix is a cut: parents come first); its mesh is read off the
  // prefix of the triangle array in one sequential pass.
  const float* errors = mt_.node_error.data();
  for (std::uint32_t n = 0; n < end; n += model::kMtBlockNodes) {
    if (!mt_.require_node(n)) {
      failed_node_ = n;
      return;
    }
  }
  for (const std::uint32_t n : cut_) in_cut_.set(n, kOut);
  cut_.resize(end);
  witnesses_.clear();  // none recorded (see below)
  for (std::uint32_t n = 0; n < end; ++n) cut_[n] = n;
  in_cut_.fill_prefix(end, kIn);
  // No witnesses were recorded: the next update starts with a forced refinement.
  kept_ = Kept::kNone;

  MeshWriter writer(mt_, out, mt_.node_triangle_offsets[end]);
  const std::uint32_t* remover = mt_.triangle_remover.data();
  float max_error = 0.0f;
  for (std::uint32_t n = 0; n < end; ++n) {
    const std::uint32_t first = n == 0 ? model::kNoVertex : mt_.node_vertex[n];
    const std::uint32_t last = mt_.node_triangle_offsets[n + 1];
    for (std::uint32_t t = mt_.node_triangle_offsets[n]; t < last; ++t) {
      const std::uint32_t r = remover[t];
      // In the mesh unless its remover is in the prefix (kNoNode is larger than any node).
      if (r < end) continue;
      if (r != model::kNoNode) max_error = std::max(max_error, errors[r]);
      writer.add(t, n == 0 ? mt_.root_first_corner[t] : first);
    }
  }
  writer.finish(end, max_error);
  out.within_budget = true;
}

void Refiner::find_root_vertices() {
  // Each once: a vertex has about six root triangles.
  if (root_vertices_.empty()) {
    for (std::uint32_t t = 0; t < mt_.node_triangle_offsets[1]; ++t) {
      root_vertices_.push_back(mt_.root_first_corner[t]);
      root_vertices_.push_back(mt_.triangle_corners[2 * std::size_t{t}]);
      root_vertices_.push_back(mt_.triangle_corners[2 * std::size_t{t} + 1]);
    }
    std::sort(root_vertices_.begin(), root_vertices_.end());
    root_vertices_.erase(std::unique(root_vertices_.begin(), root_vertices_.end()), root_vertices_.end());
  }
}

void Refiner::fill_root_vertices(const OnDemand& on_demand) {
  find_root_vertices();
  on_demand.source.fill(root_vertices_, on_demand.field);
}

void Refiner::fill_split_vertices(const OnDemand& on_demand, std::size_t first) {
  batch_.clear();
  for (std::size_t i = first; i < cut_.size(); ++i) batch_.push_back(mt_.node_vertex[cut_[i]]);
  on_demand.source.fill(batch_, on_demand.field);
}

void Refiner::refine_on_demand(const VertexErrorSource& source, std::span<float> field, Rank threshold,
                               CutMesh& out) {
  assert(field.size() == mt_.vertex_count());
  const OnDemand on_demand{source, field};
  AllowedError allowed = AllowedError::from_vertices(field);
  allowed.threshold = threshold;
  refine_from_root(allowed, out, &on_demand);
}

void Refiner::refine_from_root(const AllowedError& allowed, CutMesh& out, const OnDemand* on_demand) {
  // On demand, the root's vertices first; the nodes' split vertices as the refinement reaches them.
  if (on_demand) fill_root_vertices(*on_demand);
  refine_forced(allowed, &out, on_demand);
}

void Refiner::refine_forced(const AllowedError& allowed, CutMesh* out, const OnDemand* on_demand,
                            bool from_cut, std::size_t kept_nodes, bool all_changed) {
  assert(from_cut || kept_nodes == 0);
  kept_ = Kept::kNone;  // until the new cut is complete
  if (!from_cut) reset_to_root();
  // Like close_over, but remembering every passing triangle: the final mesh is among them (a
  // triangle examined while its remover was out either failed, forcing the remover in, or passed),
  // so the output filters that list instead of walking all the cut's triangles again.
  passing_.clear();
  const std::uint32_t* offsets = mt_.node_triangle_offsets.data();
  const std::uint32_t* removers = mt_.triangle_remover.data();
  const std::uint32_t* corners = mt_.triangle_corners.data();
  const float* field = allowed.per_vertex.data();
  const bool uniform = allowed.per_vertex.empty();  // update() from no kept cut may pass one
  // On demand, the split vertices of the nodes at positions up to i + 3 have their values before
  // position i is examined, computed in batches of about eight (up to i + 11, or the queue's end):
  // after all their ancestors', which come earlier in cut_, and before any triangle that has one
  // as a corner is read. From a cut, the nodes already in it are asked again (a source may know
  // them); the root's vertices are known either way.
  std::size_t computed = 1;  // positions of cut_ whose split vertex has its value (the root: its vertices)
  for (std::size_t i = 0; i < cut_.size(); ++i) {
    if (!uniform) fetch_ahead(i, field, on_demand != nullptr);
    if (on_demand && computed <= i + 3 && computed < cut_.size()) {
      batch_.clear();
      for (const std::size_t until = std::min(cut_.size(), i + 12); computed < until; ++computed)
        batch_.push_back(mt_.node_vertex[cut_[computed]]);
      on_demand->source.fill(batch_, on_demand->field);
    }
    const std::uint32_t n = cut_[i];
    const std::uint32_t split = n == 0 ? model::kNoVertex : mt_.node_vertex[n];
    const std::uint32_t end = offsets[n + 1];
    const bool kept_node = i < kept_nodes && !all_changed;
    for (std::uint32_t t = offsets[n]; t < end; ++t) {
      const std::uint32_t r = removers[t];
      if (r != model::kNoNode && in_cut_[r] == kIn) continue;
      // fails(t, n, allowed), with the values kept for the output.
      const std::uint32_t a = n == 0 ? mt_.root_first_corner[t] : split;
      const std::uint32_t b = corners[2 * std::size_t{t}], c = corners[2 * std::size_t{t} + 1];
      if (kept_node && !(r != model::kNoNode && util::test_bit(node_changed_, r)) && !vertex_changed(a) &&
          !vertex_changed(b) && !vertex_changed(c))
        continue;  // in the kept mesh, and still passing
      const float error = r == model::kNoNode ? 0.0f : mt_.node_error[r];
      if (r != model::kNoNode && allowed.exceeded_by(error, allowed.of_triangle(a, b, c))) {
        force(r, t, n);
      } else {
        passing_.push_back({t, n, r, {a, b, c}, error});
      }
    }
  }
  kept_ = Kept::kPassing;
  if (!out) return;
  MeshWriter writer(mt_, *out, passing_.size());
  float max_error = 0.0f;
  for (const Passing& p : passing_) {
    if (p.remover != model::kNoNode && in_cut_[p.remover] == kIn) continue;  // refined after it passed
    max_error = std::max(max_error, p.error);
    writer.add(p.triangle, p.corners);
  }
  writer.finish(cut_.size(), max_error);
  out->within_budget = true;
  // The field is not copied here, to keep static refinement free of O(vertices) work; the next
  // update treats every vertex as changed.
  field_ = Field::kUnknown;
}

// --- dynamic refinement -------------------------------------------------------------------------

void Refiner::mesh_push(std::uint32_t t, std::uint32_t creator, std::uint32_t remover,
                        const std::uint32_t* corners, float error) {
  mesh_triangles_.push_back(t);
  mesh_creators_.push_back(creator);
  mesh_removers_.push_back(remover);
  mesh_corners_.insert(mesh_corners_.end(), corners, corners + 3);
  mesh_errors_.push_back(error);
}

void Refiner::resize_kept_mesh(std::size_t triangles) {
  mesh_triangles_.resize(triangles);
  mesh_creators_.resize(triangles);
  mesh_removers_.resize(triangles);
  mesh_corners_.resize(3 * triangles);
  mesh_errors_.resize(triangles);
}

void Refiner::take_kept_mesh() {
  // The kept mesh is set aside only by refine_forced (a move leaves it in place; the other
  // refinements keep no cut to move, so no move follows them): its passing list still holds the
  // mesh's triangles (those not refined since), creators, removers, corners and errors. Called
  // after move_cut's witness pass, whose nodes are now kIn (kept) or kDropped: a passing triangle
  // whose remover is kIn or kDropped is not in it.
  assert(kept_ == Kept::kPassing);
  resize_kept_mesh(0);
  for (const Passing& p : passing_) {
    if (p.remover != model::kNoNode && (in_cut_[p.remover] == kIn || in_cut_[p.remover] == kDropped))
      continue;
    mesh_push(p.triangle, p.creator, p.remover, p.corners, p.error);
  }
  kept_ = Kept::kMesh;
}

void Refiner::update_compared(const AllowedError& allowed, CutMesh& out) {
  assert(allowed.per_vertex.empty() || allowed.per_vertex.size() == mt_.vertex_count());
  if (kept_ == Kept::kNone) return refine_forced(allowed, &out);
  bool all_changed = allowed.per_vertex.empty() || field_ != Field::kCopied;
  if (field_ == Field::kUniform && allowed.per_vertex.empty() &&
      std::memcmp(&allowed.uniform, &previous_uniform_, sizeof(float)) == 0) {
    all_changed = false;  // the same uniform value: nothing changed
  } else if (!all_changed) {
    // Bitwise comparison with the kept copy (NaN equals itself, -0 differs from +0: both harmless),
    // 64 vertices per word, copying the new values as we go.
    const std::size_t count = allowed.per_vertex.size();
    const float* now = allowed.per_vertex.data();
    float* before = previous_field_.data();
    for (std::size_t base = 0; base < count; base += 64) {
      const std::size_t end = std::min(count, base + 64);
      // Whole blocks compare with memcmp (vectorised); only differing blocks are split into bits.
      if (std::memcmp(now + base, before + base, (end - base) * sizeof(float)) == 0) continue;
      std::uint64_t word = 0;
      for (std::size_t v = base; v < end; ++v) {
        std::uint32_t x, y;
        std::memcpy(&x, now + v, 4);
        std::memcpy(&y, before + v, 4);
        word |= std::uint64_t{x != y} << (v - base);
      }
      changed_bits_[base / 64] = word;
      std::memcpy(before + base, now + base, (end - base) * sizeof(float));
    }
  }
  const bool field_all_changed = all_changed;
  all_changed = all_changed || !(allowed.threshold == previous_threshold_);  // every triangle
  move_cut(allowed, all_changed);
  out.assign(kept_view());
  if (field_all_changed) remember_field(allowed, true);
  previous_threshold_ = allowed.threshold;
  std::fill(changed_bits_.begin(), changed_bits_.end(), 0);  // the list overload expects it clear
}

CutSpan Refiner::update_view_on_demand(const VertexErrorSource& source, std::span<float> field,
                                       std::span<const std::uint32_t> changed_vertices, CutMesh& scratch) {
  assert(field.size() == mt_.vertex_count());
  const OnDemand on_demand{source, field};
  const Filling filling(filling_, on_demand);
  return update_view(AllowedError::from_vertices(field), changed_vertices, scratch);
}

CutSpan Refiner::update_view(const AllowedError& allowed, std::span<const std::uint32_t> changed_vertices,
                             CutMesh& scratch) {
  return update_kept(allowed, changed_vertices, scratch) ? kept_view() : CutSpan::of(scratch);
}

bool Refiner::update_kept(const AllowedError& allowed, std::span<const std::uint32_t> changed_vertices,
                          CutMesh& out) {
  assert(allowed.per_vertex.empty() || allowed.per_vertex.size() == mt_.vertex_count());
  if (kept_ == Kept::kNone) {
    refine_from_root(allowed, out, filling_);
    return false;
  }
  const bool field_all_changed =
      allowed.per_vertex.empty() || field_ == Field::kUnknown || field_ == Field::kUniform;
  const bool threshold_changed = !(allowed.threshold == previous_threshold_);
  // A higher threshold over the same field only drops nodes: their witnesses are tested again, and
  // of the other triangles only those they uncover and those with a changed corner.
  const bool raised = !field_all_changed && threshold_changed && previous_threshold_ < allowed.threshold;
  const bool all_changed = field_all_changed || (threshold_changed && !raised);
  if (!all_changed && !raised && changed_vertices.empty() && kept_ == Kept::kMesh) {
    // The same field: the kept cut is its minimal cut already (a gaze within the same cells).
    ++unchanged_;
    return true;
  }
  if (!field_all_changed) {
    for (const std::uint32_t v : changed_vertices) {
      assert(v < mt_.vertex_count());
      changed_bits_[v >> 6] |= std::uint64_t{1} << (v & 63);
      if (field_ == Field::kCopied) previous_field_[v] = allowed.per_vertex[v];
    }
  }
  move_cut(allowed, all_changed, raised);
  if (field_all_changed) {
    // No copy: the callers that list their changes never need one (update without a list makes it).
    remember_field(allowed, false);
  } else {
    for (const std::uint32_t v : changed_vertices) changed_bits_[v >> 6] = 0;  // leave the bitmap clear
    previous_threshold_ = allowed.threshold;
  }
  return true;
}

// One function for the five steps of a move, the gaze path BM_GazeStream measures: they share the
// changed-vertex test, the kept count and the dropped list, and either restart check may end it.
void Refiner::move_cut(const AllowedError& allowed, bool all_changed, bool raised) {
  if (kept_ == Kept::kThreshold) kept_mesh_from_cut();
  auto changed = [&](std::uint32_t v) { return all_changed || vertex_changed(v); };

  // 1. Keep the nodes whose witness still holds (cut_[0] is the root, always kept).
  const std::uint32_t* parent_offsets = mt_.node_parent_offsets.data();
  const std::uint32_t* parents = mt_.node_parents.data();
  std::size_t kept = 1;
  dropped_.clear();
  const std::size_t count = cut_.size();
  // A node whose parent dropped drops too. Rather than reading every later node's parents, a
  // dropped node marks the nodes its triangles name as removers (its children) in node_changed_;
  // parents come before children in cut_, so the mark is set before its node is reached.
  const std::uint32_t* triangle_offsets = mt_.node_triangle_offsets.data();
  const std::uint32_t* removers = mt_.triangle_remover.data();
  auto mark_children = [&](std::uint32_t x, auto&& mark) {
    for (std::uint32_t t = triangle_offsets[x]; t < triangle_offsets[x + 1]; ++t)
      if (const std::uint32_t r = removers[t]; r != model::kNoNode) mark(r);
  };
  for (std::size_t i = 1; i < count; ++i) {
    // The witness creator's state is a scattered read: fetched ahead (cut_ and witnesses_ are
    // read in order).
    if (i + 16 < count) __builtin_prefetch(in_cut_.address(witnesses_[i + 16].creator));
    const std::uint32_t n = cut_[i];
    const Witness w = witnesses_[i];
    bool keep = in_cut_[w.creator] == kIn;
    if (keep && (raised || changed(w.corners[0]) || changed(w.corners[1]) || changed(w.corners[2])))
      keep = allowed.exceeded_by(w.error, allowed.of_triangle(w.corners[0], w.corners[1], w.corners[2]));
    if (keep && !dropped_.empty()) keep = !util::test_bit(node_changed_, n);
    if (keep) {
      witnesses_[kept] = w;
      cut_[kept++] = n;
    } else {
      in_cut_.set(n, kDropped);
      dropped_.push_back(n);
      mark_children(n, [&](std::uint32_t r) { util::set_bit(node_changed_, r); });
    }
  }
  for (const std::uint32_t x : dropped_)  // node_changed_ is clear between steps
    mark_children(x, [&](std::uint32_t r) { node_changed_[r >> 6] = 0; });
  cut_.resize(kept);
  witnesses_.resize(kept);

  // Moving costs more per node than a static refinement (the dropped and added nodes' triangles
  // are looked up and tested, then the mesh is filtered and extended), and a large drop is usually
  // followed by as large an addition (a saccade, a new view): when a quarter of the cut's nodes
  // drop, the cut is refined afresh instead, forcing as refine_forced does from the root but from
  // the kept nodes. They lie in the new minimal cut, so forcing from them reaches it, and only the
  // added nodes are forced. The quarter was measured with BM_GazeStream: restarting from the kept
  // nodes past a quarter, a seventh or a thirteenth dropped costs alike; past a half, the slowest
  // gazes are slower. Dropped nodes not forced back in are out once the new cut is known.
  auto release_dropped = [&] {
    for (const std::uint32_t n : dropped_)
      if (in_cut_[n] == kDropped) in_cut_.set(n, kOut);
  };
  // The result becomes the kept mesh, as a move's does, the triangles that stay in their order
  // (the old mesh is taken from the passing list first if it is still there: in the order the
  // refinement from the root wrote it). The kept nodes' triangles are tested again only where a
  // corner changed or the remover dropped (see refine_forced): the dropped nodes are marked for it
  // (nothing lies past cut_'s end yet to mark as added), and the merge clears the marks.
  auto refine_afresh = [&] {
    if (kept_ == Kept::kPassing) take_kept_mesh();
    release_dropped();
    mark_changed_nodes(cut_.size());
    refine_forced(allowed, nullptr, filling_, true, kept, all_changed);
    merge_kept_mesh(kept);
    ++restarts_;
  };
  if (3 * dropped_.size() > kept) return refine_afresh();

  // The kept mesh is taken from the passing list only now, when the cut is moved rather than
  // refined afresh (after a refinement from the root the next move takes it).
  if (kept_ == Kept::kPassing) take_kept_mesh();

  // 2. Undo the dropped nodes: what they removed from kept nodes is uncovered and must be tested
  // (what they created leaves the mesh in step 5, by its creator's state).
  seeds_.clear();
  const std::size_t dropped_count = dropped_.size();
  for (std::size_t k = 0; k < dropped_count; ++k) {
    // The dropped nodes are scattered over the model: their parents, those parents' triangles and
    // the triangles' removers are fetched in stages ahead, as in step 1.
    if (k + 12 < dropped_count) __builtin_prefetch(parent_offsets + dropped_[k + 12]);
    if (k + 8 < dropped_count) __builtin_prefetch(parents + parent_offsets[dropped_[k + 8]]);
    if (k + 4 < dropped_count) {
      const std::uint32_t ahead = dropped_[k + 4];
      for (std::uint32_t j = parent_offsets[ahead]; j < parent_offsets[ahead + 1]; ++j)
        __builtin_prefetch(triangle_offsets + parents[j]);
    }
    if (k + 2 < dropped_count) {
      const std::uint32_t ahead = dropped_[k + 2];
      for (std::uint32_t j = parent_offsets[ahead]; j < parent_offsets[ahead + 1]; ++j)
        __builtin_prefetch(removers + triangle_offsets[parents[j]]);
    }
    const std::uint32_t x = dropped_[k];
    for_each_removed(x, [&](std::uint32_t t, std::uint32_t p) {
      if (in_cut_[p] != kIn) return;
      seeds_.push_back(t);
      seeds_.push_back(p);
    });
  }

  // 3. Force the removers of what fails now: the uncovered triangles, and mesh triangles of kept
  // nodes with a changed corner; every other such triangle passed before and still does. (A
  // dropped node forced back in has all its triangles examined in step 4.)
  kept_ = Kept::kAdding;  // step 5 rebuilds the mesh
  for (std::size_t i = 0; i < seeds_.size(); i += 2) {
    const std::uint32_t t = seeds_[i], r = mt_.triangle_remover[t];
    if (in_cut_[r] != kIn && fails(t, seeds_[i + 1], allowed)) force(r, t, seeds_[i + 1]);
  }
  const std::size_t mesh_size = mesh_triangles_.size();
  for (std::size_t i = 0; i < mesh_size; ++i) {
    const std::uint32_t* corners = &mesh_corners_[3 * i];
    if (!changed(corners[0]) && !changed(corners[1]) && !changed(corners[2])) continue;
    const std::uint32_t r = mesh_removers_[i];
    // An input triangle (fails_at is false then), refined meanwhile through another triangle, or
    // created by a dropped node.
    if (r != model::kNoNode && in_cut_[r] != kIn && in_cut_[mesh_creators_[i]] == kIn &&
        fails_at(r, corners, allowed))
      force(r, mesh_triangles_[i], mesh_creators_[i]);
  }
  // 4. Nodes added in step 3 (and theirs, in turn) are examined in full; once they outnumber a
  // third of the kept nodes, refining afresh from all of them costs less than the mesh edits ahead.
  if (!close_over(allowed, kept, kept + kept / 3)) return refine_afresh();
  release_dropped();

  // 5. The new mesh.
  rebuild_kept_mesh(kept);
  ++moves_;
}

void Refiner::mark_changed_nodes(std::size_t added) {
  for (const std::uint32_t n : dropped_) util::set_bit(node_changed_, n);
  for (std::size_t i = added; i < cut_.size(); ++i) util::set_bit(node_changed_, cut_[i]);
}

void Refiner::clear_changed_nodes(std::size_t added) {
  for (const std::uint32_t n : dropped_) node_changed_[n >> 6] = 0;
  for (std::size_t i = added; i < cut_.size(); ++i) node_changed_[cut_[i] >> 6] = 0;
}

void Refiner::compact_kept_mesh() {
  // In place, in order; the bitmap is 8 times denser than in_cut_.
  const std::size_t mesh_size = mesh_triangles_.size();
  std::size_t write = 0;
  for (std::size_t i = 0; i < mesh_size; ++i) {
    const std::uint32_t r = mesh_removers_[i];
    if (util::test_bit(node_changed_, mesh_creators_[i]) ||
        (r != model::kNoNode && util::test_bit(node_changed_, r)))
      continue;
    mesh_triangles_[write] = mesh_triangles_[i];
    mesh_creators_[write] = mesh_creators_[i];
    mesh_removers_[write] = r;
    // Three assignments: copy_n of the overlapping arrays would call memmove for 12 bytes.
    mesh_corners_[3 * write] = mesh_corners_[3 * i];
    mesh_corners_[3 * write + 1] = mesh_corners_[3 * i + 1];
    mesh_corners_[3 * write + 2] = mesh_corners_[3 * i + 2];
    mesh_errors_[write] = mesh_errors_[i];
    ++write;
  }
  resize_kept_mesh(write);
}

void Refiner::rebuild_kept_mesh(std::size_t added) {
  // Of the old mesh, what kept nodes created and no node of the cut removes; then the uncovered
  // triangles no added node removes; then what the added nodes create and no node of the cut
  // removes. Every old mesh triangle was created by a node of the old cut and removed by none: it
  // stays unless its creator dropped (and perhaps came back: added nodes' triangles are pushed
  // below) or its remover was added.
  mark_changed_nodes(added);
  compact_kept_mesh();
  clear_changed_nodes(added);
  auto push = [&](std::uint32_t t, std::uint32_t creator) {
    const std::uint32_t r = mt_.triangle_remover[t];
    if (r != model::kNoNode && in_cut_[r] != kOut) return;
    const std::uint32_t corners[3] = {mt_.first_corner(model::TriangleId{t}, model::NodeId{creator}),
                                      mt_.triangle_corners[2 * std::size_t{t}],
                                      mt_.triangle_corners[2 * std::size_t{t} + 1]};
    mesh_push(t, creator, r, corners, r == model::kNoNode ? 0.0f : mt_.node_error[r]);
  };
  for (std::size_t i = 0; i < seeds_.size(); i += 2) push(seeds_[i], seeds_[i + 1]);
  for (std::size_t i = added; i < cut_.size(); ++i) {
    const std::uint32_t x = cut_[i];
    for (std::uint32_t t = mt_.node_triangle_offsets[x]; t < mt_.node_triangle_offsets[x + 1]; ++t)
      push(t, x);
  }
  kept_ = Kept::kMesh;
}

void Refiner::merge_kept_mesh(std::size_t added) {
  // The new mesh is among the passing triangles (see refine_forced). Of those, the old mesh already
  // holds the ones whose creator was kept and whose remover neither dropped nor was added: a
  // triangle is in a cut's mesh when its creator is in the cut and its remover is not.
  assert(kept_ == Kept::kPassing);
  // The dropped nodes are marked already (refine_forced skipped by those marks); the added ones now.
  for (std::size_t i = added; i < cut_.size(); ++i) util::set_bit(node_changed_, cut_[i]);
  compact_kept_mesh();
  for (const Passing& p : passing_) {
    const bool remover_changed = p.remover != model::kNoNode && util::test_bit(node_changed_, p.remover);
    if (!remover_changed && !util::test_bit(node_changed_, p.creator)) continue;  // in the old mesh
    if (p.remover != model::kNoNode && in_cut_[p.remover] == kIn) continue;       // refined
    mesh_push(p.triangle, p.creator, p.remover, p.corners, p.error);
  }
  clear_changed_nodes(added);
  kept_ = Kept::kMesh;
}

CutSpan Refiner::kept_view() const {
  return {mesh_corners_, mesh_triangles_, cut_.size(), kept_max_error(), true};
}

float Refiner::kept_max_error() const {
  // Eight independent running maxima, then the largest of them: the same value as one running
  // maximum, without one long chain of dependent comparisons.
  constexpr std::size_t kLanes = 8;
  float lanes[kLanes] = {};
  const float* errors = mesh_errors_.data();
  const std::size_t n = mesh_errors_.size();
  std::size_t i = 0;
  for (; i + kLanes <= n; i += kLanes)
    for (std::size_t k = 0; k < kLanes; ++k) lanes[k] = std::max(lanes[k], errors[i + k]);
  float max_error = 0.0f;
  for (; i < n; ++i) max_error = std::max(max_error, errors[i]);
  for (const float lane : lanes) max_error = std::max(max_error, lane);
  return max_error;
}

std::size_t Refiner::removed_count(std::uint32_t x) const {
  std::size_t removed = 0;
  for_each_removed(x, [&](std::uint32_t, std::uint32_t) { ++removed; });
  return removed;
}

void Refiner::refine_budget(const AllowedError& allowed, std::size_t max_triangles, CutMesh& out) {
  assert(allowed.per_vertex.empty() || allowed.per_vertex.size() == mt_.vertex_count());
  if (allowed.per_vertex.empty()) {
    // Uniform: worst ratio first is largest error first, which is node order, and every node's
    // parents come before it. So the result is the longest prefix of failing nodes that fits.
    const float* errors = mt_.node_error.data();
    const std::uint32_t failing_end =
        std::uint32_t(std::partition_point(errors + 1, errors + mt_.node_count(),
                                           [&](float e) { return e > allowed.uniform; }) -
                      errors);
    std::size_t count = mt_.root_triangle_count();
    std::uint32_t end = 1;
    for (; end < failing_end; ++end) {
      const std::size_t next =
          count + (mt_.node_triangle_offsets[end + 1] - mt_.node_triangle_offsets[end]) - removed_count(end);
      if (next > max_triangles) break;
      count = next;
    }
    refine_prefix(end, out);
    out.within_budget = out.triangle_count() <= max_triangles;
    return;
  }
  Rank level;
  budget_from_root(allowed, max_triangles, 0, nullptr, level, out);
}

void Refiner::refine_budget_on_demand(const VertexErrorSource& source, std::span<float> field,
                                      std::size_t max_triangles, CutMesh& out) {
  assert(field.size() == mt_.vertex_count());
  const OnDemand on_demand{source, field};
  Rank level;
  budget_from_root(AllowedError::from_vertices(field), max_triangles, 0, &on_demand, level, out);
}

std::size_t Refiner::budget_from_root(const AllowedError& allowed, std::size_t max_triangles,
                                      std::size_t target, const OnDemand* on_demand, Rank& level,
                                      CutMesh& out) {
  reset_to_root();  // keeps no cut to move (start_budget_from keeps one)
  heap_.clear();
  deferred_.clear();
  if (on_demand) fill_root_vertices(*on_demand);
  push_failing(0, allowed);
  std::size_t level_end = 0;
  fill_budget(allowed, mt_.root_triangle_count(), max_triangles, target, level, level_end, on_demand);
  emit(out);
  out.within_budget = out.triangle_count() <= max_triangles;
  return level_end;
}

bool Refiner::heap_less(const HeapEntry& x, const HeapEntry& y) {
  // Ties broken by triangle id so the result does not depend on the heap's layout.
  if (x.tier != y.tier) return x.tier < y.tier;
  return x.key < y.key || (x.key == y.key && x.triangle > y.triangle);
}

void Refiner::push_failing(std::uint32_t n, const AllowedError& allowed) {
  const std::uint32_t end = mt_.node_triangle_offsets[n + 1];
  for (std::uint32_t t = mt_.node_triangle_offsets[n]; t < end; ++t) {
    const std::uint32_t r = mt_.triangle_remover[t];
    if (r == model::kNoNode || in_cut_[r] == kIn || !fails(t, n, allowed)) continue;
    heap_.push_back(heap_entry(t, n, allowed));
    std::push_heap(heap_.begin(), heap_.end(), HeapLess{});
  }
}

void Refiner::fill_budget(const AllowedError& allowed, std::size_t count, std::size_t max_triangles,
                          std::size_t target, Rank& level, std::size_t& level_end,
                          const OnDemand* on_demand) {
  // The ratios popped fall, but not steadily: refining a triangle can uncover worse ones, which are
  // popped next. Clipped to the smallest ratio popped so far they do fall steadily (a max-min path
  // search from the root), and when that smallest ratio first reaches ℓ every node whose forcing
  // path stays above ℓ is in the cut and no other: the minimal cut of threshold ℓ.
  Rank smallest{2, 0.0f};  // above every rank
  while (true) {
    // The entries set aside below deferred_below_ join once the heap's best is no better.
    if (!deferred_.empty() &&
        (heap_.empty() || Rank{heap_.front().tier, heap_.front().key} < deferred_below_)) {
      heap_.insert(heap_.end(), deferred_.begin(), deferred_.end());
      deferred_.clear();
      std::make_heap(heap_.begin(), heap_.end(), HeapLess{});
    }
    if (heap_.empty()) break;
    std::pop_heap(heap_.begin(), heap_.end(), HeapLess{});
    const HeapEntry top = heap_.back();
    heap_.pop_back();
    const std::uint32_t r = mt_.triangle_remover[top.triangle];
    if (in_cut_[r] == kIn) continue;  // already refined through another triangle
    if (const Rank rank{top.tier, top.key}; rank < smallest) {
      smallest = rank;
      if (count <= target) level = smallest, level_end = cut_.size();
    }
    const std::size_t first_new = cut_.size();
    force(r, top.triangle, top.creator);
    // Size change: each new node adds what it creates and takes away what it removes.
    std::size_t added = 0, removed = 0;
    for (std::size_t i = first_new; i < cut_.size(); ++i) {
      const std::uint32_t x = cut_[i];
      added += mt_.node_triangle_offsets[x + 1] - mt_.node_triangle_offsets[x];
      removed += removed_count(x);
    }
    if (count + added - removed > max_triangles) {
      truncate_cut(first_new);
      fill_floor_ = smallest;
      return;
    }
    count = count + added - removed;
    // Every corner of a new node's triangles is its split vertex or an older one's.
    if (on_demand) fill_split_vertices(*on_demand, first_new);
    for (std::size_t i = first_new; i < cut_.size(); ++i) push_failing(cut_[i], allowed);
  }
  // Nothing fails: the minimal cut of threshold 1.
  if (count <= target) level = Rank{}, level_end = cut_.size();
  fill_floor_ = smallest;
}

Rank Refiner::threshold_dropping(const AllowedError& allowed, std::size_t nodes) {
  // A node stays only while its witness fails, so a threshold at or above the witness's rank drops
  // it (and whatever it supports).
  ranks_.clear();
  for (std::size_t i = 1; i < cut_.size(); ++i) {
    const Witness& w = witnesses_[i];
    const float a = allowed.of_triangle(w.corners[0], w.corners[1], w.corners[2]);
    ranks_.push_back(rank_of(w.error, a));
  }
  if (ranks_.empty()) return Rank{2, 0.0f};
  const std::size_t k = std::min(nodes, ranks_.size()) - 1;
  std::nth_element(ranks_.begin(), ranks_.begin() + std::ptrdiff_t(k), ranks_.end());
  return ranks_[k];
}

void Refiner::write_refined(std::size_t added, std::size_t max_triangles, CutMesh& out) {
  // The kept mesh less what the nodes from `added` on remove, then what they create and no node of
  // the cut removes.
  const std::span<const std::uint32_t> nodes = std::span<const std::uint32_t>(cut_).subspan(added);
  for (const std::uint32_t x : nodes) util::set_bit(node_changed_, x);
  MeshWriter writer(mt_, out, mesh_triangles_.size() + created_by(mt_, nodes));
  float max_error = 0.0f;
  for (std::size_t i = 0; i < mesh_triangles_.size(); ++i) {
    const std::uint32_t r = mesh_removers_[i];
    if (r != model::kNoNode && util::test_bit(node_changed_, r)) continue;
    writer.add(mesh_triangles_[i], &mesh_corners_[3 * i]);
    max_error = std::max(max_error, mesh_errors_[i]);
  }
  for (const std::uint32_t x : nodes) node_changed_[x >> 6] = 0;
  max_error = std::max(max_error, write_created(mt_, in_cut_, nodes, writer));
  writer.finish(cut_.size(), max_error);
  out.within_budget = out.triangle_count() <= max_triangles;
}

namespace {
// Budgeted updates keep the threshold's cut between these fractions of the budget below it: the
// worst-first refinement fills the gap at every gaze, and the threshold changes only when the cut
// leaves the band (each change tests every triangle once).
constexpr std::size_t kBudgetLow = 16;  // the band starts a sixteenth below the budget
// A changed threshold aims a sixty-fourth below it: the nearer the kept cut lies to the budget, the
// less each gaze's fill adds, for a few more raises (BM_GazeFile, BM_GazeStream's budgeted criteria).
constexpr std::size_t kBudgetTarget = 64;
// The heap of a budgeted update holds the failing triangles ranked at least this fraction of the
// previous fill's lowest rank; the others join if the fill gets that far. Consecutive gazes' fills
// end near each other, so a narrow margin keeps the heap small and rarely has to merge the rest
// (BM_GazeFile, BM_GazeStream's budgeted criteria; at 1 the merges cost more than they save).
constexpr float kDeferBelow = 0.95f;
}  // namespace

std::size_t Refiner::budget_target(std::size_t max_triangles) const {
  // Not below the root's size, for budgets just above it.
  return std::max(max_triangles - max_triangles / kBudgetTarget, mt_.root_triangle_count());
}

void Refiner::start_budget(const AllowedError& allowed, std::size_t max_triangles, CutMesh& out) {
  assert(!allowed.per_vertex.empty() && allowed.threshold == Rank{});
  start_budget_from(allowed, max_triangles, nullptr, out);
}

void Refiner::start_budget_on_demand(const VertexErrorSource& source, std::span<float> field,
                                     std::size_t max_triangles, CutMesh& out) {
  assert(field.size() == mt_.vertex_count());
  const OnDemand on_demand{source, field};
  start_budget_from(AllowedError::from_vertices(field), max_triangles, &on_demand, out);
}

void Refiner::start_budget_from(const AllowedError& allowed, std::size_t max_triangles,
                                const OnDemand* on_demand, CutMesh& out) {
  ++budget_starts_;
  budget_threshold_.reset();
  Rank level;
  const std::size_t level_end =
      budget_from_root(allowed, max_triangles, budget_target(max_triangles), on_demand, level, out);
  if (level_end == 0) return;  // no threshold's cut fits: the next update starts from the root too
  // Keep the cut the refinement passed through at that threshold. Its mesh is built, and the new
  // field compared in full, only when an update follows (an extraction may have no gazes after it).
  truncate_cut(level_end);
  kept_ = Kept::kThreshold;
  field_ = Field::kUnknown;  // the next update retests every triangle, at any threshold
  budget_threshold_ = level;
  budget_max_ = max_triangles;
}

void Refiner::kept_mesh_from_cut() {
  // Every node of the cut counts as added to an empty mesh.
  resize_kept_mesh(0);
  dropped_.clear();
  seeds_.clear();
  rebuild_kept_mesh(0);
}

void Refiner::update_budget(const AllowedError& allowed, std::span<const std::uint32_t> changed_vertices,
                            std::size_t max_triangles, CutMesh& out) {
  assert(!allowed.per_vertex.empty() && allowed.threshold == Rank{});
  if (kept_ == Kept::kNone || !budget_threshold_ || budget_max_ != max_triangles)
    return start_budget_from(allowed, max_triangles, filling_, out);
  const std::size_t target = budget_target(max_triangles);
  const std::size_t low = max_triangles - max_triangles / kBudgetLow;  // below the target
  // The new field's cut at the kept threshold; past the budget, raise the threshold until it fits
  // (a node adds about two triangles, so drop about half the excess, aiming at the target).
  AllowedError at = allowed;
  at.threshold = *budget_threshold_;
  update_kept(at, changed_vertices, out);
  std::size_t count = mesh_triangles_.size();
  for (int raises = 0; count > max_triangles; ++raises) {
    const Rank threshold = threshold_dropping(allowed, (count - target) / 2 + 1);
    if (raises == 3 || !(at.threshold < threshold) || threshold.tier == 2)
      return start_budget_from(allowed, max_triangles, filling_, out);
    ++budget_raises_;
    at.threshold = threshold;
    update_kept(at, {}, out);
    count = mesh_triangles_.size();
  }
  budget_threshold_ = at.threshold;
  // Worst first from there, with a heap of the mesh's failing triangles. A gaze's fill pops a few
  // hundred of its tens of thousands, down to about where the previous gaze's stopped: the ones
  // well below that wait aside (fill_budget takes them in once the heap's best is no better, so
  // the order is the same) and the heap is built and popped at a fraction of the size.
  heap_.clear();
  deferred_.clear();
  deferred_below_ = Rank{0, 0.0f};  // nothing below: every entry in the heap
  if (fill_floor_.tier == 0) deferred_below_.key = fill_floor_.key * kDeferBelow;
  for (std::size_t i = 0; i < mesh_triangles_.size(); ++i) {
    if (mesh_removers_[i] == model::kNoNode) continue;
    const std::uint32_t* corners = &mesh_corners_[3 * i];
    const float a = allowed.of_triangle(corners[0], corners[1], corners[2]);
    const float error = mesh_errors_[i];
    if (!(error > a)) continue;
    // Not checked before it is forced (see heap_entry).
    const Rank rank = rank_of(error, a);
    (rank < deferred_below_ ? deferred_ : heap_)
        .push_back({rank.tier, rank.key, mesh_triangles_[i], mesh_creators_[i]});
  }
  std::make_heap(heap_.begin(), heap_.end(), HeapLess{});
  kept_ = Kept::kAdding;
  const std::size_t base = cut_.size();
  Rank level = at.threshold;
  std::size_t level_end = base;
  fill_budget(allowed, count, max_triangles, target, level, level_end, filling_);
  write_refined(base, max_triangles, out);
  // Far below the budget, keep the cut the refinement passed through nearest the target instead.
  const std::size_t keep = count < low ? level_end : base;
  truncate_cut(keep);
  if (keep > base) {
    dropped_.clear();
    seeds_.clear();
    rebuild_kept_mesh(base);
    budget_threshold_ = level;
    previous_threshold_ = level;
  } else {
    kept_ = Kept::kMesh;
  }
}

void Refiner::update_budget_on_demand(const VertexErrorSource& source, std::span<float> field,
                                      std::span<const std::uint32_t> changed_vertices,
                                      std::size_t max_triangles, CutMesh& out) {
  assert(field.size() == mt_.vertex_count());
  const OnDemand on_demand{source, field};
  const Filling filling(filling_, on_demand);
  update_budget(AllowedError::from_vertices(field), changed_vertices, max_triangles, out);
}

void refine_static(const model::Mt& mt, const AllowedError& allowed, CutMesh& out) {
  Refiner refiner(mt);
  // Only a mapped file's block can be damaged; these one-off helpers serve MTs held in memory.
  [[maybe_unused]] const Status status = refiner.refine(Refinement::from_root(allowed), out);
  assert(status.ok());
}

void refine_budget(const model::Mt& mt, const AllowedError& allowed, std::size_t max_triangles,
                   CutMesh& out) {
  Refiner refiner(mt);
  [[maybe_unused]] const Status status =
      refiner.refine(Refinement::from_root(allowed).within(max_triangles), out);
  assert(status.ok());
}

std::size_t Refiner::memory_bytes() const {
  auto bytes = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
  return in_cut_.resident_bytes() + node_changed_.resident_bytes() + bytes(cut_) + bytes(witnesses_) +
         bytes(mesh_errors_) + bytes(stack_) + bytes(previous_field_) + bytes(mesh_triangles_) +
         bytes(mesh_creators_) + bytes(mesh_removers_) + bytes(mesh_corners_) +
         changed_bits_.resident_bytes() + bytes(dropped_) + bytes(seeds_) + bytes(passing_) + bytes(heap_) +
         bytes(deferred_) + bytes(ranks_) + bytes(root_vertices_) + bytes(batch_);
}

}  // namespace mtlod::core::cut

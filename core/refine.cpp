// Selective refinement (DESIGN.md §2): static, budgeted and dynamic cuts of a Multi-Tessellation.
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
#include "core/refine.hpp"

#include <algorithm>
#include <cassert>
#include <cstring>

namespace mtlod::core {
namespace {

enum : std::uint8_t { kOut = 0, kIn = 1, kAdding = 2, kDropped = 3 };

}  // namespace

Refiner::Refiner(const Mt& mt)
    : mt_(mt),
      in_cut_(mt.node_count(), kOut),
      witness_triangle_(mt.node_count(), kNoNode),
      witness_creator_(mt.node_count(), kNoNode) {
  assert(mt.node_count() > 0);
}

bool Refiner::fails(std::uint32_t t, std::uint32_t creator, const AllowedError& allowed) const {
  const std::uint32_t r = mt_.triangle_remover[t];
  if (r == kNoNode) return false;  // an input triangle: nothing finer exists
  const float error = mt_.node_error[r];
  if (allowed.per_vertex.empty()) return error > allowed.uniform;
  const float* field = allowed.per_vertex.data();
  const float a = field[mt_.first_corner(t, creator)];
  const float b = field[mt_.triangle_corners[2 * std::size_t{t}]];
  const float c = field[mt_.triangle_corners[2 * std::size_t{t} + 1]];
  return error > std::min(a, std::min(b, c));
}

Refiner::HeapEntry Refiner::heap_entry(std::uint32_t t, std::uint32_t creator, const AllowedError& allowed) const {
  const float error = mt_.node_error[mt_.triangle_remover[t]];
  float a = allowed.uniform;
  if (!allowed.per_vertex.empty()) {
    const float* field = allowed.per_vertex.data();
    a = std::min(field[mt_.first_corner(t, creator)],
                 std::min(field[mt_.triangle_corners[2 * std::size_t{t}]],
                          field[mt_.triangle_corners[2 * std::size_t{t} + 1]]));
  }
  // allowed ≤ 0 would divide by zero: such triangles rank above all others, by error.
  if (!(a > 0)) return {1, error, t, creator};
  return {0, error / a, t, creator};
}

void Refiner::reset_to_root() {
  for (const std::uint32_t n : cut_) in_cut_[n] = kOut;
  cut_.clear();
  in_cut_[0] = kIn;
  cut_.push_back(0);
}

void Refiner::force(std::uint32_t r, std::uint32_t witness_triangle, std::uint32_t witness_creator) {
  const std::uint32_t* offsets = mt_.node_parent_offsets.data();
  const std::uint32_t* parents = mt_.node_parents.data();
  stack_.clear();
  stack_.push_back(r);
  stack_.push_back(offsets[r]);
  in_cut_[r] = kAdding;
  while (!stack_.empty()) {
    const std::size_t top = stack_.size() - 2;
    const std::uint32_t x = stack_[top];
    const std::uint32_t i = stack_[top + 1];
    if (i < offsets[x + 1]) {
      stack_[top + 1] = i + 1;
      const std::uint32_t p = parents[i];
      if (in_cut_[p] == kOut || in_cut_[p] == kDropped) {
        in_cut_[p] = kAdding;
        stack_.push_back(p);
        stack_.push_back(offsets[p]);
      }
      continue;
    }
    stack_.resize(top);
    in_cut_[x] = kIn;
    cut_.push_back(x);
    witness_triangle_[x] = witness_triangle;
    witness_creator_[x] = witness_creator;
  }
}

void Refiner::examine(std::uint32_t n, const AllowedError& allowed) {
  const std::uint32_t end = mt_.node_triangle_offsets[n + 1];
  for (std::uint32_t t = mt_.node_triangle_offsets[n]; t < end; ++t) {
    const std::uint32_t r = mt_.triangle_remover[t];
    if (r == kNoNode || in_cut_[r] == kIn) continue;
    if (fails(t, n, allowed)) force(r, t, n);
  }
}

void Refiner::close_over(const AllowedError& allowed, std::size_t first) {
  // cut_ grows while we walk it: every added node gets its own triangles examined.
  for (std::size_t i = first; i < cut_.size(); ++i) examine(cut_[i], allowed);
}

void Refiner::emit(CutMesh& out) const {
  out.triangles.clear();
  float max_error = 0.0f;
  for (const std::uint32_t n : cut_) {
    const std::uint32_t end = mt_.node_triangle_offsets[n + 1];
    const std::uint32_t first = n == 0 ? kNoNode : mt_.node_vertex[n];
    for (std::uint32_t t = mt_.node_triangle_offsets[n]; t < end; ++t) {
      const std::uint32_t r = mt_.triangle_remover[t];
      if (r != kNoNode && in_cut_[r] == kIn) continue;
      if (r != kNoNode) max_error = std::max(max_error, mt_.node_error[r]);
      out.triangles.push_back(n == 0 ? mt_.root_first_corner[t] : first);
      out.triangles.push_back(mt_.triangle_corners[2 * std::size_t{t}]);
      out.triangles.push_back(mt_.triangle_corners[2 * std::size_t{t} + 1]);
    }
  }
  out.node_count = cut_.size();
  out.max_error = max_error;
}

void Refiner::remember_field(const AllowedError& allowed) {
  field_known_ = true;
  previous_is_uniform_ = allowed.per_vertex.empty();
  previous_uniform_ = allowed.uniform;
  if (!previous_is_uniform_) previous_field_.assign(allowed.per_vertex.begin(), allowed.per_vertex.end());
}

void Refiner::refine(const AllowedError& allowed, CutMesh& out) {
  assert(allowed.per_vertex.empty() || allowed.per_vertex.size() == mt_.vertex_count());
  reset_to_root();
  close_over(allowed, 0);
  emit(out);
  out.within_budget = true;
  // The field is not copied here, to keep static refinement free of O(vertices) work; the next
  // update treats every vertex as changed.
  field_known_ = false;
  dynamic_ready_ = true;
}

void Refiner::update(const AllowedError& allowed, CutMesh& out) {
  assert(allowed.per_vertex.empty() || allowed.per_vertex.size() == mt_.vertex_count());
  if (!dynamic_ready_) return refine(allowed, out);

  // Which vertices changed their allowed error: all of them when the field is or was uniform, or
  // unknown because the cut came from refine.
  bool all_changed = false;
  bool any_changed = false;
  bool diffed = false;
  if (!field_known_) {
    any_changed = all_changed = true;
  } else if (allowed.per_vertex.empty() || previous_is_uniform_) {
    any_changed = all_changed = !(allowed.per_vertex.empty() && previous_is_uniform_ &&
                                  std::memcmp(&allowed.uniform, &previous_uniform_, sizeof(float)) == 0);
  } else {
    diffed = true;
    const std::size_t count = allowed.per_vertex.size();
    changed_.resize(count);
    const float* now = allowed.per_vertex.data();
    float* before = previous_field_.data();
    // Bitwise comparison: NaN stays equal to itself and -0 differs from +0, both harmless here.
    for (std::size_t v = 0; v < count; ++v) {
      std::uint32_t x, y;
      std::memcpy(&x, now + v, 4);
      std::memcpy(&y, before + v, 4);
      changed_[v] = x != y;
      any_changed |= x != y;
      before[v] = now[v];
    }
  }
  if (!diffed) remember_field(allowed);
  if (!any_changed) {
    emit(out);
    out.within_budget = true;
    return;
  }
  auto vertex_changed = [&](std::uint32_t v) { return all_changed || changed_[v] != 0; };

  // 1. Keep the nodes whose witness still holds (cut_[0] is the root, always kept).
  const std::uint32_t* parent_offsets = mt_.node_parent_offsets.data();
  const std::uint32_t* parents = mt_.node_parents.data();
  std::size_t kept = 1;
  bool dropped_any = false;
  dropped_.clear();
  for (std::size_t i = 1; i < cut_.size(); ++i) {
    const std::uint32_t n = cut_[i];
    const std::uint32_t c = witness_creator_[n];
    const std::uint32_t t = witness_triangle_[n];
    bool keep = in_cut_[c] == kIn;
    if (keep && (vertex_changed(mt_.first_corner(t, c)) || vertex_changed(mt_.triangle_corners[2 * std::size_t{t}]) ||
                 vertex_changed(mt_.triangle_corners[2 * std::size_t{t} + 1])))
      keep = fails(t, c, allowed);
    // Parents can only be missing once something was dropped.
    if (keep && dropped_any)
      for (std::uint32_t j = parent_offsets[n]; j < parent_offsets[n + 1] && keep; ++j) keep = in_cut_[parents[j]] == kIn;
    if (keep) {
      cut_[kept++] = n;
    } else {
      in_cut_[n] = kDropped;
      dropped_.push_back(n);
      dropped_any = true;
    }
  }
  cut_.resize(kept);

  // 2. Examine the triangles of the remaining cut that may fail now: those with a changed vertex and
  // those uncovered by a dropped node. Every other triangle passed before and still does.
  for (std::size_t i = 0; i < kept; ++i) {
    const std::uint32_t n = cut_[i];
    const std::uint32_t end = mt_.node_triangle_offsets[n + 1];
    const bool first_changed = n == 0 ? false : vertex_changed(mt_.node_vertex[n]);
    for (std::uint32_t t = mt_.node_triangle_offsets[n]; t < end; ++t) {
      const std::uint32_t r = mt_.triangle_remover[t];
      if (r == kNoNode || in_cut_[r] == kIn) continue;
      const bool check = in_cut_[r] == kDropped || first_changed ||
                         vertex_changed(mt_.triangle_corners[2 * std::size_t{t}]) ||
                         vertex_changed(mt_.triangle_corners[2 * std::size_t{t} + 1]) ||
                         (n == 0 && vertex_changed(mt_.root_first_corner[t]));
      if (check && fails(t, n, allowed)) force(r, t, n);
    }
  }
  // 3. Nodes added in step 2 (and theirs, in turn) are examined in full.
  close_over(allowed, kept);
  for (const std::uint32_t n : dropped_)
    if (in_cut_[n] == kDropped) in_cut_[n] = kOut;

  emit(out);
  out.within_budget = true;
}

void Refiner::refine_budget(const AllowedError& allowed, std::size_t max_triangles, CutMesh& out) {
  assert(allowed.per_vertex.empty() || allowed.per_vertex.size() == mt_.vertex_count());
  reset_to_root();
  dynamic_ready_ = false;
  std::size_t count = mt_.root_triangle_count();
  heap_.clear();
  auto less = [](const HeapEntry& x, const HeapEntry& y) {
    // Ties broken by triangle id so the result does not depend on the heap's layout.
    if (x.tier != y.tier) return x.tier < y.tier;
    return x.key < y.key || (x.key == y.key && x.triangle > y.triangle);
  };
  auto push_failing = [&](std::uint32_t n) {
    const std::uint32_t end = mt_.node_triangle_offsets[n + 1];
    for (std::uint32_t t = mt_.node_triangle_offsets[n]; t < end; ++t) {
      const std::uint32_t r = mt_.triangle_remover[t];
      if (r == kNoNode || in_cut_[r] == kIn || !fails(t, n, allowed)) continue;
      heap_.push_back(heap_entry(t, n, allowed));
      std::push_heap(heap_.begin(), heap_.end(), less);
    }
  };
  push_failing(0);
  while (!heap_.empty()) {
    std::pop_heap(heap_.begin(), heap_.end(), less);
    const HeapEntry top = heap_.back();
    heap_.pop_back();
    const std::uint32_t r = mt_.triangle_remover[top.triangle];
    if (in_cut_[r] == kIn) continue;  // already refined through another triangle
    const std::size_t first_new = cut_.size();
    force(r, top.triangle, top.creator);
    // Size change: each new node adds what it creates and takes away what it removes.
    std::size_t added = 0, removed = 0;
    for (std::size_t i = first_new; i < cut_.size(); ++i) {
      const std::uint32_t x = cut_[i];
      added += mt_.node_triangle_offsets[x + 1] - mt_.node_triangle_offsets[x];
      for (std::uint32_t j = mt_.node_parent_offsets[x]; j < mt_.node_parent_offsets[x + 1]; ++j) {
        const std::uint32_t p = mt_.node_parents[j];
        for (std::uint32_t t = mt_.node_triangle_offsets[p]; t < mt_.node_triangle_offsets[p + 1]; ++t)
          removed += mt_.triangle_remover[t] == x;
      }
    }
    if (count + added - removed > max_triangles) {
      for (std::size_t i = first_new; i < cut_.size(); ++i) in_cut_[cut_[i]] = kOut;
      cut_.resize(first_new);
      break;
    }
    count = count + added - removed;
    for (std::size_t i = first_new; i < cut_.size(); ++i) push_failing(cut_[i]);
  }
  emit(out);
  out.within_budget = out.triangle_count() <= max_triangles;
}

void refine_static(const Mt& mt, const AllowedError& allowed, CutMesh& out) {
  Refiner refiner(mt);
  refiner.refine(allowed, out);
}

void refine_budget(const Mt& mt, const AllowedError& allowed, std::size_t max_triangles, CutMesh& out) {
  Refiner refiner(mt);
  refiner.refine_budget(allowed, max_triangles, out);
}

}  // namespace mtlod::core

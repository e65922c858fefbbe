// Differences between consecutive cuts by id (see cut_delta.hpp). Two bit arrays over the MT's
// triangles keep every step O(cut), with no sorting; only the pages of the cut's ids are resident
// (ZeroedArray), however large the model. A moved cut, in the order the refiner keeps it, is
// diffed by one ordered pass instead, its bits read for the appended part only.
#include "core/cut/cut_delta.hpp"

#include <algorithm>
#include <cassert>

namespace mtlod::core::cut {
namespace {

bool test(const util::ZeroedArray<std::uint64_t>& bits, std::uint32_t id) {
  return (bits[id >> 6] >> (id & 63)) & 1;
}
void set(util::ZeroedArray<std::uint64_t>& bits, std::uint32_t id) {
  bits[id >> 6] |= std::uint64_t{1} << (id & 63);
}
void clear(util::ZeroedArray<std::uint64_t>& bits, std::uint32_t id) {
  bits[id >> 6] &= ~(std::uint64_t{1} << (id & 63));
}

}  // namespace

bool CutDelta::update(std::span<const std::uint32_t> ids, std::size_t triangle_count,
                      std::vector<std::uint32_t>& added, std::vector<std::uint32_t>& removed) {
  if (triangle_count != triangle_count_) {
    triangle_count_ = triangle_count;
    sent_bits_.reset((triangle_count + 63) / 64);
    next_bits_.reset(sent_bits_.size());
    sent_.clear();
    empty_ = true;
  }
  const bool from_empty = empty_;
  added.clear();
  removed.clear();
  // The same cut in the same order (a gaze that moved no allowed error): nothing to diff.
  if (!empty_ && ids.size() == sent_.size() && std::equal(ids.begin(), ids.end(), sent_.begin()))
    return false;
  // The new cut becomes the client's: sent_bits_ gains the added, loses the removed.
  auto take = [&] {
    for (const std::uint32_t id : removed) clear(sent_bits_, id);
    for (const std::uint32_t i : added) set(sent_bits_, ids[i]);
    sent_.assign(ids.begin(), ids.end());
    empty_ = false;
  };
  if (!empty_ && diff_in_order(ids, added, removed)) {
    take();
    return false;
  }
  for (std::uint32_t i = 0; i < ids.size(); ++i) {
    assert(ids[i] < triangle_count && !test(next_bits_, ids[i]));
    set(next_bits_, ids[i]);
    if (!test(sent_bits_, ids[i])) added.push_back(i);
  }
  for (const std::uint32_t id : sent_) {
    if (!test(next_bits_, id)) removed.push_back(id);
  }
  for (const std::uint32_t id : ids) clear(next_bits_, id);
  take();
  return from_empty;
}

bool CutDelta::diff_in_order(std::span<const std::uint32_t> ids, std::vector<std::uint32_t>& added,
                             std::vector<std::uint32_t>& removed) {
  // The client's ids that stay are matched in order, the others are taken as dropped. Each id of
  // the tail the client has was one of those (the matched part of ids holds distinct ids of the
  // client's, matched once each): moved to the end, not dropped, and struck off the list. A cut
  // refined from the root comes in another order and nearly every id fails to match: once half the
  // client's ids failed while fewer than a quarter as many matched, the pass gives up rather than
  // finish a scan that gains nothing. (A saccade may replace more than half of a cut kept in order.)
  const std::size_t most_removed = sent_.size() / 2;
  std::size_t i = 0;
  for (const std::uint32_t id : sent_) {
    if (i < ids.size() && ids[i] == id) {
      ++i;
    } else {
      removed.push_back(id);
      if (removed.size() > most_removed && 4 * i < removed.size()) {
        removed.clear();
        return false;
      }
    }
  }
  std::size_t moved = 0;
  for (std::size_t k = i; k < ids.size(); ++k) {
    assert(ids[k] < triangle_count_ && !test(next_bits_, ids[k]));
    if (test(sent_bits_, ids[k])) {
      set(next_bits_, ids[k]);
      ++moved;
    } else {
      added.push_back(static_cast<std::uint32_t>(k));
    }
  }
  if (moved > 0) {
    std::erase_if(removed, [&](std::uint32_t id) { return test(next_bits_, id); });
    for (std::size_t k = i; k < ids.size(); ++k) clear(next_bits_, ids[k]);
  }
  return true;
}

void CutDelta::reset() {
  for (const std::uint32_t id : sent_) clear(sent_bits_, id);
  sent_.clear();
  empty_ = true;
}

void gather_triangles(std::span<const std::uint32_t> corners, std::span<const std::uint32_t> ids,
                      std::span<const std::uint32_t> positions, std::vector<std::uint32_t>& triangles,
                      std::vector<std::uint32_t>& gathered_ids) {
  assert(corners.size() == 3 * ids.size());
  triangles.resize(3 * positions.size());
  gathered_ids.resize(positions.size());
  std::uint32_t* corner = triangles.data();
  for (std::size_t k = 0; k < positions.size(); ++k) {
    const std::size_t i = positions[k];
    assert(i < ids.size());
    std::copy_n(&corners[3 * i], 3, corner + 3 * k);
    gathered_ids[k] = ids[i];
  }
}

}  // namespace mtlod::core::cut

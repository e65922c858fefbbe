// Differences between consecutive cuts by id (see cut_delta.hpp). Two bit arrays over the MT's
// triangles keep every step O(cut), with no sorting; only the pages of the cut's ids are resident
// (ZeroedArray), however large the model.
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
  for (std::uint32_t i = 0; i < ids.size(); ++i) {
    assert(ids[i] < triangle_count && !test(next_bits_, ids[i]));
    set(next_bits_, ids[i]);
    if (!test(sent_bits_, ids[i])) added.push_back(i);
  }
  for (const std::uint32_t id : sent_) {
    if (!test(next_bits_, id)) removed.push_back(id);
  }
  // The new cut becomes the client's: sent_bits_ gains the added, loses the removed.
  for (const std::uint32_t id : removed) clear(sent_bits_, id);
  for (const std::uint32_t i : added) set(sent_bits_, ids[i]);
  for (const std::uint32_t id : ids) clear(next_bits_, id);
  sent_.assign(ids.begin(), ids.end());
  empty_ = false;
  return from_empty;
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

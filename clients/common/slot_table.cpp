// Open-addressing id → value map (see slot_table.hpp).
#include "clients/common/slot_table.hpp"

#include <cassert>

namespace mtlod::clients {

void SlotTable::reset(std::size_t expected) {
  std::size_t capacity = 16;
  shift_ = 60;
  while (capacity < 2 * expected) capacity *= 2, --shift_;
  entries_.assign(capacity, Entry{kEmpty, 0});
  size_ = 0;
}

void SlotTable::grow() {
  std::vector<Entry> entries;
  entries.swap(entries_);
  reset(entries.size());  // doubles: reset makes room for twice the expected count
  for (const Entry& e : entries)
    if (e.key != kEmpty) insert(e.key, e.value);
}

void SlotTable::insert(std::uint32_t key, std::uint32_t value) {
  [[maybe_unused]] const bool added = try_insert(key, value);
  assert(added);
}

bool SlotTable::try_insert(std::uint32_t key, std::uint32_t value) {
  assert(key != kEmpty);
  if (2 * (size_ + 1) > entries_.size()) grow();
  const std::size_t mask = entries_.size() - 1;
  std::size_t i = home(key);
  for (; entries_[i].key != kEmpty; i = (i + 1) & mask)
    if (entries_[i].key == key) return false;
  entries_[i] = {key, value};
  ++size_;
  return true;
}

std::size_t SlotTable::position(std::uint32_t key) const {
  const std::size_t mask = entries_.size() - 1;
  std::size_t i = home(key);
  while (entries_[i].key != key) {
    assert(entries_[i].key != kEmpty);
    i = (i + 1) & mask;
  }
  return i;
}

std::size_t SlotTable::find(std::uint32_t key) const {
  if (entries_.empty() || key == kEmpty) return kAbsent;
  const std::size_t mask = entries_.size() - 1;
  for (std::size_t i = home(key);; i = (i + 1) & mask) {
    if (entries_[i].key == key) return i;
    if (entries_[i].key == kEmpty) return kAbsent;  // probe runs end at an empty entry (load ≤ 1/2)
  }
}

std::uint32_t SlotTable::erase_moving_last(std::size_t position, std::uint32_t last_key) {
  const std::uint32_t slot = entries_[position].value;
  // Assigning moves no entry, so the erased key's entry is still at `position` afterwards.
  if (entries_[position].key != last_key) assign(last_key, slot);
  erase_at(position);
  return slot;
}

void SlotTable::erase_at(std::size_t i) {
  const std::size_t mask = entries_.size() - 1;
  // Backward shift: pull later entries of the probe run into the hole so lookups never stop early.
  for (std::size_t j = (i + 1) & mask; entries_[j].key != kEmpty; j = (j + 1) & mask) {
    const std::size_t h = home(entries_[j].key);
    // Entry j may move to i only if its home is not in the cyclic range (i, j].
    if (((j - h) & mask) >= ((j - i) & mask)) {
      entries_[i] = entries_[j];
      i = j;
    }
  }
  entries_[i].key = kEmpty;
  --size_;
}

}  // namespace mtlod::clients

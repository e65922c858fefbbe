// Open-addressing map from a 32-bit id to a 32-bit value (linear probing, backward-shift deletion):
// no node allocations, and key and value share an entry so a probe touches one cache line. Used for
// "where in a dense array is the triangle with this id" (a client's delta mesh). Key 0xFFFFFFFF
// marks an empty entry and cannot be stored.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace mtlod::clients {

class SlotTable {
 public:
  static constexpr std::uint32_t kEmpty = std::numeric_limits<std::uint32_t>::max();
  static constexpr std::size_t kAbsent = std::numeric_limits<std::size_t>::max();

  // Empties the table, sized for about `expected` keys (it grows past that).
  void reset(std::size_t expected);
  // Adds a key that is not present (key != kEmpty).
  void insert(std::uint32_t key, std::uint32_t value);
  // Adds key unless it is present (one probe); false when it was (key != kEmpty).
  bool try_insert(std::uint32_t key, std::uint32_t value);
  // Where key's entry is: it must be present.
  std::size_t position(std::uint32_t key) const;
  // Where key's entry is, or kAbsent.
  std::size_t find(std::uint32_t key) const;
  std::uint32_t value_at(std::size_t position) const { return entries_[position].value; }
  void erase_at(std::size_t position);
  // For values that are slots in a dense array whose last slot holds last_key: erases the entry at
  // `position` and points last_key at the slot it frees (unless last_key is the erased key).
  // Returns that slot, where the caller moves its array's last element before dropping the last.
  std::uint32_t erase_moving_last(std::size_t position, std::uint32_t last_key);
  void assign(std::uint32_t key, std::uint32_t value) { entries_[position(key)].value = value; }
  // Starts fetching the cache line where a probe for key begins.
  void prefetch(std::uint32_t key) const {
    if (!entries_.empty()) __builtin_prefetch(entries_.data() + home(key));
  }
  std::size_t size() const { return size_; }
  std::size_t memory_bytes() const { return entries_.capacity() * sizeof(Entry); }

 private:
  struct Entry {
    std::uint32_t key, value;
  };
  std::size_t home(std::uint32_t key) const { return std::size_t((key * 0x9E3779B97F4A7C15ull) >> shift_); }
  void grow();
  std::vector<Entry> entries_;
  std::size_t size_ = 0;
  unsigned shift_ = 64;
};

}  // namespace mtlod::clients

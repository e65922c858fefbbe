// Stable LSD radix sort by a 32-bit key, shared by the MT builders (core/build/mt_builder.cpp,
// core/build/large_build.cpp): their node order must be the same sort for their files to agree.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <utility>

namespace mtlod::core::util {

// Stable LSD radix sort of `items` by a 32-bit key, 11 bits per pass: equal keys keep their order.
template <class Vector, class Key>
void radix_sort(Vector& items, Vector& scratch, const Key& key) {
  using T = typename Vector::value_type;
  constexpr int kBits = 11;
  constexpr std::uint32_t kBuckets = 1u << kBits;
  scratch.resize(items.size());
  constexpr int kPasses = (32 + kBits - 1) / kBits;
  // Every pass's counts from one read of the items (the passes only permute them).
  std::array<std::array<std::uint32_t, kBuckets>, kPasses> counts{};
  for (const T& x : items) {
    const std::uint32_t k = key(x);
    for (int pass = 0; pass < kPasses; ++pass) ++counts[pass][(k >> (pass * kBits)) & (kBuckets - 1)];
  }
  for (int pass = 0; pass < kPasses; ++pass) {
    // A digit all items share leaves the order as it is.
    if (std::find(counts[pass].begin(), counts[pass].end(), std::uint32_t(items.size())) !=
        counts[pass].end())
      continue;
    std::uint32_t sum = 0;
    for (std::uint32_t& n : counts[pass]) sum += std::exchange(n, sum);
    const int shift = pass * kBits;
    for (const T& x : items) scratch[counts[pass][(key(x) >> shift) & (kBuckets - 1)]++] = x;
    items.swap(scratch);
  }
}

}  // namespace mtlod::core::util

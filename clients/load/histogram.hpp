// A latency histogram with log-linear buckets (the layout of HdrHistogram): values below 2^kSubBits
// are counted exactly; above, each power-of-two range is cut into 2^kSubBits equal buckets, so a
// reported percentile is at most 1/2^kSubBits (0.8 %) above the exact one. Fixed memory, O(1)
// record, mergeable across threads.
#pragma once

#include <cstdint>
#include <vector>

namespace mtlod::clients {

class LatencyHistogram {
 public:
  static constexpr int kSubBits = 7;  // 128 buckets per power of two

  LatencyHistogram();

  void record(std::uint64_t value);
  void merge(const LatencyHistogram& other);
  void clear();

  std::uint64_t count() const { return count_; }
  std::uint64_t min() const { return count_ ? min_ : 0; }
  std::uint64_t max() const { return max_; }
  double mean() const { return count_ ? static_cast<double>(sum_) / static_cast<double>(count_) : 0.0; }

  // The value at `percentile` (0..100): the smallest recorded value v such that at least
  // percentile % of the values are ≤ v, rounded up to its bucket's upper end (never above max()).
  // 0 when empty.
  std::uint64_t value_at_percentile(double percentile) const;

  // Bucket layout, for tests: the bucket of a value and the largest value sharing it.
  static std::size_t bucket_of(std::uint64_t value);
  static std::uint64_t highest_in_bucket(std::size_t bucket);

 private:
  std::vector<std::uint64_t> counts_;
  std::uint64_t count_ = 0;
  std::uint64_t min_ = UINT64_MAX;
  std::uint64_t max_ = 0;
  std::uint64_t sum_ = 0;
};

}  // namespace mtlod::clients

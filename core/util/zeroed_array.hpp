// An array of zeros whose memory comes straight from the kernel (an anonymous mapping): making one
// writes nothing, and only the pages a caller writes become resident. For per-node and per-vertex
// state of a client session, whose length follows the model while the entries in use follow the
// cut: a fresh session of a 100M-triangle model then costs what its cut touches, not 50M zeros.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

namespace mtlod::core::util {

namespace zeroed_detail {
void* map(std::size_t bytes);  // zero-filled, never null (throws std::bad_alloc)
void unmap(void* data, std::size_t bytes);
std::size_t resident(const void* data, std::size_t bytes);  // bytes of the pages in memory
}  // namespace zeroed_detail

template <class T>
class ZeroedArray {
  // All-zero bytes must be the value zero (true of integers and IEEE floats).
  static_assert(std::is_trivially_copyable_v<T> && std::is_arithmetic_v<T>);

 public:
  ZeroedArray() = default;
  explicit ZeroedArray(std::size_t n) { reset(n); }
  ZeroedArray(ZeroedArray&& o) noexcept
      : data_(std::exchange(o.data_, nullptr)), size_(std::exchange(o.size_, 0)) {}
  ZeroedArray& operator=(ZeroedArray&& o) noexcept {
    std::swap(data_, o.data_);
    std::swap(size_, o.size_);
    return *this;
  }
  ZeroedArray(const ZeroedArray&) = delete;
  ZeroedArray& operator=(const ZeroedArray&) = delete;
  ~ZeroedArray() { release(); }

  // Becomes n zeros: a fresh mapping (the old pages go back to the kernel).
  void reset(std::size_t n) {
    release();
    if (n == 0) return;
    data_ = static_cast<T*>(zeroed_detail::map(n * sizeof(T)));
    size_ = n;
  }

  T& operator[](std::size_t i) { return data_[i]; }
  const T& operator[](std::size_t i) const { return data_[i]; }
  T* data() { return data_; }
  const T* data() const { return data_; }
  T* begin() { return data_; }
  T* end() { return data_ + size_; }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  operator std::span<T>() { return {data_, size_}; }
  operator std::span<const T>() const { return {data_, size_}; }

  // Bytes of its pages that are in memory: what the array really costs.
  std::size_t resident_bytes() const { return data_ ? zeroed_detail::resident(data_, size_ * sizeof(T)) : 0; }

 private:
  void release() {
    if (data_) zeroed_detail::unmap(data_, size_ * sizeof(T));
    data_ = nullptr;
    size_ = 0;
  }
  T* data_ = nullptr;
  std::size_t size_ = 0;
};

// Bit i of a bitmap held as 64-bit words (a ZeroedArray<std::uint64_t> of (n + 63) / 64 words).
inline void set_bit(ZeroedArray<std::uint64_t>& bits, std::size_t i) {
  bits[i >> 6] |= std::uint64_t{1} << (i & 63);
}
inline void clear_bit(ZeroedArray<std::uint64_t>& bits, std::size_t i) {
  bits[i >> 6] &= ~(std::uint64_t{1} << (i & 63));
}
inline bool test_bit(const ZeroedArray<std::uint64_t>& bits, std::size_t i) {
  return (bits[i >> 6] >> (i & 63)) & 1;
}

// A ZeroedArray read through a bitmap of the pages written: an entry of a page never written reads
// as zero without the page being touched. Reading spread entries of a fresh mapping otherwise maps
// a page per entry, a fault each (and another when the page is first written): the per-node state
// of a fresh session on a large model, read for every node its cut's triangles name, is mostly
// such reads. The bitmap, a bit per 4 KiB page, stays in the caches (1.6 KB for 52M entries of a
// byte).
template <class T>
class PagedArray {
 public:
  PagedArray() = default;
  explicit PagedArray(std::size_t n) : values_(n), written_((pages(n) + 63) / 64, 0) {}

  T operator[](std::size_t i) const {
    const std::size_t page = i / kPerPage;
    return (written_[page >> 6] >> (page & 63)) & 1 ? values_[i] : T{};
  }
  void set(std::size_t i, T value) {
    const std::size_t page = i / kPerPage;
    written_[page >> 6] |= std::uint64_t{1} << (page & 63);
    values_[i] = value;
  }
  // Entries [0, n) become `value`.
  void fill_prefix(std::size_t n, T value) {
    for (std::size_t page = 0; page < pages(n); ++page)
      written_[page >> 6] |= std::uint64_t{1} << (page & 63);
    std::fill(values_.begin(), values_.begin() + n, value);
  }
  // Where entry i lives, for prefetching (a page never written is not touched by a prefetch).
  const T* address(std::size_t i) const { return values_.data() + i; }
  std::size_t size() const { return values_.size(); }
  std::size_t resident_bytes() const {
    return values_.resident_bytes() + written_.capacity() * sizeof(std::uint64_t);
  }

 private:
  static constexpr std::size_t kPerPage = 4096 / sizeof(T);
  static std::size_t pages(std::size_t n) { return (n + kPerPage - 1) / kPerPage; }
  ZeroedArray<T> values_;
  std::vector<std::uint64_t> written_;  // a bit per page of values_
};

}  // namespace mtlod::core::util

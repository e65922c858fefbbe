// GrowOnlyVector: a std::vector whose resize leaves new elements uninitialised, for big arrays whose
// new slots are all written right after growing (no zero fill on one thread first).
#pragma once

#include <memory>
#include <new>
#include <utility>
#include <vector>

namespace mtlod::core::util {

// An allocator whose resize leaves new elements uninitialised (default-initialised), for arrays
// whose new slots are all written right after growing.
template <class T>
struct DefaultInitAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};
template <class T>
using GrowOnlyVector = std::vector<T, DefaultInitAllocator<T>>;

}  // namespace mtlod::core::util

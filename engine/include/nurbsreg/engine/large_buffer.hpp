#pragma once
// An allocator for per-point arrays of whole frames (millions of points): allocations of 4 MiB
// and more get their own anonymous mapping, aligned to 2 MiB, whose pages are faulted in at
// allocation on all TBB threads. A first touch is a zeroed page and, on a VM whose host backs
// guest memory lazily, a host fault too: faulted in by whatever serial loop first wrote the array
// (std::vector's value-initialisation), the fresh arrays of a 1,000,000-point alignment (~300 MB)
// took about a quarter of its time on a 2-core VM (bench/README.md "Warm certificates"), and on
// two threads it takes half the wall time. No huge-page advice (large_buffer.cpp says why).
// Smaller allocations use plain operator new. Stateless: every instance compares equal.

#include <cstddef>
#include <new>
#include <vector>

namespace nurbsreg::engine {

namespace detail {
// Defined in large_buffer.cpp.
void* allocate_large(std::size_t bytes);
void deallocate_large(void* p, std::size_t bytes) noexcept;
inline constexpr std::size_t kLargeBufferThreshold = std::size_t{4} << 20;
}  // namespace detail

template <class T>
struct LargeBufferAllocator {
  using value_type = T;
  LargeBufferAllocator() = default;
  template <class U>
  LargeBufferAllocator(const LargeBufferAllocator<U>&) noexcept {}

  T* allocate(std::size_t n) {
    if (n > std::size_t(-1) / sizeof(T)) throw std::bad_array_new_length();
    const std::size_t bytes = n * sizeof(T);
    if (bytes < detail::kLargeBufferThreshold) {
      return static_cast<T*>(::operator new(bytes, std::align_val_t(alignof(T))));
    }
    return static_cast<T*>(detail::allocate_large(bytes));
  }
  void deallocate(T* p, std::size_t n) noexcept {
    const std::size_t bytes = n * sizeof(T);
    if (bytes < detail::kLargeBufferThreshold) {
      ::operator delete(p, std::align_val_t(alignof(T)));
    } else {
      detail::deallocate_large(p, bytes);
    }
  }
  template <class U>
  bool operator==(const LargeBufferAllocator<U>&) const noexcept {
    return true;
  }
};

// A per-point array of a frame.
template <class T>
using FrameVector = std::vector<T, LargeBufferAllocator<T>>;

}  // namespace nurbsreg::engine

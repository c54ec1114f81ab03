#include "nurbsreg/engine/large_buffer.hpp"

#include <sys/mman.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstdint>

namespace nurbsreg::engine::detail {

namespace {
constexpr std::size_t kHugePage = std::size_t{2} << 20;

std::size_t mapped_size(std::size_t bytes) {
  return (bytes + kHugePage - 1) / kHugePage * kHugePage;
}
}  // namespace

void* allocate_large(std::size_t bytes) {
  const std::size_t size = mapped_size(bytes);
  // Map 2 MiB more than needed and unmap the unaligned head and tail, so that the region starts
  // on a 2 MiB boundary: where the system backs anonymous memory with transparent huge pages
  // (THP "always"), the whole array can take them. No MADV_HUGEPAGE of its own: on the 2-core
  // VMs this runs on, a fresh huge page cost about five times the first touch of its 512 small
  // pages (the host backs the free huge blocks the guest hands back only when touched again),
  // and a whole alignment from any pose ran slower with the advice than without; the projection
  // itself showed no difference (bench/README.md, "Twenty-sixth pass").
  const std::size_t span = size + kHugePage;
  void* raw = mmap(nullptr, span, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (raw == MAP_FAILED) throw std::bad_alloc();
  const auto base = reinterpret_cast<std::uintptr_t>(raw);
  const std::uintptr_t aligned = (base + kHugePage - 1) / kHugePage * kHugePage;
  if (aligned > base) munmap(raw, aligned - base);
  const std::uintptr_t end = base + span;
  if (end > aligned + size) munmap(reinterpret_cast<void*>(aligned + size), end - aligned - size);
  void* p = reinterpret_cast<void*>(aligned);
  // Fault the pages in now, on every thread, rather than page by page in whatever serial loop
  // first writes the array (std::vector's value-initialisation): a first touch costs the kernel
  // a zeroed page and, on a VM whose host backs guest memory lazily, a host fault too. Measured
  // on this 2-core VM for 512 MB: 830 ms on one thread, 450 ms on two (and ~30 ms once backed).
  constexpr std::size_t kPage = 4096;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, size, kHugePage),
                    [p](const tbb::blocked_range<std::size_t>& r) {
                      auto* bytes = static_cast<volatile unsigned char*>(p);
                      for (std::size_t offset = r.begin(); offset < r.end(); offset += kPage)
                        bytes[offset] = 0;
                    });
  return p;
}

void deallocate_large(void* p, std::size_t bytes) noexcept {
  if (p != nullptr) munmap(p, mapped_size(bytes));
}

}  // namespace nurbsreg::engine::detail

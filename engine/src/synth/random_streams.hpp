#pragma once
// Internal: reproducible random streams for work split into fixed chunks (sampling, synthetic
// scans). Each chunk draws from its own generator seeded from (seed, chunk), so the results
// depend on the seed and the sizes, not on the number of threads or their schedule.

#include <cstddef>
#include <cstdint>

namespace nurbsreg::engine {

// Samples drawn by one task.
inline constexpr std::size_t kSampleChunk = 8192;

// The seed of chunk `chunk`'s stream (splitmix64 of the two): neighbouring chunks get
// unrelated streams.
inline std::uint64_t chunk_seed(std::uint64_t seed, std::uint64_t chunk) {
  std::uint64_t z = seed + 0x9e3779b97f4a7c15ull * (chunk + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

}  // namespace nurbsreg::engine

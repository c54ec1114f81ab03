#pragma once
// How big the few heavy tests are. The sanitizer builds (scripts/test.sh's asan and tsan stages,
// tests/CMakeLists.txt defines NURBSREG_REDUCED_TESTS there) run the same checks on smaller
// inputs: they hunt for memory and threading errors, which every input size exercises, and run
// several times slower than Release, which keeps the full sizes for the numerical claims.

namespace nurbsreg::test {

#ifdef NURBSREG_REDUCED_TESTS
inline constexpr bool kReducedTests = true;
#else
inline constexpr bool kReducedTests = false;
#endif

// `full` in the Release suite, `reduced` under sanitizers.
template <class T>
constexpr T test_size(T full, T reduced) {
  return kReducedTests ? reduced : full;
}

}  // namespace nurbsreg::test

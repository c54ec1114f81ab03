#pragma once

// Runtime CPU dispatch for the projection's hot kernels.
//
// NURBSREG_HOT_CLONES on a function makes GCC compile it twice, for the x86-64 baseline (SSE2)
// and for x86-64-v3 (AVX2, BMI2, FMA), and pick one at load time through an ifunc resolver
// (function multiversioning, target_clones). One portable binary then runs the wider code on
// the CPUs that have it. A clone's callees are not cloned unless inlined into it: the attribute
// goes on the outermost function that inlines a hot loop, never on a tiny function called
// millions of times (each call goes through the ifunc and cannot be inlined).
//
// The attribute goes on the definition only: the defining translation unit exports the ifunc under
// the function's own name, and other units call it through a plain declaration (a declaration
// with the attribute would make them emit a resolver of their own, for clones they cannot see).
//
// The clones give bit-identical results: both evaluate the same IEEE operations in the same
// order. Floating-point contraction (a * b + c -> FMA, which x86-64-v3 has) is turned off for
// every nurbsreg target (-ffp-contract=off, cmake/NurbsregTarget.cmake; GCC contracts by default
// even with -std=c++20) and there is no -ffast-math. Tests (tests/dispatch): the libraries hold
// no FMA instruction and no AVX instruction outside the clones, and a fixed set of projections
// gives bit-identical results with every dispatch forced to the baseline.
//
// Empty (one plain function) when:
//  - the compiler is not GCC or the target not x86-64 (Clang accepts target_clones only from
//    version 14 and orders its resolver differently; untested here),
//  - the build already targets AVX2 (NURBSREG_NATIVE: -march=native defines __AVX2__),
//  - NURBSREG_CPU_DISPATCH is OFF in CMake (NURBSREG_CPU_DISPATCH undefined here), e.g. for
//    tools (valgrind, older binutils) that handle ifuncs badly.
#if defined(NURBSREG_CPU_DISPATCH) && defined(__GNUC__) && !defined(__clang__) && \
    defined(__x86_64__) && !defined(__AVX2__)
#define NURBSREG_HOT_CLONES [[gnu::target_clones("arch=x86-64-v3", "default")]]
// Where the two versions need different source (e.g. a wider vector type, which a clone cannot
// select: __AVX2__ is not defined inside it), `#if NURBSREG_HOT_VERSIONS` and two definitions of
// the function, one NURBSREG_TARGET_V3 and one NURBSREG_TARGET_DEFAULT (GCC C++ function
// multiversioning: the same ifunc dispatch). Both must compute the same values.
#define NURBSREG_HOT_VERSIONS 1
#define NURBSREG_TARGET_V3 [[gnu::target("arch=x86-64-v3")]]
#define NURBSREG_TARGET_DEFAULT [[gnu::target("default")]]
#else
#define NURBSREG_HOT_CLONES
#define NURBSREG_HOT_VERSIONS 0
#endif

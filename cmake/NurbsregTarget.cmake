# One place that applies the project's standard to our own targets only:
# C++20, warnings as errors. Nothing here leaks to dependencies or consumers.

# Code for the build machine's own instruction set (AVX2 etc.): faster projection, binaries that
# may not run elsewhere. Every nurbsreg target gets the same flags. Eigen's static alignment stays
# at 16 bytes so that the layout of Eigen members (Vec4 in BezierPatch, ...) is the same as in the
# prebuilt libraries we link (PCL), which are compiled for SSE2.
option(NURBSREG_NATIVE "Compile nurbsreg's targets with -march=native (not portable)" OFF)
# The portable build's hot kernels are compiled for SSE2 and for x86-64-v3 (AVX2), chosen at load
# time (engine/src/platform/cpu_dispatch.hpp). OFF: SSE2 only. Without effect when NURBSREG_NATIVE is on.
option(NURBSREG_CPU_DISPATCH "Runtime dispatch of the hot kernels to AVX2 clones (GCC, x86-64)" ON)

# Sanitizer and fuzzing builds (scripts/test.sh builds them in build-asan/ and build-tsan/ with
# clang; README "Tests under sanitizers"). The flags go to nurbsreg's own targets only; link
# options are PUBLIC so that every executable linking a sanitized library links the runtime.
set(NURBSREG_SANITIZE "" CACHE STRING
    "Sanitizers for nurbsreg's targets: empty, address,undefined or thread")
option(NURBSREG_FUZZ "Build the libFuzzer harnesses in tests/fuzz (Clang only)" OFF)
option(NURBSREG_WERROR "Warnings are errors on nurbsreg's targets" ON)
if(NURBSREG_FUZZ AND NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
  message(FATAL_ERROR "NURBSREG_FUZZ needs Clang (libFuzzer): configure with CXX=clang++")
endif()

# libFuzzer's coverage instrumentation (-fsanitize=fuzzer-no-link), with NURBSREG_FUZZ, only on
# the harnesses and the modules whose code they explore: the readers (io) and the service's
# request parsing. Not on the engine and the other modules: the test suite runs in the same
# build directory (scripts/test.sh's asan stage), and a callback at every comparison of the
# numeric kernels would slow it for coverage no harness is after (the JSON model harness
# reaches the engine only to check the parsed model's distances).
set(NURBSREG_FUZZ_MODULES "io;service" CACHE STRING
    "Modules instrumented for libFuzzer's coverage when NURBSREG_FUZZ is on")
function(nurbsreg_apply_fuzz_coverage target)
  if(NURBSREG_FUZZ)
    target_compile_options(${target} PRIVATE -fsanitize=fuzzer-no-link)
    target_link_options(${target} PUBLIC -fsanitize=fuzzer-no-link)
  endif()
endfunction()

function(nurbsreg_apply_standard target)
  target_compile_features(${target} PUBLIC cxx_std_20)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  if(CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
    # No floating-point contraction: GCC contracts a * b + c into an FMA by default in C++, even
    # with -std=c++20 (only ISO C modes turn it off), wherever the target has one (-march=native,
    # the x86-64-v3 clones). Off, the clones and a native build project bit-identically to the
    # portable build (Eigen's own FMA intrinsics in its dense matrix products remain natively).
    target_compile_options(${target} PRIVATE -Wall -Wextra -ffp-contract=off)
    if(NURBSREG_WERROR)
      target_compile_options(${target} PRIVATE -Werror)
    endif()
    if(NURBSREG_SANITIZE)
      # UBSan findings abort (a test fails) instead of printing and going on.
      target_compile_options(${target} PRIVATE -fsanitize=${NURBSREG_SANITIZE}
                                               -fno-omit-frame-pointer -fno-sanitize-recover=all)
      target_link_options(${target} PUBLIC -fsanitize=${NURBSREG_SANITIZE})
    endif()
    if(NURBSREG_NATIVE)
      target_compile_options(${target} PRIVATE -march=native)
      target_compile_definitions(${target} PRIVATE EIGEN_MAX_STATIC_ALIGN_BYTES=16)
    elseif(NURBSREG_CPU_DISPATCH)
      target_compile_definitions(${target} PRIVATE NURBSREG_CPU_DISPATCH)
    endif()
  endif()
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    # GCC 12 at -O3 reports these falsely on Eigen fixed-size arrays and std::string
    # concatenation (GCC bugs 105329, 105651): still shown, not fatal.
    target_compile_options(${target} PRIVATE -Wno-error=maybe-uninitialized -Wno-error=restrict
                                             -Wno-error=array-bounds -Wno-error=stringop-overflow)
  endif()
endfunction()

# nurbsreg_add_module(<name> [RECURSE] [PUBLIC_DEPS <targets...>] [PRIVATE_DEPS <targets...>])
# A static library from <name>/src/*.cpp (RECURSE: also from the folders below src/, one folder
# per job) with public headers in <name>/include, exported as nurbsreg::<name>.
function(nurbsreg_add_module name)
  cmake_parse_arguments(ARG "RECURSE" "" "PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  if(ARG_RECURSE)
    file(GLOB_RECURSE sources CONFIGURE_DEPENDS "${CMAKE_CURRENT_SOURCE_DIR}/src/*.cpp")
  else()
    file(GLOB sources CONFIGURE_DEPENDS "${CMAKE_CURRENT_SOURCE_DIR}/src/*.cpp")
  endif()
  if(NOT sources)
    message(STATUS "nurbsreg: module ${name} has no sources yet; skipped")
    return()
  endif()
  add_library(nurbsreg_${name} STATIC ${sources})
  add_library(nurbsreg::${name} ALIAS nurbsreg_${name})
  target_include_directories(nurbsreg_${name} PUBLIC "${CMAKE_CURRENT_SOURCE_DIR}/include")
  target_link_libraries(nurbsreg_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  nurbsreg_apply_standard(nurbsreg_${name})
  if(name IN_LIST NURBSREG_FUZZ_MODULES)
    nurbsreg_apply_fuzz_coverage(nurbsreg_${name})
  endif()
endfunction()

# One place that applies the project's standard to our own targets only:
# C++20, warnings as errors. Nothing here leaks to dependencies or consumers.

# Code for the build machine's own instruction set (AVX2 etc.): faster projection, binaries that
# may not run elsewhere. Every nurbsreg target gets the same flags. Eigen's static alignment stays
# at 16 bytes so that the layout of Eigen members (Vec4 in BezierPatch, ...) is the same as in the
# prebuilt libraries we link (PCL), which are compiled for SSE2. Floating-point contraction is
# turned off (GCC contracts a * b + c into an FMA by default in C++ when the target has one), so
# results are bit-identical to the portable build's.
option(NURBSREG_NATIVE "Compile nurbsreg's targets with -march=native (not portable)" OFF)

function(nurbsreg_apply_standard target)
  target_compile_features(${target} PUBLIC cxx_std_20)
  set_target_properties(${target} PROPERTIES CXX_EXTENSIONS OFF)
  if(CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
    target_compile_options(${target} PRIVATE -Wall -Wextra -Werror)
    if(NURBSREG_NATIVE)
      target_compile_options(${target} PRIVATE -march=native -ffp-contract=off)
      target_compile_definitions(${target} PRIVATE EIGEN_MAX_STATIC_ALIGN_BYTES=16)
    endif()
  endif()
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    # GCC 12 at -O3 reports these falsely on Eigen fixed-size arrays and std::string
    # concatenation (GCC bugs 105329, 105651): still shown, not fatal.
    target_compile_options(${target} PRIVATE -Wno-error=maybe-uninitialized -Wno-error=restrict
                                             -Wno-error=array-bounds -Wno-error=stringop-overflow)
  endif()
endfunction()

# nurbsreg_add_module(NAME <name> [DEPS <targets...>])
# A static library from <name>/src/*.cpp with public headers in <name>/include,
# exported as nurbsreg::<name>.
function(nurbsreg_add_module name)
  cmake_parse_arguments(ARG "" "" "PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  file(GLOB sources CONFIGURE_DEPENDS "${CMAKE_CURRENT_SOURCE_DIR}/src/*.cpp")
  if(NOT sources)
    message(STATUS "nurbsreg: module ${name} has no sources yet; skipped")
    return()
  endif()
  add_library(nurbsreg_${name} STATIC ${sources})
  add_library(nurbsreg::${name} ALIAS nurbsreg_${name})
  target_include_directories(nurbsreg_${name} PUBLIC "${CMAKE_CURRENT_SOURCE_DIR}/include")
  target_link_libraries(nurbsreg_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  nurbsreg_apply_standard(nurbsreg_${name})
endfunction()

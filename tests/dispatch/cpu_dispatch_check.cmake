# ctest checks of the runtime CPU dispatch (engine/src/platform/cpu_dispatch.hpp), run with cmake -P.
#
# MODE=instructions, on the libraries LIBS (;-separated):
#  - no fused multiply-add instruction. An FMA rounds once where a * b + c rounds twice: one in a
#    clone (or in a -march=native build) would make its results differ from the baseline's.
#  - EXPECT_CLONES=ON (a portable build with dispatch): x86-64-v3 clones exist (the check is not
#    passed by an empty dispatch), and no VEX-encoded (AVX) instruction appears outside them, so
#    the libraries run on a CPU without AVX.
# MODE=identical: PROBE (normal dispatch) and BASELINE (the same probe forced to the baseline
#   clones) must print the same digests. On a CPU without AVX2 both run the baseline code: then
#   "nothing compared" is printed (SKIP_REGULAR_EXPRESSION).

if(MODE STREQUAL "instructions")
  foreach(lib IN LISTS LIBS)
    execute_process(COMMAND "${OBJDUMP}" -d --no-show-raw-insn "${lib}"
                    OUTPUT_VARIABLE asm RESULT_VARIABLE rc)
    if(NOT rc EQUAL 0)
      message(FATAL_ERROR "${OBJDUMP} -d ${lib} failed (${rc})")
    endif()
    string(REGEX MATCHALL "[ \t]vf(n?)m(add|sub|addsub|subadd)[0-9a-z]*[ \t]" fma "${asm}")
    list(LENGTH fma count)
    if(count GREATER 0)
      list(REMOVE_DUPLICATES fma)
      message(FATAL_ERROR "${lib}: ${count} FMA instructions (${fma}): contraction is on somewhere "
                          "(-ffp-contract=off, cmake/NurbsregTarget.cmake)")
    endif()
    message(STATUS "${lib}: no FMA instruction")
    if(EXPECT_CLONES)
      # One block per function, "<name>:" first; a VEX instruction's mnemonic starts with v.
      string(REPLACE ";" "," asm "${asm}")
      string(REPLACE "\n\n" ";" blocks "${asm}")
      set(avx "")
      foreach(block IN LISTS blocks)
        if(NOT block MATCHES "^[0-9a-f]+ <([^>]*)>:\n")
          continue()
        endif()
        set(function "${CMAKE_MATCH_1}")
        if(function MATCHES "arch_x86_64_v3")  # a clone, or a part split off one
          continue()
        endif()
        if(block MATCHES "\n +[0-9a-f]+:\t(v[a-z0-9]+)[ \n]")
          list(APPEND avx "${function} (${CMAKE_MATCH_1})")
        endif()
      endforeach()
      if(avx)
        message(FATAL_ERROR "${lib}: AVX instructions outside the x86-64-v3 clones: ${avx}")
      endif()
    endif()
  endforeach()
  if(EXPECT_CLONES)
    list(GET LIBS 0 first)
    execute_process(COMMAND "${OBJDUMP}" -t "${first}" OUTPUT_VARIABLE symbols)
    string(REGEX MATCHALL "\\.arch_x86_64_v3" clones "${symbols}")
    list(LENGTH clones count)
    if(count EQUAL 0)
      message(FATAL_ERROR "${first}: no x86-64-v3 clone, but the dispatch is on")
    endif()
    message(STATUS "${first}: ${count} x86-64-v3 clones; no AVX instruction outside them")
  endif()
elseif(MODE STREQUAL "identical")
  foreach(exe PROBE BASELINE)
    execute_process(COMMAND "${${exe}}" OUTPUT_VARIABLE out_${exe} RESULT_VARIABLE rc)
    if(NOT rc EQUAL 0)
      message(FATAL_ERROR "${${exe}} failed (${rc}):\n${out_${exe}}")
    endif()
  endforeach()
  message(STATUS "dispatching:\n${out_PROBE}baseline:\n${out_BASELINE}")
  if(NOT out_BASELINE MATCHES "^avx2 0\n")
    message(FATAL_ERROR "the baseline probe still sees AVX2: its CPU model was not replaced")
  endif()
  string(REGEX REPLACE "^avx2 [01]\n" "" digests_PROBE "${out_PROBE}")
  string(REGEX REPLACE "^avx2 [01]\n" "" digests_BASELINE "${out_BASELINE}")
  if(NOT digests_PROBE STREQUAL digests_BASELINE)
    message(FATAL_ERROR "the AVX2 and the baseline clones give different results")
  endif()
  if(out_PROBE MATCHES "^avx2 0\n")
    message(STATUS "this CPU has no AVX2: both runs used the baseline clones; nothing compared")
    return()
  endif()
  message(STATUS "AVX2 and baseline clones: identical results")
else()
  message(FATAL_ERROR "MODE must be instructions or identical")
endif()

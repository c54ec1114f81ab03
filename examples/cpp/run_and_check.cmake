# ctest driver of the examples: runs PROGRAM with ARGS, fails on a non-zero exit status, then for
# every check "regex@min@max" in CHECKS (separated by #) requires the regex to match the output and the number it
# captures to lie in [min, max].
execute_process(COMMAND ${PROGRAM} ${ARGS} OUTPUT_VARIABLE out ERROR_VARIABLE err
                RESULT_VARIABLE status)
message("${out}${err}")
if(NOT status EQUAL 0)
  message(FATAL_ERROR "${PROGRAM} exited with ${status}")
endif()
string(REPLACE "#" ";" checks "${CHECKS}")
foreach(check IN LISTS checks)
  string(REPLACE "@" ";" parts "${check}")
  list(GET parts 0 regex)
  list(GET parts 1 low)
  list(GET parts 2 high)
  if(NOT out MATCHES "${regex}")
    message(FATAL_ERROR "output does not match \"${regex}\"")
  endif()
  set(value "${CMAKE_MATCH_1}")
  if(value LESS low OR value GREATER high)
    message(FATAL_ERROR "\"${regex}\": ${value} is outside [${low}, ${high}]")
  endif()
endforeach()

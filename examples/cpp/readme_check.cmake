# Fails unless README contains EXAMPLE verbatim (the README's first C++ example is compiled
# and run as that program).
file(READ "${README}" readme)
file(READ "${EXAMPLE}" example)
string(FIND "${readme}" "${example}" at)
if(at EQUAL -1)
  message(FATAL_ERROR "${README} does not contain ${EXAMPLE} verbatim")
endif()

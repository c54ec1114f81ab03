# cmake -DINPUT=<file> -DOUTPUT=<file.cpp> -DSYMBOL=<name> -P embed_file.cmake
# Writes a C++ source that defines `std::string_view nurbsreg::inspect::embedded::<SYMBOL>()` with
# the bytes of INPUT, so the report's JavaScript and CSS live inside the nurbsreg binary.
file(READ "${INPUT}" hex HEX)
string(LENGTH "${hex}" hex_length)
math(EXPR size "${hex_length} / 2")
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "'\\\\x\\1'," bytes "${hex}")
# Line breaks every 32 bytes keep the generated file readable by compilers' diagnostics.
string(REGEX REPLACE "(('[^']*',){32})" "\\1\n" bytes "${bytes}")
file(WRITE "${OUTPUT}.tmp"
  "// Generated from ${INPUT} by embed_file.cmake: do not edit.\n"
  "#include <string_view>\n"
  "namespace nurbsreg::inspect::embedded {\n"
  "namespace { const char data[] = {\n${bytes}'\\0'}; }\n"
  "std::string_view ${SYMBOL}() { return {data, ${size}}; }\n"
  "}  // namespace nurbsreg::inspect::embedded\n")
file(RENAME "${OUTPUT}.tmp" "${OUTPUT}")

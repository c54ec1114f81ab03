// libFuzzer harness: STEP or IGES files (read_cad_file), chosen at compile time by
// NURBSREG_FUZZ_EXTENSION (".step" or ".iges"). The import runs as users run it, in a child
// process (cad_isolation.hpp): whatever OpenCASCADE does with the input, this process must get
// a model or one printable InputError naming the file. With NURBSREG_CAD_IN_PROCESS=1 the
// import runs in this process instead, so that coverage guides the fuzzer through OpenCASCADE
// and our conversion (crashes found that way are OCCT's, contained by the child in production).
#include <cstdlib>

#include "fuzz_support.hpp"
#include "nurbsreg/io/cad_import.hpp"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  setenv("NURBSREG_CAD_TIMEOUT", "20", 0);
  setenv("NURBSREG_MAX_BEZIER_POINTS", "200000", 0);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string& path = nurbsreg::fuzz::write_input(NURBSREG_FUZZ_EXTENSION, data, size);
  try {
    (void)nurbsreg::io::read_cad_file(path);
  } catch (const nurbsreg::io::InputError& e) {
    nurbsreg::fuzz::check_message(e, path);
  }
  return 0;
}

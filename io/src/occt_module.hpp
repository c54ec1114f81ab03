#pragma once
// STEP/IGES import through OpenCASCADE lives in a module of its own, libnurbsreg_occt.so
// (io/occt/), loaded with dlopen on the first import (private to io).
//
// Why a module. OpenCASCADE's 15 libraries and their dependencies took about 20 ms of loading
// and relocation at every start of every process linking io (the CLI, the Python package, the
// service, the tests), though most of them never read a CAD file. Only an import loads them now.
//
// The module and io come from the same build: the call passes C++ objects (the path, the
// report, the model) by pointer, and the module answers with a status instead of throwing
// across the boundary. kOcctModuleAbi and the program version, checked on loading, keep a
// module of another build from being used.
//
// Where the module is looked for, first found wins: $NURBSREG_OCCT_MODULE (a file); beside the
// executable or shared object that holds io (the build puts it beside `nurbsreg`); the build
// tree's own copy (a path fixed at build time, for the tests, benchmarks and the Python package).

#include <string>

#include "nurbsreg/engine/model.hpp"
#include "nurbsreg/io/cad_import.hpp"

namespace nurbsreg::io::cad_detail {

inline constexpr int kOcctModuleAbi = 2;
inline constexpr const char* kOcctModuleFile = "libnurbsreg_occt.so";

struct OcctImportCall {
  enum Status { kOk = 0, kInputError = 1, kOutOfMemory = 2, kFailure = 3 };
  const std::string* path = nullptr;
  bool step = true;                   // STEP, else IGES (io decides by the extension)
  CadImportReport* report = nullptr;  // filled (never null)
  engine::Model* model = nullptr;     // the converted model, with kOk
  Status status = kFailure;
  // kInputError: what is wrong with the file (without the path); kFailure: the exception's text.
  std::string* error = nullptr;
};

// The module's exported functions (extern "C", so that dlsym finds them by these names): its
// kOcctModuleAbi, its program version, and the import.
using OcctImportFunction = void (*)(OcctImportCall*);
inline constexpr const char* kOcctAbiSymbol = "nurbsreg_occt_abi";
inline constexpr const char* kOcctVersionSymbol = "nurbsreg_occt_version";
inline constexpr const char* kOcctImportSymbol = "nurbsreg_occt_import";

// Loads the module once per process (thread-safe); throws std::runtime_error naming the places
// it looked when it cannot. Called before the import's fork, so that the child finds it loaded.
OcctImportFunction occt_import_function();

}  // namespace nurbsreg::io::cad_detail

#pragma once

#include <string>

// Where a test (or benchmark) finds the project's files, compiled into its program by
// cmake/SourcePaths.cmake (not into every object's compile command, so that a compiler cache
// shares objects between checkouts).
namespace nurbsreg::test {

// The project's examples/ folder.
std::string examples_dir();
// The shared/ folder (beside the checkout, or the CMake cache's NURBSREG_SHARED_DIR).
std::string shared_dir();
// The `nurbsreg` binary of this build; empty where the program was built without the CLI.
std::string nurbsreg_binary();

}  // namespace nurbsreg::test

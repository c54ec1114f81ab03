#pragma once
// Limits on what one input may make nurbsreg allocate or spend (README "Resource limits").
//
// A file's header can claim any size: the readers never allocate beyond what the file's bytes
// can hold, and these limits bound what a valid but enormous input may cost, so that a hostile
// or mistaken file ends with a clear message (exit 3) instead of exhausting the machine. Each
// default can be raised (or lowered) with an environment variable, read at every call, so the
// CLI, batch jobs and library users share one switch:
//
//   NURBSREG_MAX_FILE_BYTES     bytes of one input file read into memory   default 8 GiB
//   NURBSREG_MAX_POINTS         points of one point cloud                  default 200,000,000
//   NURBSREG_MAX_BEZIER_POINTS  control points of a model's Bézier patches and curve pieces
//                               after decomposition (what a prepared model's memory grows
//                               with: about 60 bytes each)              default 4,000,000
//   NURBSREG_CAD_TIMEOUT        seconds of wall-clock time of one STEP/IGES import (its
//                               child process, cad_import.hpp)              default 600
//   NURBSREG_CAD_MEMORY_MB      address space of that child, MiB            default 16384
//
// Values are positive integers (a suffix-free decimal). A malformed value throws InputError
// naming the variable. Thread-safe (getenv only).

#include <cstdint>

namespace nurbsreg::io {

struct ResourceLimits {
  std::uint64_t max_file_bytes = std::uint64_t{8} << 30;
  std::uint64_t max_points = 200'000'000;
  std::uint64_t max_bezier_points = 4'000'000;
  std::uint64_t cad_timeout_seconds = 600;
  std::uint64_t cad_memory_mb = 16384;
};

// The defaults above, each replaced by its environment variable when that is set.
ResourceLimits resource_limits();

}  // namespace nurbsreg::io

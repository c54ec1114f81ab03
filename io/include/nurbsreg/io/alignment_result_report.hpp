#pragma once
// The alignment report (alignment_report.hpp) of one registration::Aligner run, filled the same
// way for `align --report`, `batch` and the service's POST /v1/align, so that a frame reports
// the same fields and numbers everywhere. Thread-safe; allocates (not a hot path).

#include <cstddef>

#include "nurbsreg/io/alignment_report.hpp"
#include "nurbsreg/registration/alignment.hpp"

namespace nurbsreg::io {

// `method` is the run's IcpOptions method, `skipped_points` the cloud's non-finite points and
// `seconds` the caller's wall time for the frame (the single command: since it started).
AlignmentReport make_alignment_report(const registration::AlignmentResult& frame,
                                      icp::IcpMethod method, std::size_t skipped_points,
                                      double seconds);

}  // namespace nurbsreg::io

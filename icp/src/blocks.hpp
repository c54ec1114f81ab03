#pragma once
// Internal to the icp library: per-point loops over fixed blocks of indices.

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstddef>

#include "nurbsreg/engine/cancellation.hpp"
#include "nurbsreg/icp/icp.hpp"

namespace nurbsreg::icp::detail {

// Runs body(begin, end, block) over fixed blocks of kReductionBlock indices in [0, n), on TBB
// threads or serially. Bodies write only to their own block's slot, so combining the slots
// in block order afterwards gives the same bits for any thread count (STYLE.md point 9).
template <class Body>
void for_each_block(std::size_t n, bool parallel, const Body& body) {
  const std::size_t blocks = (n + kReductionBlock - 1) / kReductionBlock;
  const auto run = [&](std::size_t b) {
    body(b * kReductionBlock, std::min(n, (b + 1) * kReductionBlock), b);
  };
  if (parallel && blocks > 1) {
    tbb::parallel_for(std::size_t{0}, blocks, run);
    nurbsreg::engine::stop_if_cancelled();
  } else {
    for (std::size_t b = 0; b < blocks; ++b)
      run(b);
  }
}

}  // namespace nurbsreg::icp::detail

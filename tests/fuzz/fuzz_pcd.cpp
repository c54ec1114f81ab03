// libFuzzer harness: PCD point clouds (read_point_cloud) and PCD tables (read_point_table).
#include <cmath>
#include <cstdlib>

#include "fuzz_support.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/io/point_table.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string& path = nurbsreg::fuzz::write_input(".pcd", data, size);
  try {
    const nurbsreg::io::PointCloud cloud = nurbsreg::io::read_point_cloud(path);
    // Every kept point is finite and within range; the counts add up.
    if (cloud.points.size() + cloud.skipped_nonfinite != cloud.total) std::abort();
    for (const auto& p : cloud.points) {
      if (!p.allFinite()) std::abort();
    }
  } catch (const nurbsreg::io::InputError& e) {
    nurbsreg::fuzz::check_message(e, path);
  }
  try {
    (void)nurbsreg::io::read_point_table(path);
  } catch (const nurbsreg::io::InputError& e) {
    nurbsreg::fuzz::check_message(e, path);
  }
  return 0;
}

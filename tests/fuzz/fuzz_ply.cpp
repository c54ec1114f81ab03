// libFuzzer harness: PLY point clouds (ascii and binary, read_point_cloud).
#include <cstdlib>

#include "fuzz_support.hpp"
#include "nurbsreg/io/point_cloud.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string& path = nurbsreg::fuzz::write_input(".ply", data, size);
  try {
    const nurbsreg::io::PointCloud cloud = nurbsreg::io::read_point_cloud(path);
    if (cloud.points.size() + cloud.skipped_nonfinite != cloud.total) std::abort();
  } catch (const nurbsreg::io::InputError& e) {
    nurbsreg::fuzz::check_message(e, path);
  }
  return 0;
}

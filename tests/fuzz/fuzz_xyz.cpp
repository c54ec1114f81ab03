// libFuzzer harness: XYZ/CSV text, through both text readers: the point-cloud reader (.xyz and
// .csv, whitespace or commas) and the CSV table reader (read_point_table).
#include <cstdlib>

#include "fuzz_support.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/io/point_table.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string& xyz = nurbsreg::fuzz::write_input(".xyz", data, size);
  try {
    const nurbsreg::io::PointCloud cloud = nurbsreg::io::read_point_cloud(xyz);
    if (cloud.points.size() + cloud.skipped_nonfinite != cloud.total) std::abort();
  } catch (const nurbsreg::io::InputError& e) {
    nurbsreg::fuzz::check_message(e, xyz);
  }
  const std::string& csv = nurbsreg::fuzz::write_input(".csv", data, size);
  try {
    (void)nurbsreg::io::read_point_table(csv);
  } catch (const nurbsreg::io::InputError& e) {
    nurbsreg::fuzz::check_message(e, csv);
  }
  return 0;
}

// libFuzzer harness: `modify --targets` CSV files (read_modify_targets).
#include <cmath>
#include <cstdlib>
#include <set>

#include "fuzz_support.hpp"
#include "nurbsreg/io/modify_io.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string& path = nurbsreg::fuzz::write_input(".csv", data, size);
  try {
    const auto targets = nurbsreg::io::read_modify_targets(path);
    std::set<int> segments;
    for (const auto& t : targets) {
      if (t.segment < 0 || !t.point.allFinite() || !segments.insert(t.segment).second) std::abort();
    }
  } catch (const nurbsreg::io::InputError& e) {
    nurbsreg::fuzz::check_message(e, path);
  }
  return 0;
}

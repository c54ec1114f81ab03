// libFuzzer harness: `nurbsreg serve`'s request parsing and body decoders (request_checks.hpp,
// which the normal suite also runs over corpus/fuzz_request: tests/service).
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "request_checks.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  nurbsreg::fuzz::request::check_request(
      std::string_view(reinterpret_cast<const char*>(data), size));
  return 0;
}

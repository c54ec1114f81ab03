#include "nurbsreg/io/resource_limits.hpp"

#include <charconv>
#include <cstdlib>
#include <string>
#include <string_view>

#include "nurbsreg/io/errors.hpp"

namespace nurbsreg::io {
namespace {

void override_from(const char* variable, std::uint64_t& limit) {
  const char* text = std::getenv(variable);
  if (text == nullptr) return;
  const std::string_view value(text);
  std::uint64_t parsed = 0;
  const auto [end, ec] = std::from_chars(value.data(), value.data() + value.size(), parsed);
  if (ec != std::errc() || end != value.data() + value.size() || parsed == 0) {
    throw InputError(std::string("environment variable ") + variable,
                     "expected a positive integer, got '" + std::string(value.substr(0, 40)) + "'");
  }
  limit = parsed;
}

}  // namespace

ResourceLimits resource_limits() {
  ResourceLimits limits;
  override_from("NURBSREG_MAX_FILE_BYTES", limits.max_file_bytes);
  override_from("NURBSREG_MAX_POINTS", limits.max_points);
  override_from("NURBSREG_MAX_BEZIER_POINTS", limits.max_bezier_points);
  override_from("NURBSREG_CAD_TIMEOUT", limits.cad_timeout_seconds);
  override_from("NURBSREG_CAD_MEMORY_MB", limits.cad_memory_mb);
  return limits;
}

}  // namespace nurbsreg::io

#pragma once
// Small helpers shared by the io readers and writers (private to the io library).

#include <charconv>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>

namespace nurbsreg::io::text_detail {

// The whole file as bytes. Throws InputError naming the file when it cannot be opened or read.
std::string read_text_file(const std::string& path);
// Throws the same InputError as read_text_file when the file cannot be opened, without reading.
void require_readable(const std::string& path);

// Appends x in its shortest form that reads back to exactly the same double (std::to_chars,
// C++17 [charconv]): writers stay exact without printing 17 digits for every value.
inline void append_number(std::string& out, double x) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), x);
  out.append(buffer, result.ptr);
}

inline void append_integer(std::string& out, std::int64_t x) {
  char buffer[24];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), x);
  out.append(buffer, result.ptr);
}

// Parses a whole token as a double (std::from_chars: locale-independent, exact, accepts "nan"
// and "inf", which callers reject or skip as they need). False if the token is not a number.
inline bool parse_number(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  const auto result = std::from_chars(token.data(), token.data() + token.size(), value);
  return result.ec == std::errc() && result.ptr == token.data() + token.size();
}

// Line number (1-based) and column (1-based, in bytes) of a byte offset in text.
struct TextPosition {
  std::size_t line = 1;
  std::size_t column = 1;
};
TextPosition position_of(std::string_view text, std::size_t offset);

}  // namespace nurbsreg::io::text_detail

#pragma once
// The one set of text helpers of the io readers and writers (private to the io library): the
// whole-file reader, the number parser, the CSV splitter and the quoting of file content in
// messages. Every reader uses these, so that the formats agree on what a number is (`1e999` is
// an error everywhere, not inf in one reader and an error in another) and on how big a file
// may be.

#include <charconv>
#include <cmath>
#include <cstdint>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "printable.hpp"

namespace nurbsreg::io::text_detail {

// The whole file as bytes. Throws InputError naming the file when it cannot be opened or read,
// or when it is larger than the byte limit (resource_limits.hpp, NURBSREG_MAX_FILE_BYTES):
// every reader holds its file in memory.
std::string read_text_file(const std::string& path);
// Throws the same InputError as read_text_file when the file cannot be opened, without reading.
void require_readable(const std::string& path);

// Lower-case extension including the dot (".pcd"), empty when there is none.
std::string lower_extension(const std::string& path);

// Byte-order mark that some editors and spreadsheets put at the start of text files.
inline constexpr std::string_view kUtf8Bom = "\xEF\xBB\xBF";

// Appends x in its shortest form that reads back to exactly the same value (std::to_chars,
// C++17 [charconv]): writers stay exact without printing 17 digits for every value; integers
// print exactly.
template <class T>
inline void append_number(std::string& out, T x) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), x);
  out.append(buffer, result.ptr);
}
inline std::string format_number(double x) {
  std::string out;
  append_number(out, x);
  return out;
}
inline void append_integer(std::string& out, std::int64_t x) {
  append_number(out, x);
}

// Parses a whole token as a double: std::from_chars (locale-independent, exact) plus a leading
// '+'. Accepts the literals `nan`, `inf` and `infinity` (any case), which callers skip or reject
// as they need. Strict: false when the token is not entirely a number, and also when its
// magnitude is out of the range of a double (`1e999`, `1e-400`): such a literal is a corrupt
// or foreign value, not a measurement, and rounding it to inf or 0 would hide that.
inline bool parse_number(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return false;
  const auto result = std::from_chars(token.data(), token.data() + token.size(), value);
  return result.ec == std::errc() && result.ptr == token.data() + token.size();
}

// A token from a file for an error message: quoted, at most 40 characters, control and
// non-ASCII bytes shown as \xHH so that the message stays one printable line (a scan or pose
// file may hold any bytes, and echoing ESC sequences would drive the user's terminal).
inline std::string quote(std::string_view token) {
  constexpr std::size_t kMax = 40;
  return "'" + printable(token.substr(0, kMax)) + (token.size() > kMax ? "...'" : "'");
}

// An entity name from a file for a message: in double quotes, `"` and `\` escaped, bytes
// outside printable ASCII as \xHH, at most 80 characters.
inline std::string quote_name(std::string_view name) {
  constexpr char kHex[] = "0123456789abcdef";
  std::string out = "\"";
  for (const char c : name.substr(0, 80)) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte == '"' || byte == '\\') {
      out.push_back('\\');
      out.push_back(c);
    } else if (byte >= 0x20 && byte < 0x7f) {
      out.push_back(c);
    } else {
      out += "\\x";
      out.push_back(kHex[byte >> 4]);
      out.push_back(kHex[byte & 15]);
    }
  }
  if (name.size() > 80) out += "...";
  return out + "\"";
}

// True when the token is a number whose magnitude no double holds (`1e999`), which
// parse_number refuses.
inline bool out_of_range(std::string_view token) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  double ignored = 0;
  const auto result = std::from_chars(token.data(), token.data() + token.size(), ignored);
  return result.ec == std::errc::result_out_of_range && result.ptr == token.data() + token.size();
}

// Why parse_number refused a token, for messages: "not a number: 'abc'" or "out of the range of
// a double: '1e999'".
inline std::string bad_number(std::string_view token) {
  return (out_of_range(token) ? "out of the range of a double: " : "not a number: ") + quote(token);
}

// Splits one CSV line on commas into `fields` (cleared first), trimming blanks and a trailing
// '\r' from each field. "a, b,,c" gives four fields, the third empty. The views point into
// `line`.
inline void split_csv(std::string_view line, std::vector<std::string_view>& fields) {
  fields.clear();
  std::size_t start = 0;
  while (true) {
    const std::size_t end = line.find(',', start);
    std::string_view field = line.substr(start, end == std::string_view::npos ? end : end - start);
    while (!field.empty() && (field.front() == ' ' || field.front() == '\t'))
      field.remove_prefix(1);
    while (!field.empty() &&
           (field.back() == ' ' || field.back() == '\t' || field.back() == '\r')) {
      field.remove_suffix(1);
    }
    fields.push_back(field);
    if (end == std::string_view::npos) break;
    start = end + 1;
  }
}

// Line number (1-based) and column (1-based, in bytes) of a byte offset in text.
struct TextPosition {
  std::size_t line = 1;
  std::size_t column = 1;
};
TextPosition position_of(std::string_view text, std::size_t offset);

}  // namespace nurbsreg::io::text_detail

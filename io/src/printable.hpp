#pragma once
// Text that may echo a file's bytes (a parser library's message quoting the input: nlohmann's
// "last read: '...'") for an error message: bytes outside printable ASCII as \xHH, the rest as
// is, so that the message stays one printable line (CONTRACT §1; the fuzz harnesses check it).
// text_io.hpp's quote() does the same for tokens and names, quoted and shortened.

#include <string>
#include <string_view>

namespace nurbsreg::io::text_detail {

inline std::string printable(std::string_view text) {
  constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte >= 0x20 && byte < 0x7f) {
      out.push_back(c);
    } else {
      out += "\\x";
      out.push_back(kHex[byte >> 4]);
      out.push_back(kHex[byte & 15]);
    }
  }
  return out;
}

}  // namespace nurbsreg::io::text_detail

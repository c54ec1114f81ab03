#include "text_io.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/resource_limits.hpp"

namespace nurbsreg::io::text_detail {

void require_readable(const std::string& path) {
  // A directory opens as an ifstream on Linux and then reads as empty: name it instead.
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) throw InputError(path, "is a directory, not a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
}

std::string read_text_file(const std::string& path) {
  require_readable(path);
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  // One read into a buffer of the file's size: a stringstream would copy the bytes twice and
  // grow geometrically, which dominated reading large CSV tables.
  const std::streamoff size = in.tellg();
  if (size < 0) throw InputError(path, "cannot read the file (not a regular file?)");
  const std::uint64_t limit = resource_limits().max_file_bytes;
  if (static_cast<std::uint64_t>(size) > limit) {
    throw InputError(path, "the file has " + std::to_string(size) +
                               " bytes, more than the limit of " + std::to_string(limit) +
                               " (raise it with NURBSREG_MAX_FILE_BYTES=<bytes>)");
  }
  std::string text(static_cast<std::size_t>(size), '\0');
  in.seekg(0);
  in.read(text.data(), size);
  if (in.gcount() != size) throw InputError(path, "cannot read the file (read stopped early)");
  return text;
}

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

TextPosition position_of(std::string_view text, std::size_t offset) {
  TextPosition position;
  offset = std::min(offset, text.size());
  for (std::size_t i = 0; i < offset; ++i) {
    if (text[i] == '\n') {
      ++position.line;
      position.column = 1;
    } else {
      ++position.column;
    }
  }
  return position;
}

}  // namespace nurbsreg::io::text_detail

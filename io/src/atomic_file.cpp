#include "nurbsreg/io/atomic_file.hpp"

#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "nurbsreg/io/errors.hpp"

namespace nurbsreg::io {

void write_atomically(const std::string& path, const std::function<void(std::ostream&)>& write) {
  namespace fs = std::filesystem;
  static std::atomic<unsigned> counter{0};
  const fs::path target(path);
  const fs::path temporary =
      target.parent_path() / ("." + target.filename().string() + ".tmp-" +
                              std::to_string(::getpid()) + "-" + std::to_string(counter++));
  try {
    {
      std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
      if (!out)
        throw OutputError(path, "cannot create the file (directory missing or not writable)");
      write(out);
      out.flush();
      if (!out) throw OutputError(path, "write failed (disk full?)");
    }
    std::error_code ec;
    fs::rename(temporary, target, ec);
    if (ec) throw OutputError(path, "cannot rename the finished file into place: " + ec.message());
  } catch (...) {
    std::error_code ignored;
    fs::remove(temporary, ignored);
    throw;
  }
}

}  // namespace nurbsreg::io

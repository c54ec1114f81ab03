#include "nurbsreg/inspect/output_folder.hpp"

#include <unistd.h>

#include <stdexcept>
#include <system_error>

namespace nurbsreg::inspect {
namespace fs = std::filesystem;

OutputFolder::OutputFolder(const fs::path& out_dir) : out_dir_(out_dir) {
  std::error_code ec;
  if (fs::exists(out_dir_, ec) && !fs::is_directory(out_dir_, ec)) {
    throw std::runtime_error(out_dir_.string() + ": exists and is not a folder");
  }
  fs::path absolute = fs::absolute(out_dir_, ec);
  if (ec) throw std::runtime_error(out_dir_.string() + ": " + ec.message());
  absolute = absolute.lexically_normal();
  if (!absolute.has_filename()) absolute = absolute.parent_path();
  const fs::path parent = absolute.parent_path();
  if (!fs::is_directory(parent, ec)) {
    throw std::runtime_error(out_dir_.string() + ": its parent folder " + parent.string() +
                             " does not exist");
  }
  staging_ = parent / ("." + absolute.filename().string() + ".inspect-" + std::to_string(getpid()));
  fs::remove_all(staging_, ec);
  if (!fs::create_directory(staging_, ec) || ec) {
    throw std::runtime_error(
        out_dir_.string() + ": cannot write beside it (" +
        (ec ? ec.message() : std::string("cannot create ") + staging_.string()) + ")");
  }
  // A read-only existing output folder would fail only at commit(), after all the work.
  if (fs::is_directory(out_dir_, ec) && access(out_dir_.c_str(), W_OK) != 0) {
    fs::remove_all(staging_, ec);
    throw std::runtime_error(out_dir_.string() + ": not writable");
  }
}

OutputFolder::~OutputFolder() {
  std::error_code ec;
  fs::remove_all(staging_, ec);  // after commit: the empty staging folder or nothing
}

void OutputFolder::commit() {
  std::error_code ec;
  if (!fs::exists(out_dir_, ec)) {
    fs::rename(staging_, out_dir_, ec);
    if (ec) throw std::runtime_error(out_dir_.string() + ": " + ec.message());
    committed_ = true;
    return;
  }
  for (const fs::directory_entry& entry : fs::directory_iterator(staging_)) {
    fs::rename(entry.path(), out_dir_ / entry.path().filename(), ec);
    if (ec)
      throw std::runtime_error((out_dir_ / entry.path().filename()).string() + ": " + ec.message());
  }
  committed_ = true;
}

}  // namespace nurbsreg::inspect

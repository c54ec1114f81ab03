#pragma once
// The inspection's output folder, all or nothing: files are written into a staging folder
// beside it (`.<name>.inspect-<pid>`), and commit() moves them in only when every one is done.
// A run that fails (or throws) before commit() leaves the output folder as it was: the
// destructor removes the staging folder. An existing output folder is kept; files of the same
// names in it are replaced, each by one rename.

#include <filesystem>
#include <string>

namespace nurbsreg::inspect {

class OutputFolder {
 public:
  // Creates the staging folder (and the output folder's missing parents are not created: the
  // parent must exist). Throws std::runtime_error naming the folder when it cannot be used: the
  // path is a file, the parent is missing or not writable.
  explicit OutputFolder(const std::filesystem::path& out_dir);
  ~OutputFolder();
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;

  // Where to write file `name` now (inside the staging folder).
  std::string path(const std::string& name) const { return (staging_ / name).string(); }
  // Moves every staged file into the output folder; throws std::runtime_error.
  void commit();
  const std::filesystem::path& out_dir() const { return out_dir_; }

 private:
  std::filesystem::path out_dir_;
  std::filesystem::path staging_;
  bool committed_ = false;
};

}  // namespace nurbsreg::inspect

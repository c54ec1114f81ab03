#pragma once
// Errors at the I/O boundary. The CLI turns them into the contract's exit codes and a
// one-line message: `error: <file>: <what>`.

#include <stdexcept>
#include <string>

namespace nurbsreg::io {

// Bad input: unreadable, malformed or invalid file, invalid model (exit status 3).
class InputError : public std::runtime_error {
 public:
  InputError(std::string file, const std::string& what)
      : std::runtime_error(file + ": " + what), file_(std::move(file)) {}
  const std::string& file() const { return file_; }

 private:
  std::string file_;
};

// Anything else that failed while writing or processing (exit status 1).
class OutputError : public std::runtime_error {
 public:
  OutputError(const std::string& file, const std::string& what)
      : std::runtime_error(file + ": " + what) {}
};

}  // namespace nurbsreg::io

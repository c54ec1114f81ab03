#pragma once
// Shared by the libFuzzer harnesses (tests/fuzz/README.md): the readers take file names, so
// each input is written to a scratch file first (in $TMPDIR, /dev/shm when it exists: memory),
// and every error a reader throws must be one printable line naming that file (CONTRACT §1).

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "nurbsreg/io/errors.hpp"

namespace nurbsreg::fuzz {

// A scratch file of this process with the given extension (".pcd"), rewritten per input (one
// per extension: a harness may write the same bytes as .pcd and as .ply).
inline std::string scratch_file(const char* extension) {
  static const std::string stem = [] {
    std::string dir = std::filesystem::exists("/dev/shm") ? "/dev/shm" : "/tmp";
    if (const char* tmp = std::getenv("NURBSREG_FUZZ_TMPDIR")) dir = tmp;
    return dir + "/nurbsreg_fuzz_" + std::to_string(::getpid());
  }();
  return stem + extension;
}

inline std::string write_input(const char* extension, const std::uint8_t* data, std::size_t size) {
  std::string path = scratch_file(extension);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  return path;
}

// A reader's message must be one line of printable ASCII that names the file: anything else is
// a finding (abort, so libFuzzer saves the input).
inline void check_message(const nurbsreg::io::InputError& e, const std::string& file) {
  const std::string_view what = e.what();
  for (const char c : what) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte >= 0x7f) {
      std::fprintf(stderr, "unprintable byte 0x%02x in the message: %s\n", byte, e.what());
      std::abort();
    }
  }
  if (!what.starts_with(file + ": ")) {
    std::fprintf(stderr, "the message does not name the file %s: %s\n", file.c_str(), e.what());
    std::abort();
  }
}

}  // namespace nurbsreg::fuzz

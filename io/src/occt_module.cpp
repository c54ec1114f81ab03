#include "occt_module.hpp"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace nurbsreg::io::cad_detail {
namespace {

// The directory of the executable or shared object this function's code is in: where the
// build puts the module beside `nurbsreg`.
std::filesystem::path own_directory() {
  Dl_info info{};
  if (::dladdr(reinterpret_cast<void*>(&own_directory), &info) == 0 || info.dli_fname == nullptr) {
    return {};
  }
  std::error_code ec;
  const std::filesystem::path file = std::filesystem::canonical(info.dli_fname, ec);
  return ec ? std::filesystem::path() : file.parent_path();
}

std::vector<std::string> candidates() {
  std::vector<std::string> paths;
  if (const char* forced = std::getenv("NURBSREG_OCCT_MODULE"); forced != nullptr && *forced) {
    paths.emplace_back(forced);
    return paths;  // asked for this one: no other
  }
  if (const std::filesystem::path dir = own_directory(); !dir.empty()) {
    paths.push_back((dir / kOcctModuleFile).string());
  }
#ifdef NURBSREG_OCCT_MODULE_PATH
  paths.emplace_back(NURBSREG_OCCT_MODULE_PATH);
#endif
  return paths;
}

struct Loaded {
  OcctImportFunction import = nullptr;
  std::string error;  // why it could not be loaded
};

Loaded load() {
  Loaded loaded;
  std::string tried;
  for (const std::string& path : candidates()) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) {
      tried += "\n  " + path + ": no such file";
      continue;
    }
    // RTLD_LOCAL: the module's copies of the engine's code stay its own.
    void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (handle == nullptr) {
      const char* why = ::dlerror();
      tried += "\n  " + path + ": " + (why != nullptr ? why : "cannot be loaded");
      continue;
    }
    using AbiFunction = int (*)();
    using VersionFunction = const char* (*)();
    const auto abi = reinterpret_cast<AbiFunction>(::dlsym(handle, kOcctAbiSymbol));
    const auto version = reinterpret_cast<VersionFunction>(::dlsym(handle, kOcctVersionSymbol));
    const auto import = reinterpret_cast<OcctImportFunction>(::dlsym(handle, kOcctImportSymbol));
    if (abi == nullptr || version == nullptr || import == nullptr || abi() != kOcctModuleAbi ||
        std::string(version()) != NURBSREG_VERSION) {
      tried += "\n  " + path + ": not this build's OpenCASCADE module (stale or foreign)";
      ::dlclose(handle);
      continue;
    }
    loaded.import = import;  // never unloaded: OCCT's global state lives as long as the process
    return loaded;
  }
  loaded.error = std::string("STEP/IGES import needs nurbsreg's OpenCASCADE module ") +
                 kOcctModuleFile +
                 ", which could not be loaded (set NURBSREG_OCCT_MODULE to "
                 "its path):" +
                 tried;
  return loaded;
}

}  // namespace

OcctImportFunction occt_import_function() {
  static std::once_flag once;
  static Loaded loaded;
  std::call_once(once, [] { loaded = load(); });
  if (loaded.import == nullptr) throw std::runtime_error(loaded.error);
  return loaded.import;
}

}  // namespace nurbsreg::io::cad_detail

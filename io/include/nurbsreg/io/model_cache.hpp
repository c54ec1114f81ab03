#pragma once
// The converted-model cache (issue 26, item 3): a STEP/IGES file is converted by OpenCASCADE
// once; later loads of the same file content read the converted engine::Model from a compact
// binary file instead (milliseconds instead of seconds).
//
// Key: a 128-bit hash of the source file's bytes and its size, and the program's cache version
// (kModelCacheVersion: the nurbsreg version and a revision of the importer and the format). The
// entry's name is derived from both, and its header repeats them, so a file that changed, or an
// entry written by another version, is never taken for the right one.
//
// Entry: a header (magic, format, byte order, version, source size and hash, payload size and a
// 64-bit checksum of the payload), then the model (every number as its IEEE-754 bits, so a hit
// gives the model bit for bit). Binary and not JSON because parsing the text of a 1272-patch
// part is slower than the budget of a cached load (0.5 s with preparation).
//
// Never used silently when wrong: an entry that is truncated, fails its checksum, does not decode
// to a valid model, or whose header names another source or version is replaced by a fresh
// conversion, with a warning naming the entry and what is wrong. Writes are atomic
// (atomic_file.hpp): concurrent processes may race, each renames a complete entry into place.
// A cache directory that cannot be created or written costs a warning, never the load.
//
// Where: $NURBSREG_CACHE_DIR, else $XDG_CACHE_HOME/nurbsreg, else $HOME/.cache/nurbsreg. Off
// when NURBSREG_NO_CACHE is set to anything but "" or "0" (or by the CLI's --no-cache). Entries
// are never evicted: delete the directory to reclaim the space. Thread-safe (no shared state).

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "nurbsreg/engine/model.hpp"

namespace nurbsreg::io {

// The version an entry must have been written by (program version + cache revision). Bump the
// revision (model_cache.cpp) whenever the STEP/IGES conversion or the entry format changes.
std::string model_cache_version();

struct ModelCacheSettings {
  bool enabled = false;
  std::string directory;
  std::string version = model_cache_version();

  // The settings the environment asks for (see the header comment); enabled when a directory is
  // known and NURBSREG_NO_CACHE does not turn it off.
  static ModelCacheSettings from_environment();
};

// What a cached load did (logs, tests).
enum class CacheOutcome {
  disabled,  // no cache: converted
  hit,       // read from the cache
  miss,      // no entry: converted and stored
  rebuilt,   // an entry was there but wrong (corrupt, truncated, stale): converted and replaced
};

struct ContentHash {
  std::uint64_t lo = 0, hi = 0;
  bool operator==(const ContentHash&) const = default;
};
// 128-bit hash of the bytes (two independent 64-bit multiply-rotate lanes, finalised by
// splitmix64): a cache key, not a cryptographic digest.
ContentHash hash_bytes(std::string_view bytes);
// hash_bytes of the model as an entry's payload stores it: every number's bits, the names, trims
// and skipped faces. Two models with the same hash are the same model (up to the hash's
// collisions), whatever file they came from (the features cache's key, features_cache.hpp).
ContentHash hash_model(const engine::Model& model);

// The model as an entry's bytes, and back. decode_model_entry checks everything the header says
// (magic, format, byte order, version, source hash and size, payload size and checksum), decodes
// and validates the model, and throws CacheEntryError naming what is wrong.
std::string encode_model_entry(const engine::Model& model, const ContentHash& source,
                               std::uint64_t source_size, const std::string& version);
class CacheEntryError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
engine::Model decode_model_entry(std::string_view bytes, const ContentHash& source,
                                 std::uint64_t source_size, const std::string& version);

// The entry file a source with this content would use.
std::string model_cache_entry_path(const ModelCacheSettings& settings, const ContentHash& source,
                                   std::uint64_t source_size);

// Loads `path` through the cache: on a hit the cached model, otherwise convert(path), stored for
// next time. Errors of convert (InputError, ...) pass through unchanged, and nothing is stored.
engine::Model read_model_through_cache(
    const std::string& path, const ModelCacheSettings& settings,
    const std::function<engine::Model(const std::string&)>& convert,
    CacheOutcome* outcome = nullptr);

}  // namespace nurbsreg::io

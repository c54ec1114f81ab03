// The model-features cache: entry encoding, checks and the read-through load
// (features_cache.hpp).

#include "nurbsreg/io/features_cache.hpp"

#include <spdlog/spdlog.h>

#include <bit>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <optional>
#include <stdexcept>

#include "cache_codec.hpp"
#include "nurbsreg/io/atomic_file.hpp"

#ifndef NURBSREG_VERSION
#define NURBSREG_VERSION "unknown"
#endif
#ifndef NURBSREG_FEATURE_SOURCES_DIGEST
#define NURBSREG_FEATURE_SOURCES_DIGEST "unknown"
#endif

namespace nurbsreg::io {
namespace {

using detail::hex;
using detail::read_whole_file;
using detail::Reader;
using detail::Writer;
using registration::FeatureOptions;
using registration::kFeatureDescriptorSize;
using registration::ModelFeatureParts;
using registration::ModelFeatures;

constexpr char kMagic[8] = {'N', 'R', 'B', 'F', 'E', 'A', 'T', 'S'};
// An entry of the area and keypoints alone (what an alignment from a given pose needs).
constexpr char kSamplesMagic[8] = {'N', 'R', 'B', 'F', 'S', 'A', 'M', 'P'};
// Bump when the entry's layout below changes (what the features are is
// registration::kModelFeaturesRevision's, in the version).
constexpr std::uint32_t kFormat = 1;
// A symmetry is stored as the top three rows of its 4 x 4 matrix (an isometry's last row is
// 0 0 0 1, and Eigen's isometry products never read it).
constexpr std::size_t kSymmetryDoubles = 12;

// The options as the header stores them: every field's bits.
struct OptionBits {
  std::uint64_t keypoints, normal_radius, feature_radius, seed;
  bool operator==(const OptionBits&) const = default;
};
OptionBits bits_of(const FeatureOptions& o) {
  return {o.keypoints, std::bit_cast<std::uint64_t>(o.normal_radius),
          std::bit_cast<std::uint64_t>(o.feature_radius), o.seed};
}

// The area, the voxel and the keypoints (points, then normals): the start of both payloads.
void write_samples(Writer& w, const ModelFeatures& f) {
  const registration::ModelKeypoints& k = f.keypoints();
  w.raw(f.surface_area());
  w.raw(f.voxel());
  w.u64(k.points.size());
  for (const std::vector<engine::Vec3>* v : {&k.points, &k.normals}) {
    for (const engine::Vec3& p : *v)
      w.array(p.data(), 3);
  }
}

void read_samples(Reader& r, ModelFeatureParts& p) {
  p.surface_area = r.raw<double>();
  p.voxel = r.raw<double>();
  const std::size_t n = r.count(6 * sizeof(double));  // a point and a normal each
  p.keypoints.points.resize(n);
  p.keypoints.normals.resize(n);
  for (std::vector<engine::Vec3>* v : {&p.keypoints.points, &p.keypoints.normals}) {
    for (engine::Vec3& x : *v)
      r.array(x.data(), 3);
  }
}

std::string encode_payload(const ModelFeatures& f) {
  f.build_all();
  const registration::FeatureDescriptors& d = f.descriptors();
  Writer w;
  write_samples(w, f);
  w.u64(static_cast<std::uint64_t>(d.cols()));
  w.u64(static_cast<std::uint64_t>(d.rows()));
  w.array(d.data(), static_cast<std::size_t>(d.size()));
  w.u64(f.symmetries().size());
  for (const Eigen::Isometry3d& S : f.symmetries()) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c)
        w.raw(S.matrix()(r, c));
  }
  return std::move(w.bytes());
}

ModelFeatureParts decode_payload(std::string_view bytes) {
  Reader r(bytes);
  ModelFeatureParts p;
  read_samples(r, p);
  const std::size_t n = p.keypoints.points.size();
  const std::uint64_t cols = r.u64();
  if (cols != kFeatureDescriptorSize) {
    throw CacheEntryError("descriptors of " + std::to_string(cols) + " numbers, expected " +
                          std::to_string(kFeatureDescriptorSize) + " (corrupt)");
  }
  const std::size_t rows = r.count(kFeatureDescriptorSize * sizeof(float));
  // One row per described keypoint, a subset of them (ModelFeatures::from_parts counts it).
  if (rows > n) {
    throw CacheEntryError(std::to_string(rows) + " descriptors for " + std::to_string(n) +
                          " keypoints (corrupt)");
  }
  p.descriptors.resize(static_cast<Eigen::Index>(rows), kFeatureDescriptorSize);
  r.array(p.descriptors.data(), static_cast<std::size_t>(p.descriptors.size()));
  p.symmetries.resize(r.count(kSymmetryDoubles * sizeof(double)));
  for (Eigen::Isometry3d& S : p.symmetries) {
    S = Eigen::Isometry3d::Identity();
    for (int row = 0; row < 3; ++row)
      for (int c = 0; c < 4; ++c)
        S.matrix()(row, c) = r.raw<double>();
  }
  if (!r.done()) throw CacheEntryError("bytes after the features (corrupt)");
  return p;
}

ModelFeatureParts decode_samples_payload(std::string_view bytes) {
  Reader r(bytes);
  ModelFeatureParts p;
  read_samples(r, p);
  if (!r.done()) throw CacheEntryError("bytes after the keypoints (corrupt)");
  return p;
}

// An entry: the header (magic, format, byte order, version, model hash, options, payload size
// and checksum), then the payload.
std::string wrap_entry(const char (&magic)[8], const std::string& payload,
                       const FeatureOptions& options, const ContentHash& model,
                       const std::string& version) {
  const OptionBits o = bits_of(options);
  Writer w;
  detail::write_entry_start(w, magic, kFormat, version);
  w.u64(model.lo);
  w.u64(model.hi);
  w.raw(o);
  w.u64(payload.size());
  w.u64(hash_bytes(payload).lo);
  w.bytes().append(payload);
  return std::move(w.bytes());
}

// The payload of an entry whose header names this magic, version, model and options, with the
// size and checksum it states; CacheEntryError naming what is wrong otherwise.
std::string_view unwrap_entry(std::string_view bytes, const char (&magic)[8],
                              const ContentHash& model_hash, const FeatureOptions& options,
                              const std::string& version) {
  Reader r = detail::read_entry_start(bytes, magic, kFormat, "features cache", version);
  if (r.u64() != model_hash.lo || r.u64() != model_hash.hi)
    throw CacheEntryError("made from another model (stale)");
  if (r.raw<OptionBits>() != bits_of(options))
    throw CacheEntryError("made with other feature options");
  const std::uint64_t size = r.u64();
  const std::uint64_t check = r.u64();
  // Only a compare: the payload size never sizes anything.
  if (r.left() != size)
    throw CacheEntryError("its size does not match its header (truncated or corrupt)");
  const std::string_view payload = bytes.substr(sizeof magic + r.offset());
  if (hash_bytes(payload).lo != check) throw CacheEntryError("checksum mismatch (corrupt)");
  return payload;
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Writes an entry atomically; a directory that cannot be made or written costs a warning, never
// the alignment.
template <class Encode>
bool store_entry(const std::string& entry, const FeaturesCacheSettings& settings, Encode encode) {
  try {
    std::error_code ec;
    std::filesystem::create_directories(settings.directory, ec);
    const std::string bytes = encode();
    write_atomically(entry, [&](std::ostream& out) {
      out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    });
    return true;
  } catch (const std::exception& e) {
    spdlog::warn("could not store the model features in the cache ({}): {}", entry, e.what());
    return false;
  }
}

}  // namespace

std::string features_cache_version() {
  return std::string("nurbsreg ") + NURBSREG_VERSION + " features " +
         std::to_string(registration::kModelFeaturesRevision) + " sources " +
         NURBSREG_FEATURE_SOURCES_DIGEST;
}

FeaturesCacheSettings FeaturesCacheSettings::from_environment() {
  const ModelCacheSettings m = ModelCacheSettings::from_environment();
  FeaturesCacheSettings s;
  s.enabled = m.enabled;
  s.directory = m.directory;
  return s;
}

std::string encode_features_entry(const ModelFeatures& features, const ContentHash& model,
                                  const std::string& version) {
  return wrap_entry(kMagic, encode_payload(features), features.options(), model, version);
}

std::shared_ptr<const ModelFeatures> decode_features_entry(std::string_view bytes,
                                                           const engine::PreparedModel& model,
                                                           const ContentHash& model_hash,
                                                           const FeatureOptions& options,
                                                           const std::string& version) {
  const std::string_view payload = unwrap_entry(bytes, kMagic, model_hash, options, version);
  try {
    return ModelFeatures::from_parts(model, options, decode_payload(payload));
  } catch (const std::invalid_argument& e) {
    throw CacheEntryError(e.what());
  }
}

std::string encode_samples_entry(const ModelFeatures& features, const ContentHash& model,
                                 const std::string& version) {
  Writer w;
  write_samples(w, features);
  return wrap_entry(kSamplesMagic, w.bytes(), features.options(), model, version);
}

std::shared_ptr<const ModelFeatures> decode_samples_entry(std::string_view bytes,
                                                          const engine::PreparedModel& model,
                                                          const ContentHash& model_hash,
                                                          const FeatureOptions& options,
                                                          const std::string& version) {
  const std::string_view payload = unwrap_entry(bytes, kSamplesMagic, model_hash, options, version);
  try {
    return ModelFeatures::from_samples(model, options, decode_samples_payload(payload));
  } catch (const std::invalid_argument& e) {
    throw CacheEntryError(e.what());
  }
}

std::string features_cache_entry_path(const FeaturesCacheSettings& settings,
                                      const ContentHash& model, const FeatureOptions& options) {
  const OptionBits o = bits_of(options);
  const std::string key(reinterpret_cast<const char*>(&o), sizeof o);
  const std::uint64_t rest = hash_bytes(settings.version + '\0' + key).lo;
  return (std::filesystem::path(settings.directory) /
          (hex(model.lo) + hex(model.hi) + "-" + hex(rest) + ".nrbfeat"))
      .string();
}

std::string features_cache_samples_path(const FeaturesCacheSettings& settings,
                                        const ContentHash& model, const FeatureOptions& options) {
  return std::filesystem::path(features_cache_entry_path(settings, model, options))
      .replace_extension(".nrbsamp")
      .string();
}

std::shared_ptr<const ModelFeatures> load_model_features(const engine::PreparedModel& model,
                                                         const FeatureOptions& options,
                                                         const FeaturesCacheSettings& settings,
                                                         CacheOutcome* outcome) {
  const auto start = std::chrono::steady_clock::now();
  const auto finish = [&](std::shared_ptr<const ModelFeatures> f, CacheOutcome done,
                          const std::string& what) {
    if (outcome != nullptr) *outcome = done;
    // A build takes seconds on a large part: said at the default level, its time in `what` (a
    // read, at debug, with its own time).
    if (done == CacheOutcome::miss || done == CacheOutcome::rebuilt) {
      spdlog::info("model features: {}", what);
    } else {
      spdlog::debug("model features: {} in {:.3f} s", what, seconds_since(start));
    }
    return f;
  };
  if (!settings.enabled) {
    // As without a cache: the parts are built when the alignment first needs them.
    return finish(std::make_shared<const ModelFeatures>(model, options), CacheOutcome::disabled,
                  "no cache (the area measured; the rest is built on first use)");
  }
  const ContentHash key = hash_model(model.model());
  const std::string entry = features_cache_entry_path(settings, key, options);
  CacheOutcome done = CacheOutcome::miss;
  if (const std::optional<std::string> bytes = read_whole_file(entry)) {
    try {
      return finish(decode_features_entry(*bytes, model, key, options, settings.version),
                    CacheOutcome::hit, "read from the cache (hit, " + entry + ")");
    } catch (const CacheEntryError& e) {
      spdlog::warn(
          "the model features cache entry {} is not usable: {}; building the features "
          "again",
          entry, e.what());
      done = CacheOutcome::rebuilt;
    }
  }
  auto features = std::make_shared<const ModelFeatures>(model, options);
  features->build_all();
  const double build_seconds = seconds_since(start);
  const char* word = done == CacheOutcome::miss ? "miss" : "rebuilt";
  std::string what = fmt::format("built in {:.3f} s ({})", build_seconds, word);
  if (store_entry(entry, settings,
                  [&] { return encode_features_entry(*features, key, settings.version); })) {
    what += ", stored in the cache (" + entry + ")";
  }
  return finish(std::move(features), done, what);
}

std::shared_ptr<const ModelFeatures> cached_model_features(const engine::PreparedModel& model,
                                                           const FeatureOptions& options,
                                                           const FeaturesCacheSettings& settings,
                                                           CacheOutcome* outcome) {
  const auto start = std::chrono::steady_clock::now();
  if (!settings.enabled) {
    if (outcome != nullptr) *outcome = CacheOutcome::disabled;
    auto f = std::make_shared<const ModelFeatures>(model, options);
    spdlog::debug("model features: no cache; the area measured in {:.3f} s (the rest on first use)",
                  seconds_since(start));
    return f;
  }
  const ContentHash key = hash_model(model.model());
  const auto hit = [&](std::shared_ptr<const ModelFeatures> f, const std::string& entry,
                       const char* what) {
    if (outcome != nullptr) *outcome = CacheOutcome::hit;
    spdlog::debug("model features: {}read from the cache (hit, {}) in {:.3f} s", what, entry,
                  seconds_since(start));
    return f;
  };
  // A full entry (an alignment from any pose stored it) first, then one of the area and
  // keypoints alone (an earlier run like this one stored it).
  const std::string full = features_cache_entry_path(settings, key, options);
  if (const std::optional<std::string> bytes = read_whole_file(full)) {
    try {
      return hit(decode_features_entry(*bytes, model, key, options, settings.version), full, "");
    } catch (const CacheEntryError& e) {
      spdlog::warn(
          "the model features cache entry {} is not usable: {}; the next alignment from any pose "
          "replaces it",
          full, e.what());
    }
  }
  const std::string samples = features_cache_samples_path(settings, key, options);
  CacheOutcome done = CacheOutcome::miss;
  if (const std::optional<std::string> bytes = read_whole_file(samples)) {
    try {
      return hit(decode_samples_entry(*bytes, model, key, options, settings.version), samples,
                 "the area and keypoints ");
    } catch (const CacheEntryError& e) {
      spdlog::warn(
          "the model features cache entry {} is not usable: {}; measuring the area and keypoints "
          "again",
          samples, e.what());
      done = CacheOutcome::rebuilt;
    }
  }
  // Measured now (the alignment needs both: the area for the noise, the keypoints for the
  // verdict's coverage) and stored alone: the descriptors would cost seconds, more than these
  // runs take.
  auto features = std::make_shared<const ModelFeatures>(model, options);
  features->keypoints();
  std::string what =
      fmt::format("the area and keypoints measured in {:.3f} s ({})", seconds_since(start),
                  done == CacheOutcome::miss ? "miss" : "rebuilt");
  if (store_entry(samples, settings,
                  [&] { return encode_samples_entry(*features, key, settings.version); })) {
    what += ", stored in the cache (" + samples + ")";
  }
  if (outcome != nullptr) *outcome = done;
  spdlog::debug("model features: {}", what);
  return features;
}

}  // namespace nurbsreg::io

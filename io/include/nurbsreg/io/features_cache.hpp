#pragma once
// The model-features cache: the global alignment's model features (registration::ModelFeatures:
// surface area, keypoints with exact normals, descriptors, discrete symmetries) are built once
// per model and options; later runs on the same model read them from a compact binary file
// instead of building them again (on a real part the build can cost more than the alignment).
//
// Key: the model's exact content (hash_model: every number's bits, so a .json model is keyed as
// well as a converted STEP/IGES file), every registration::FeatureOptions field (bit for bit),
// and the version (features_cache_version: the nurbsreg version,
// registration::kModelFeaturesRevision and a digest of the sources that compute the features,
// taken when the build is configured: an edit to them makes old entries stale by itself). The
// entry's name is derived from all three, and its header repeats them, so features of another
// model, other options or another version are never taken for the right ones.
//
// Entry: a header (magic, format, byte order, version, model hash, options, payload size and a
// 64-bit checksum of the payload), then the parts: area, voxel, keypoints (points, normals),
// descriptors (rows x kFeatureDescriptorSize floats, one row per described keypoint: the
// keypoints ModelFeatures::from_parts finds again on a surface), symmetries (the 3 x 4 affine part
// of each turn). An entry of the samples alone (.nrbsamp, its own magic, the same header) holds
// the area, voxel and keypoints: what an alignment from a given pose needs. Every number is stored
// as its IEEE-754 bits: a hit gives the features a fresh build gives, so the same alignments to the
// bit.
//
// Never used silently when wrong: an entry that is truncated, fails its checksum, whose counts
// run past its end, whose numbers are not finite or whose parts do not fit together
// (ModelFeatures::from_parts), or whose header names another model, options or version is
// replaced by a fresh build, with a warning naming the entry and what is wrong. A count in an
// entry is checked against the bytes that are really there before anything is allocated for
// it. Writes are atomic (atomic_file.hpp). A directory that cannot be created or written costs
// a warning, never the alignment.
//
// Where, and off: the model cache's settings (model_cache.hpp: $NURBSREG_CACHE_DIR, else
// $XDG_CACHE_HOME/nurbsreg, else $HOME/.cache/nurbsreg; NURBSREG_NO_CACHE or the CLI's
// --no-cache turn both off). Thread-safe (no shared state).

#include <memory>
#include <string>
#include <string_view>

#include "nurbsreg/engine/prepared_model.hpp"
#include "nurbsreg/io/model_cache.hpp"
#include "nurbsreg/registration/model_features.hpp"

namespace nurbsreg::io {

// The version an entry must have been written by: the nurbsreg version and
// registration::kModelFeaturesRevision.
std::string features_cache_version();

struct FeaturesCacheSettings {
  bool enabled = false;
  std::string directory;
  std::string version = features_cache_version();

  // The model cache's directory and switch (ModelCacheSettings::from_environment).
  static FeaturesCacheSettings from_environment();
};

// The features as an entry's bytes (builds the parts not yet built: ModelFeatures::build_all),
// and back. decode_features_entry checks everything the header says (magic, format, byte order,
// version, model hash, options, payload size and checksum), decodes the parts with every count
// checked against the bytes left, and makes them into features of `model`
// (ModelFeatures::from_parts's checks); it throws CacheEntryError naming what is wrong.
std::string encode_features_entry(const registration::ModelFeatures& features,
                                  const ContentHash& model, const std::string& version);
std::shared_ptr<const registration::ModelFeatures> decode_features_entry(
    std::string_view bytes, const engine::PreparedModel& model, const ContentHash& model_hash,
    const registration::FeatureOptions& options, const std::string& version);
std::shared_ptr<const registration::ModelFeatures> decode_features_entry(
    std::string_view bytes, const engine::PreparedModel&& model, const ContentHash& model_hash,
    const registration::FeatureOptions& options, const std::string& version) = delete;

// An entry of the area, the voxel and the keypoints alone (builds the keypoints if they are not
// yet), and back: the same header and checks, its own magic; decoded into features that build
// the descriptors and symmetries on first use (ModelFeatures::from_samples).
std::string encode_samples_entry(const registration::ModelFeatures& features,
                                 const ContentHash& model, const std::string& version);
std::shared_ptr<const registration::ModelFeatures> decode_samples_entry(
    std::string_view bytes, const engine::PreparedModel& model, const ContentHash& model_hash,
    const registration::FeatureOptions& options, const std::string& version);
std::shared_ptr<const registration::ModelFeatures> decode_samples_entry(
    std::string_view bytes, const engine::PreparedModel&& model, const ContentHash& model_hash,
    const registration::FeatureOptions& options, const std::string& version) = delete;
// The entry file the features of a model with this hash and these options would use.
std::string features_cache_entry_path(const FeaturesCacheSettings& settings,
                                      const ContentHash& model,
                                      const registration::FeatureOptions& options);
// Its entry of the area and keypoints alone: the same name, extension .nrbsamp.
std::string features_cache_samples_path(const FeaturesCacheSettings& settings,
                                        const ContentHash& model,
                                        const registration::FeatureOptions& options);

// The features of `model` (which must outlive them) for `options`: on a hit the stored ones;
// otherwise built in full (build_all) and stored for next time. Disabled: a fresh ModelFeatures,
// built lazily as without a cache. Errors of building (the model has no area: std::runtime_error)
// pass through, and nothing is stored. The -v log says hit, miss or rebuilt and the time.
std::shared_ptr<const registration::ModelFeatures> load_model_features(
    const engine::PreparedModel& model, const registration::FeatureOptions& options,
    const FeaturesCacheSettings& settings, CacheOutcome* outcome = nullptr);
std::shared_ptr<const registration::ModelFeatures> load_model_features(
    const engine::PreparedModel&& model, const registration::FeatureOptions& options,
    const FeaturesCacheSettings& settings, CacheOutcome* outcome = nullptr) = delete;

// For the runs that need only the features' cheap parts (an alignment from a given pose: the
// area for the noise estimate and the keypoints for the verdict's coverage, together a few
// tenths of a second on a large part): a full entry's features when there is one; else those of
// an entry of the area and keypoints alone; else both measured now and stored as such an entry
// for the next run (the descriptors are never built here: they cost seconds, more than these
// runs take). An entry that is not usable gets a warning naming it and what is wrong: a full one
// is left for the next full load to replace, one of the samples alone is replaced now. Disabled:
// a fresh ModelFeatures, as without a cache.
std::shared_ptr<const registration::ModelFeatures> cached_model_features(
    const engine::PreparedModel& model, const registration::FeatureOptions& options,
    const FeaturesCacheSettings& settings, CacheOutcome* outcome = nullptr);
std::shared_ptr<const registration::ModelFeatures> cached_model_features(
    const engine::PreparedModel&& model, const registration::FeatureOptions& options,
    const FeaturesCacheSettings& settings, CacheOutcome* outcome = nullptr) = delete;

}  // namespace nurbsreg::io

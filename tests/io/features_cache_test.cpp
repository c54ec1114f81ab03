// The model-features cache (io/features_cache.hpp): a hit gives the features a fresh build gives,
// bit for bit, and so the same alignment; a truncated, corrupt, stale or foreign entry is
// detected, rebuilt with a warning naming the entry and replaced, never used; other options or
// another model use another entry; a count that claims more than the entry holds is an error
// before anything is allocated for it; an unwritable cache costs a warning, not the features.

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "nurbsreg/engine/synthetic_scan.hpp"
#include "nurbsreg/io/features_cache.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "nurbsreg/registration/alignment.hpp"
#include "support/log_capture.hpp"
#include "support/saddle_model.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::io {
namespace {

namespace fs = std::filesystem;
using registration::FeatureOptions;
using registration::ModelFeatures;

const engine::PreparedModel& saddle() {
  static const engine::PreparedModel m(test::saddle_model());
  return m;
}

const engine::PreparedModel& panel() {
  static const engine::PreparedModel m(
      read_model_json(nurbsreg::test::examples_dir() + "/panel.json"));
  return m;
}

template <class T>
bool same_bits(const T* a, const T* b, std::size_t n) {
  return n == 0 || std::memcmp(a, b, n * sizeof(T)) == 0;
}

// Every part of `a` and `b`, bit for bit.
void expect_same_bits(const ModelFeatures& a, const ModelFeatures& b) {
  EXPECT_EQ(std::bit_cast<std::uint64_t>(a.surface_area()),
            std::bit_cast<std::uint64_t>(b.surface_area()));
  EXPECT_EQ(std::bit_cast<std::uint64_t>(a.voxel()), std::bit_cast<std::uint64_t>(b.voxel()));
  const auto& ka = a.keypoints();
  const auto& kb = b.keypoints();
  ASSERT_EQ(ka.points.size(), kb.points.size());
  ASSERT_EQ(ka.normals.size(), kb.normals.size());
  EXPECT_TRUE(same_bits(ka.points.data()->data(), kb.points.data()->data(), 3 * ka.points.size()));
  EXPECT_TRUE(
      same_bits(ka.normals.data()->data(), kb.normals.data()->data(), 3 * ka.normals.size()));
  ASSERT_EQ(a.descriptors().rows(), b.descriptors().rows());
  ASSERT_EQ(a.descriptors().cols(), b.descriptors().cols());
  EXPECT_TRUE(same_bits(a.descriptors().data(), b.descriptors().data(),
                        static_cast<std::size_t>(a.descriptors().size())));
  ASSERT_EQ(a.symmetries().size(), b.symmetries().size());
  for (std::size_t i = 0; i < a.symmetries().size(); ++i)
    EXPECT_TRUE(same_bits(a.symmetries()[i].matrix().data(), b.symmetries()[i].matrix().data(), 16))
        << "symmetry " << i;
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}
void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

// The header's size before the payload (features_cache.cpp's layout): magic, format, byte
// order, the version string with its length, the model hash, four option words, payload size
// and checksum.
std::size_t header_size(const std::string& version) {
  return 8 + 4 + 4 + 8 + version.size() + 2 * 8 + 4 * 8 + 8 + 8;
}
// Writes a payload into an entry with a matching size and checksum (a well-formed header around
// a payload of our choice).
std::string with_payload(const std::string& entry, const std::string& version,
                         const std::string& payload) {
  const std::size_t h = header_size(version);
  std::string out = entry.substr(0, h) + payload;
  const std::uint64_t size = payload.size(), check = hash_bytes(payload).lo;
  std::memcpy(out.data() + h - 16, &size, 8);
  std::memcpy(out.data() + h - 8, &check, 8);
  return out;
}

class FeaturesCacheTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("nurbsreg_features_cache_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    settings_.enabled = true;
    settings_.directory = (dir_ / "cache").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::shared_ptr<const ModelFeatures> load(const engine::PreparedModel& model,
                                            CacheOutcome* outcome,
                                            std::vector<std::string>* warnings = nullptr) {
    std::shared_ptr<const ModelFeatures> f;
    const auto w = test::log_lines_of(
        spdlog::level::warn, [&] { f = load_model_features(model, options_, settings_, outcome); });
    if (warnings != nullptr) *warnings = w;
    return f;
  }
  std::string entry(const engine::PreparedModel& model) const {
    return features_cache_entry_path(settings_, hash_model(model.model()), options_);
  }
  // A load of the saddle that finds its entry unusable: rebuilt, the warning names the entry
  // and `why`, and the next load is a hit again (the entry was replaced).
  void expect_rebuilt(const std::string& why) {
    CacheOutcome outcome{};
    std::vector<std::string> warnings;
    const auto f = load(saddle(), &outcome, &warnings);
    EXPECT_EQ(outcome, CacheOutcome::rebuilt);
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find(entry(saddle())), std::string::npos) << warnings[0];
    EXPECT_NE(warnings[0].find(why), std::string::npos) << warnings[0];
    expect_same_bits(*f, fresh_saddle());
    load(saddle(), &outcome);
    EXPECT_EQ(outcome, CacheOutcome::hit);
  }
  static const ModelFeatures& fresh_saddle() {
    static const ModelFeatures f(saddle());
    return f;
  }

  fs::path dir_;
  FeaturesCacheSettings settings_;
  FeatureOptions options_;
};

TEST_F(FeaturesCacheTest, RoundTripIsBitExact) {
  const ModelFeatures& fresh = fresh_saddle();
  ASSERT_EQ(fresh.symmetries().size(), 3u);  // the stored turns are exercised
  const ContentHash key = hash_model(saddle().model());
  const std::string bytes = encode_features_entry(fresh, key, "v1");
  const auto decoded = decode_features_entry(bytes, saddle(), key, options_, "v1");
  expect_same_bits(*decoded, fresh);
  EXPECT_EQ(decoded->options().seed, options_.seed);
}

// from_parts builds nothing: the accessors give the parts as given (a changed descriptor and
// no symmetries stay so), never a fresh build over them.
TEST_F(FeaturesCacheTest, FromPartsGivesThePartsAsGiven) {
  registration::ModelFeatureParts parts;
  parts.surface_area = fresh_saddle().surface_area();
  parts.voxel = fresh_saddle().voxel();
  parts.keypoints = fresh_saddle().keypoints();
  parts.descriptors = fresh_saddle().descriptors();
  parts.descriptors(0, 0) += 1.0f;
  const auto f = ModelFeatures::from_parts(saddle(), options_, parts);
  EXPECT_EQ(f->descriptors()(0, 0), parts.descriptors(0, 0));
  EXPECT_TRUE(f->symmetries().empty());  // the saddle's three turns were not searched for
  f->build_all();
  EXPECT_EQ(f->descriptors()(0, 0), parts.descriptors(0, 0));
  EXPECT_TRUE(f->symmetries().empty());
}

// from_samples builds no keypoints: the accessors give the samples as given (a moved keypoint
// stays moved), and the parts built on first use are built from them.
TEST_F(FeaturesCacheTest, FromSamplesGivesTheSamplesAsGiven) {
  registration::ModelFeatureParts parts;
  parts.surface_area = fresh_saddle().surface_area();
  parts.voxel = fresh_saddle().voxel();
  parts.keypoints = fresh_saddle().keypoints();
  parts.keypoints.points.pop_back();
  parts.keypoints.normals.pop_back();
  const auto f = ModelFeatures::from_samples(saddle(), options_, parts);
  EXPECT_EQ(f->keypoints().points.size(), parts.keypoints.points.size());
  EXPECT_EQ(f->keypoints().points.back(), parts.keypoints.points.back());
  f->build_all();
  EXPECT_EQ(f->keypoints().points.size(), parts.keypoints.points.size());
  EXPECT_EQ(f->described_keypoints().points.size(),
            static_cast<std::size_t>(f->descriptors().rows()));
}

// Found by fuzz_cache_entry (its seed samples_tiny_area): an entry's area, with the voxel it
// gives, may be tiny; the descriptors' grids then have cells of 1e-150, and a keypoint's cell
// coordinate overflowed the conversion to an integer (undefined; the sanitizer build stops on
// it). The build now completes on clamped cells, with finite descriptors.
TEST_F(FeaturesCacheTest, SamplesWithATinyAreaStillBuildFiniteDescriptors) {
  registration::ModelFeatureParts parts;
  parts.surface_area = 2e-299;
  parts.voxel = std::sqrt(parts.surface_area /
                          static_cast<double>(std::max<std::size_t>(options_.keypoints, 16)));
  parts.keypoints = fresh_saddle().keypoints();
  const auto f = ModelFeatures::from_samples(saddle(), options_, parts);
  EXPECT_EQ(f->described_keypoints().points.size(),
            static_cast<std::size_t>(f->descriptors().rows()));
  EXPECT_TRUE(f->descriptors().allFinite());
}

TEST_F(FeaturesCacheTest, HitAfterMissGivesTheSameAlignmentToTheBit) {
  CacheOutcome outcome{};
  const auto built = load(panel(), &outcome);
  EXPECT_EQ(outcome, CacheOutcome::miss);
  EXPECT_TRUE(fs::exists(entry(panel())));
  const auto hit = load(panel(), &outcome);
  EXPECT_EQ(outcome, CacheOutcome::hit);
  expect_same_bits(*hit, *built);

  engine::SyntheticScanOptions o;
  o.points = 3000;
  o.noise_sigma = 0.01;
  o.seed = 5;
  o.T_scan_model = engine::pose_from_euler_degrees(150, -60, 20, engine::Vec3(1000, 0, 0));
  const engine::SyntheticScan scan = engine::make_synthetic_scan(panel().model(), o);
  registration::Aligner cached(panel(), icp::IcpOptions{}, {}, hit);
  registration::Aligner fresh(panel(), icp::IcpOptions{});  // builds its own, no cache
  const registration::AlignmentResult a = cached.align(scan.points);
  const registration::AlignmentResult b = fresh.align(scan.points);
  ASSERT_FALSE(a.failure) << *a.failure;
  EXPECT_TRUE(
      same_bits(a.icp.T_model_scan.matrix().data(), b.icp.T_model_scan.matrix().data(), 16));
  EXPECT_EQ(a.icp.inliers, b.icp.inliers);
  EXPECT_EQ(std::bit_cast<std::uint64_t>(a.icp.rms), std::bit_cast<std::uint64_t>(b.icp.rms));
}

// The runs from a given pose read a full entry when there is one; otherwise they measure the
// area and keypoints, store those alone and read them next time, never building the rest. The
// features from those samples build the rest on first use, to the same bits as a fresh build.
TEST_F(FeaturesCacheTest, CachedFeaturesStoreOnlyTheAreaAndKeypoints) {
  const std::string samples =
      features_cache_samples_path(settings_, hash_model(saddle().model()), options_);
  const auto cached = [&](CacheOutcome& outcome, std::vector<std::string>* debug = nullptr) {
    std::shared_ptr<const ModelFeatures> f;
    const auto lines = test::log_lines_of(spdlog::level::debug, [&] {
      f = cached_model_features(saddle(), options_, settings_, &outcome);
    });
    if (debug != nullptr) *debug = lines;
    return f;
  };
  CacheOutcome outcome{};
  const auto missed = cached(outcome);
  EXPECT_EQ(outcome, CacheOutcome::miss);
  EXPECT_TRUE(fs::exists(samples));
  EXPECT_FALSE(fs::exists(entry(saddle())));
  const std::string stored = read_bytes(samples);
  expect_same_bits(*missed, fresh_saddle());  // builds the descriptors and symmetries too
  EXPECT_FALSE(fs::exists(entry(saddle())));  // not stored even then
  EXPECT_EQ(read_bytes(samples), stored);

  std::vector<std::string> debug;
  const auto hit = cached(outcome, &debug);
  EXPECT_EQ(outcome, CacheOutcome::hit);
  ASSERT_EQ(debug.size(), 1u);
  EXPECT_NE(debug[0].find("the area and keypoints read from the cache (hit, " + samples),
            std::string::npos)
      << debug[0];
  expect_same_bits(*hit, fresh_saddle());  // descriptors and symmetries built from the samples

  // A corrupt entry of the samples: a warning naming it, measured again and replaced.
  std::string bytes = stored;
  bytes[bytes.size() / 2] ^= 0x10;
  write_bytes(samples, bytes);
  std::shared_ptr<const ModelFeatures> f;
  const auto warnings = test::log_lines_of(spdlog::level::warn, [&] {
    f = cached_model_features(saddle(), options_, settings_, &outcome);
  });
  EXPECT_EQ(outcome, CacheOutcome::rebuilt);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find(samples), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[0].find("checksum"), std::string::npos) << warnings[0];
  EXPECT_EQ(read_bytes(samples), stored);
  expect_same_bits(*f, fresh_saddle());

  // A full entry comes first: read even when the samples' entry is corrupt.
  load(saddle(), nullptr);
  write_bytes(samples, bytes);
  cached(outcome, &debug);
  EXPECT_EQ(outcome, CacheOutcome::hit);
  ASSERT_EQ(debug.size(), 1u);
  EXPECT_NE(debug[0].find("model features: read from the cache (hit, " + entry(saddle())),
            std::string::npos)
      << debug[0];
  // A corrupt full entry: a warning naming it, left for a full load to replace; the samples'
  // entry (corrupt too) is replaced.
  std::string full = read_bytes(entry(saddle()));
  full[full.size() / 2] ^= 0x10;
  write_bytes(entry(saddle()), full);
  const auto both = test::log_lines_of(spdlog::level::warn, [&] {
    f = cached_model_features(saddle(), options_, settings_, &outcome);
  });
  EXPECT_EQ(outcome, CacheOutcome::rebuilt);
  ASSERT_EQ(both.size(), 2u);
  EXPECT_NE(both[0].find(entry(saddle())), std::string::npos) << both[0];
  EXPECT_NE(both[1].find(samples), std::string::npos) << both[1];
  EXPECT_EQ(read_bytes(entry(saddle())), full);
  EXPECT_EQ(read_bytes(samples), stored);
  expect_same_bits(*f, fresh_saddle());

  settings_.enabled = false;
  cached_model_features(saddle(), options_, settings_, &outcome);
  EXPECT_EQ(outcome, CacheOutcome::disabled);
}

// The samples' entry: the area, voxel and keypoints bit for bit; every header check of the full
// entry (magic: a full entry is not one of samples, nor the reverse), counts checked against
// the bytes there, and from_samples's checks of the parts.
TEST_F(FeaturesCacheTest, SamplesEntryRoundTripAndChecks) {
  const ContentHash key = hash_model(saddle().model());
  const std::string good = encode_samples_entry(fresh_saddle(), key, "v1");
  const auto decoded = decode_samples_entry(good, saddle(), key, options_, "v1");
  expect_same_bits(*decoded, fresh_saddle());
  const auto fails = [&](const std::string& bytes, const std::string& why) {
    try {
      decode_samples_entry(bytes, saddle(), key, options_, "v1");
      ADD_FAILURE() << "accepted; expected: " << why;
    } catch (const CacheEntryError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  };
  const std::string full = encode_features_entry(fresh_saddle(), key, "v1");
  fails(full, "magic");
  EXPECT_THROW(decode_features_entry(good, saddle(), key, options_, "v1"), CacheEntryError);
  fails(good.substr(0, good.size() - 1), "truncated");
  std::string flipped = good;
  flipped[flipped.size() - 3] ^= 0x01;
  fails(flipped, "checksum");
  try {
    decode_samples_entry(good, saddle(), hash_model(panel().model()), options_, "v1");
    ADD_FAILURE() << "another model's entry accepted";
  } catch (const CacheEntryError& e) {
    EXPECT_NE(std::string(e.what()).find("another model"), std::string::npos) << e.what();
  }
  const std::string payload = good.substr(header_size("v1"));
  // The well-formed entry around the payload decodes: the test's layout is the writer's.
  EXPECT_NO_THROW(
      decode_samples_entry(with_payload(good, "v1", payload), saddle(), key, options_, "v1"));
  const std::uint64_t huge = std::uint64_t{1} << 40;
  std::string p = payload;
  std::memcpy(p.data() + 16, &huge, 8);
  fails(with_payload(good, "v1", p), "count runs past the end");
  fails(with_payload(good, "v1", payload + "x"), "bytes after the keypoints");
  p = payload;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::memcpy(p.data() + 16 + 8 + 8, &nan, 8);  // keypoint 0's y
  fails(with_payload(good, "v1", p), "keypoint 0 is not finite");
  p = payload;
  const double area = 1.0;  // a finite area that does not give the stored voxel
  std::memcpy(p.data(), &area, 8);
  fails(with_payload(good, "v1", p), "voxel");
  // from_samples takes no descriptors or symmetries.
  registration::ModelFeatureParts parts;
  parts.surface_area = fresh_saddle().surface_area();
  parts.voxel = fresh_saddle().voxel();
  parts.keypoints = fresh_saddle().keypoints();
  EXPECT_NO_THROW(ModelFeatures::from_samples(saddle(), options_, parts));
  parts.symmetries = fresh_saddle().symmetries();
  EXPECT_THROW(ModelFeatures::from_samples(saddle(), options_, parts), std::invalid_argument);
}

TEST_F(FeaturesCacheTest, TruncatedEntryIsRebuilt) {
  load(saddle(), nullptr);
  fs::resize_file(entry(saddle()), fs::file_size(entry(saddle())) / 2);
  expect_rebuilt("truncated");
  fs::resize_file(entry(saddle()), 5);  // shorter than the magic
  expect_rebuilt("bad magic");
}

TEST_F(FeaturesCacheTest, FlippedPayloadByteIsRebuilt) {
  load(saddle(), nullptr);
  std::string bytes = read_bytes(entry(saddle()));
  bytes[bytes.size() * 3 / 4] ^= 0x10;  // a descriptor's bit
  write_bytes(entry(saddle()), bytes);
  expect_rebuilt("checksum");
}

TEST_F(FeaturesCacheTest, AnotherVersionsEntryIsStale) {
  load(saddle(), nullptr);
  // Another version's entry has another name: never read.
  const FeaturesCacheSettings current = settings_;
  settings_.version = "nurbsreg 9.9.9 features 99";
  EXPECT_NE(entry(saddle()),
            features_cache_entry_path(current, hash_model(saddle().model()), options_));
  CacheOutcome outcome{};
  load(saddle(), &outcome);
  EXPECT_EQ(outcome, CacheOutcome::miss);
  // ... and found under this version's name (copied, or a hash collision of the names), it is
  // stale.
  fs::copy_file(entry(saddle()),
                features_cache_entry_path(current, hash_model(saddle().model()), options_),
                fs::copy_options::overwrite_existing);
  settings_ = current;
  expect_rebuilt("stale");
}

TEST_F(FeaturesCacheTest, OtherOptionsUseAnotherEntry) {
  load(saddle(), nullptr);
  const std::string first = entry(saddle());
  CacheOutcome outcome{};
  for (int field = 0; field < 4; ++field) {
    options_ = FeatureOptions{};
    if (field == 0) options_.keypoints = 2000;
    if (field == 1) options_.normal_radius = 2.5;
    if (field == 2) options_.feature_radius = 7.0;
    if (field == 3) options_.seed = 2;
    EXPECT_NE(entry(saddle()), first) << "field " << field;
    const auto f = load(saddle(), &outcome);
    EXPECT_EQ(outcome, CacheOutcome::miss) << "field " << field;
    EXPECT_EQ(f->options().seed, options_.seed);
    // Found under the name of the default options, features of other options are rebuilt.
    fs::copy_file(entry(saddle()), first, fs::copy_options::overwrite_existing);
    options_ = FeatureOptions{};
    expect_rebuilt("other feature options");
  }
}

TEST_F(FeaturesCacheTest, AnotherModelsEntryIsStale) {
  load(panel(), nullptr);
  fs::create_directories(settings_.directory);
  fs::copy_file(entry(panel()), entry(saddle()), fs::copy_options::overwrite_existing);
  expect_rebuilt("another model");
}

TEST_F(FeaturesCacheTest, ACountBeyondTheEntryIsAnErrorNotAnAllocation) {
  const ContentHash key = hash_model(saddle().model());
  const std::string good = encode_features_entry(fresh_saddle(), key, "v1");
  const std::string payload = good.substr(header_size("v1"));
  const auto fails = [&](const std::string& bytes, const std::string& why) {
    try {
      decode_features_entry(bytes, saddle(), key, options_, "v1");
      ADD_FAILURE() << "accepted; expected: " << why;
    } catch (const CacheEntryError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  };
  // The well-formed entry around the payload decodes: the test's layout is the writer's.
  EXPECT_NO_THROW(
      decode_features_entry(with_payload(good, "v1", payload), saddle(), key, options_, "v1"));
  // 2^40 keypoints (48 TB): with a matching checksum, only the count check stops it (an
  // allocation would throw std::bad_alloc or std::length_error, not CacheEntryError).
  const std::uint64_t huge = std::uint64_t{1} << 40;
  std::string p = payload;
  std::memcpy(p.data() + 16, &huge, 8);
  fails(with_payload(good, "v1", p), "count runs past the end");
  // 2^40 symmetries: the last count.
  const std::size_t n = fresh_saddle().keypoints().points.size();
  // One descriptor row per described keypoint (ModelFeatures::described_keypoints).
  const auto rows = static_cast<std::size_t>(fresh_saddle().descriptors().rows());
  const std::size_t symmetries_at = 16 + 8 + n * 48 + 16 + rows * 32 * 4;
  p = payload;
  std::memcpy(p.data() + symmetries_at, &huge, 8);
  fails(with_payload(good, "v1", p), "count runs past the end");
  // More descriptor rows than keypoints.
  p = payload;
  const std::uint64_t more = n + 1;
  std::memcpy(p.data() + 16 + 8 + n * 48 + 8, &more, 8);
  fails(with_payload(good, "v1", p), "descriptors for");
  // A header claiming a payload far beyond the file: a compare, nothing read or allocated.
  std::string claims = good;
  std::memcpy(claims.data() + header_size("v1") - 16, &huge, 8);
  fails(claims, "does not match its header");
}

TEST_F(FeaturesCacheTest, NonFiniteOrMismatchedPartsAreRejected) {
  const ContentHash key = hash_model(saddle().model());
  const std::string good = encode_features_entry(fresh_saddle(), key, "v1");
  const std::string payload = good.substr(header_size("v1"));
  const auto fails = [&](const std::string& p, const std::string& why) {
    try {
      decode_features_entry(with_payload(good, "v1", p), saddle(), key, options_, "v1");
      ADD_FAILURE() << "accepted; expected: " << why;
    } catch (const CacheEntryError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::string p = payload;
  std::memcpy(p.data() + 16 + 8 + 8, &nan, 8);  // keypoint 0's y
  fails(p, "keypoint 0 is not finite");
  // Finite but far off the model (fuzz_cache_entry: 9.9e91 overflowed the described keypoints'
  // grid, which from_parts builds): not a sample of this model.
  p = payload;
  const double far = 9.93014e91;
  std::memcpy(p.data() + 16 + 8 + 8, &far, 8);
  fails(p, "keypoint 0 lies outside the model's bounding box");
  p = payload;
  const double area = 1.0;  // a finite area that does not give the stored voxel
  std::memcpy(p.data(), &area, 8);
  fails(p, "voxel");
  p = payload;
  std::memcpy(p.data(), &nan, 8);
  fails(p, "surface area");
  const std::size_t n = fresh_saddle().keypoints().points.size();
  p = payload;
  const float inf = std::numeric_limits<float>::infinity();
  std::memcpy(p.data() + 16 + 8 + n * 48 + 16 + 4 * 5, &inf, 4);
  fails(p, "descriptor is not finite");
  p = payload;
  std::memcpy(p.data() + p.size() - 8, &nan, 8);  // the last symmetry's z translation
  fails(p, "symmetry 2 is not finite");
  // from_parts checks the same for callers that keep the parts elsewhere.
  registration::ModelFeatureParts parts;
  parts.surface_area = fresh_saddle().surface_area();
  parts.voxel = fresh_saddle().voxel();
  parts.keypoints = fresh_saddle().keypoints();
  parts.descriptors = fresh_saddle().descriptors().topRows(3);
  EXPECT_THROW(ModelFeatures::from_parts(saddle(), options_, parts), std::invalid_argument);
}

TEST_F(FeaturesCacheTest, DisabledOrUnwritableCacheStillGivesTheFeatures) {
  settings_.enabled = false;
  CacheOutcome outcome{};
  const auto lazy = load(saddle(), &outcome);
  EXPECT_EQ(outcome, CacheOutcome::disabled);
  EXPECT_FALSE(fs::exists(settings_.directory));
  expect_same_bits(*lazy, fresh_saddle());
  // A cache "directory" that is a file: a warning naming the entry, and the features anyway.
  settings_.enabled = true;
  std::ofstream(settings_.directory) << "not a directory";
  std::vector<std::string> warnings;
  const auto f = load(saddle(), &outcome, &warnings);
  EXPECT_EQ(outcome, CacheOutcome::miss);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("could not store"), std::string::npos) << warnings[0];
  expect_same_bits(*f, fresh_saddle());
}

// Processes (here threads) that miss at once each build and rename a complete entry into
// place: all get the same features, and the entry left is whole.
TEST_F(FeaturesCacheTest, ConcurrentLoadsAgree) {
  std::vector<std::shared_ptr<const ModelFeatures>> got(4);
  std::vector<std::thread> threads;
  for (std::size_t k = 0; k < got.size(); ++k)
    threads.emplace_back([&, k] { got[k] = load_model_features(saddle(), options_, settings_); });
  for (std::thread& t : threads)
    t.join();
  for (const auto& f : got)
    expect_same_bits(*f, fresh_saddle());
  CacheOutcome outcome{};
  expect_same_bits(*load(saddle(), &outcome), fresh_saddle());
  EXPECT_EQ(outcome, CacheOutcome::hit);
}

}  // namespace
}  // namespace nurbsreg::io

// The converted-model cache (io/model_cache.hpp): a hit gives the converted model bit for bit; a
// corrupt, truncated or stale entry is detected and rebuilt, never used; a version change
// invalidates; conversion errors pass through and store nothing; concurrent loads agree.

#include <gtest/gtest.h>

#include <algorithm>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "nurbsreg/io/cad_import.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/model_cache.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::io {
namespace {

namespace fs = std::filesystem;

// A real converted part (trim loops, 3-D edges, reversed faces), converted once.
const engine::Model& screw() {
  static const engine::Model m =
      read_cad_file(nurbsreg::test::shared_dir() + "/data/real/occt/screw.step");
  return m;
}

class ModelCacheTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("nurbsreg_cache_test_" +
            std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    source_ = (dir_ / "part.step").string();
    std::ofstream(source_, std::ios::binary) << "ISO-10303-21; a stand-in source file\n";
    settings_.enabled = true;
    settings_.directory = (dir_ / "cache").string();
    // The real conversion, before any test starts threads: the STEP import forks a child, and
    // LLVM 14's AddressSanitizer does not hold its allocator's locks across fork(), so a fork
    // while another thread allocates can leave the child blocked on them for good (seen under
    // ASan in 9 of 40 runs of ConcurrentLoadsAgree, never in Release: glibc's malloc is
    // fork-safe). The tests check the cache, whose "conversion" is this model.
    screw();
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Loads source_ through the cache; the "conversion" counts its calls and returns screw().
  engine::Model load(CacheOutcome* outcome = nullptr) {
    return read_model_through_cache(
        source_, settings_,
        [this](const std::string&) {
          ++conversions_;
          return screw();
        },
        outcome);
  }
  std::string entry() const {
    std::ifstream in(source_, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return model_cache_entry_path(settings_, hash_bytes(bytes), bytes.size());
  }

  fs::path dir_;
  std::string source_;
  ModelCacheSettings settings_;
  std::atomic<int> conversions_{0};
};

TEST_F(ModelCacheTest, HitGivesTheSameModelBitForBit) {
  CacheOutcome outcome{};
  const engine::Model first = load(&outcome);
  EXPECT_EQ(outcome, CacheOutcome::miss);
  EXPECT_TRUE(fs::exists(entry()));
  const engine::Model second = load(&outcome);
  EXPECT_EQ(outcome, CacheOutcome::hit);
  EXPECT_EQ(conversions_, 1);
  // The JSON writer prints every number in its shortest round-trip form: equal text, equal bits.
  EXPECT_EQ(model_to_json(second), model_to_json(screw()));
  ASSERT_FALSE(second.surfaces.empty());
  std::size_t trimmed = 0;
  for (const engine::NurbsSurface& s : second.surfaces)
    trimmed += s.is_trimmed() ? 1 : 0;
  EXPECT_GT(trimmed, 0u);
}

TEST_F(ModelCacheTest, CorruptEntryIsRebuiltNotUsed) {
  load();
  std::string bytes;
  {
    std::ifstream in(entry(), std::ios::binary);
    bytes.assign((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  }
  // One bit of one control point, deep in the payload: the checksum catches it.
  bytes[bytes.size() * 3 / 4] ^= 0x10;
  std::ofstream(entry(), std::ios::binary | std::ios::trunc) << bytes;
  CacheOutcome outcome{};
  const engine::Model m = load(&outcome);
  EXPECT_EQ(outcome, CacheOutcome::rebuilt);
  EXPECT_EQ(conversions_, 2);
  EXPECT_EQ(model_to_json(m), model_to_json(screw()));
  load(&outcome);  // the rebuilt entry replaced the corrupt one
  EXPECT_EQ(outcome, CacheOutcome::hit);
}

TEST_F(ModelCacheTest, TruncatedEntryIsRebuilt) {
  load();
  fs::resize_file(entry(), fs::file_size(entry()) / 2);
  CacheOutcome outcome{};
  load(&outcome);
  EXPECT_EQ(outcome, CacheOutcome::rebuilt);
  fs::resize_file(entry(), 5);  // shorter than the magic
  load(&outcome);
  EXPECT_EQ(outcome, CacheOutcome::rebuilt);
  EXPECT_EQ(conversions_, 3);
}

TEST_F(ModelCacheTest, EveryDecodingCheckNamesTheProblem) {
  const ContentHash key{1, 2};
  const std::string good = encode_model_entry(screw(), key, 10, "v1");
  EXPECT_EQ(model_to_json(decode_model_entry(good, key, 10, "v1")), model_to_json(screw()));
  const auto fails = [&](std::string_view bytes, const ContentHash& k, std::uint64_t size,
                         const std::string& version, const std::string& why) {
    try {
      decode_model_entry(bytes, k, size, version);
      ADD_FAILURE() << "accepted; expected: " << why;
    } catch (const CacheEntryError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  };
  fails(good, key, 10, "v2", "stale");                         // another program version
  fails(good, ContentHash{1, 3}, 10, "v1", "another source");  // another source file
  fails(good, key, 11, "v1", "another source");
  fails(std::string_view(good).substr(0, good.size() - 1), key, 10, "v1", "truncated");
  fails(std::string_view(good).substr(0, 40), key, 10, "v1", "truncated");
  fails("garbage!garbage!garbage!", key, 10, "v1", "bad magic");
  std::string flipped = good;
  flipped[good.size() - 3] ^= 1;
  fails(flipped, key, 10, "v1", "checksum");
}

// Findings of fuzz_cache_entry: a corrupt entry's bytes reached the messages (the version it
// names, a surface name in the model's validation error). They must stay one printable line.
TEST_F(ModelCacheTest, MessagesQuotingAnEntrysBytesStayPrintable) {
  const ContentHash key{1, 2};
  const auto message = [&](const std::string& bytes, const std::string& version) {
    try {
      decode_model_entry(bytes, key, 10, version);
    } catch (const CacheEntryError& e) {
      return std::string(e.what());
    }
    ADD_FAILURE() << "accepted";
    return std::string();
  };
  const auto printable = [](const std::string& m) {
    return !m.empty() && std::all_of(m.begin(), m.end(), [](char c) {
      return static_cast<unsigned char>(c) >= 0x20 && static_cast<unsigned char>(c) < 0x7f;
    });
  };
  const std::string stale = message(encode_model_entry(screw(), key, 10, "fu\xc0\n"), "v1");
  EXPECT_TRUE(printable(stale)) << stale;
  EXPECT_NE(stale.find("fu\\xc0\\x0a"), std::string::npos) << stale;
  engine::Model bad = screw();
  bad.surfaces.at(0).name = "sa\x9c\x9b";
  bad.surfaces.at(0).degree_u = -3;
  const std::string invalid = message(encode_model_entry(bad, key, 10, "v1"), "v1");
  EXPECT_TRUE(printable(invalid)) << invalid;
  EXPECT_NE(invalid.find("invalid model"), std::string::npos) << invalid;
}

TEST_F(ModelCacheTest, VersionChangeInvalidates) {
  load();
  settings_.version = "nurbsreg 9.9.9 cache 99";
  CacheOutcome outcome{};
  load(&outcome);
  EXPECT_EQ(outcome, CacheOutcome::miss);  // another entry name: the old one is never read
  EXPECT_EQ(conversions_, 2);
  load(&outcome);
  EXPECT_EQ(outcome, CacheOutcome::hit);
}

TEST_F(ModelCacheTest, ChangedSourceIsConvertedAgain) {
  load();
  std::ofstream(source_, std::ios::binary | std::ios::app) << "one more line\n";
  CacheOutcome outcome{};
  load(&outcome);
  EXPECT_EQ(outcome, CacheOutcome::miss);
  EXPECT_EQ(conversions_, 2);
}

TEST_F(ModelCacheTest, AnEntryUnderAnotherSourcesNameIsStale) {
  load();
  const std::string old_entry = entry();
  std::ofstream(source_, std::ios::binary | std::ios::trunc) << "another source file\n";
  fs::copy_file(old_entry, entry(), fs::copy_options::overwrite_existing);
  CacheOutcome outcome{};
  load(&outcome);
  EXPECT_EQ(outcome, CacheOutcome::rebuilt);
}

TEST_F(ModelCacheTest, ConversionErrorsPassThroughAndStoreNothing) {
  EXPECT_THROW(read_model_through_cache(
                   source_, settings_,
                   [](const std::string& p) -> engine::Model { throw InputError(p, "broken"); }),
               InputError);
  EXPECT_FALSE(fs::exists(entry()));
}

TEST_F(ModelCacheTest, DisabledOrUnwritableCacheStillLoads) {
  settings_.enabled = false;
  CacheOutcome outcome{};
  load(&outcome);
  EXPECT_EQ(outcome, CacheOutcome::disabled);
  EXPECT_FALSE(fs::exists(settings_.directory));
  // A cache "directory" that is a file: a warning, and the model anyway.
  settings_.enabled = true;
  std::ofstream(settings_.directory) << "not a directory";
  const engine::Model m = load(&outcome);
  EXPECT_EQ(model_to_json(m), model_to_json(screw()));
}

TEST_F(ModelCacheTest, ConcurrentLoadsAgree) {
  std::vector<std::string> json(4);
  std::vector<std::thread> threads;
  for (std::size_t k = 0; k < json.size(); ++k)
    threads.emplace_back([&, k] { json[k] = model_to_json(load()); });
  for (std::thread& t : threads)
    t.join();
  for (const std::string& j : json)
    EXPECT_EQ(j, model_to_json(screw()));
  CacheOutcome outcome{};
  load(&outcome);
  EXPECT_EQ(outcome, CacheOutcome::hit);
}

// The environment decides: NURBSREG_CACHE_DIR first, NURBSREG_NO_CACHE turns it off.
TEST(ModelCacheSettings, FromEnvironment) {
  ::setenv("NURBSREG_CACHE_DIR", "/tmp/somewhere", 1);
  ::unsetenv("NURBSREG_NO_CACHE");
  ModelCacheSettings s = ModelCacheSettings::from_environment();
  EXPECT_TRUE(s.enabled);
  EXPECT_EQ(s.directory, "/tmp/somewhere");
  ::setenv("NURBSREG_NO_CACHE", "1", 1);
  EXPECT_FALSE(ModelCacheSettings::from_environment().enabled);
  ::setenv("NURBSREG_NO_CACHE", "0", 1);
  EXPECT_TRUE(ModelCacheSettings::from_environment().enabled);
  ::unsetenv("NURBSREG_NO_CACHE");
  ::unsetenv("NURBSREG_CACHE_DIR");
  EXPECT_NE(model_cache_version().find("cache"), std::string::npos);
}

}  // namespace
}  // namespace nurbsreg::io

// The LZF codec of PCD's binary_compressed data (io/src/lzf.cpp): what the encoder writes the
// decoder reads back exactly, on the inputs that exercise each part of the format (literal runs
// of every length, back references of the longest length and at the farthest distance, repeats
// beyond it, data that does not compress); the encoder stays within its stated bound and refuses
// an output that does not fit. The decoder itself reads PCL's files (RealPcd tests) and
// Open3D reads the encoder's (tests/python/test_open3d.py).
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <vector>

#include "lzf.hpp"

namespace nurbsreg::io::detail {
namespace {

std::vector<std::uint8_t> compress(const std::vector<std::uint8_t>& in) {
  std::vector<std::uint8_t> out(in.size() + in.size() / 32 + 1);
  const std::size_t size = lzf_compress(in.data(), in.size(), out.data(), out.size());
  EXPECT_TRUE(size > 0 || in.empty()) << "the stated bound must always fit";
  out.resize(size);
  return out;
}

void expect_round_trip(const std::vector<std::uint8_t>& in, const char* what) {
  const std::vector<std::uint8_t> packed = compress(in);
  std::vector<std::uint8_t> back(in.size());
  ASSERT_TRUE(lzf_decompress(packed.data(), packed.size(), back.data(), back.size())) << what;
  EXPECT_EQ(back, in) << what;
}

std::vector<std::uint8_t> random_bytes(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<std::uint8_t> v(n);
  for (auto& b : v)
    b = static_cast<std::uint8_t>(rng());
  return v;
}

TEST(Lzf, RoundTripsEveryKindOfInput) {
  for (std::size_t n : {1, 2, 3, 4, 31, 32, 33, 64, 65, 1000}) {
    expect_round_trip(random_bytes(n, n), "random bytes");
    expect_round_trip(std::vector<std::uint8_t>(n, 7), "one byte repeated");
  }
  // Runs far longer than one back reference (264 bytes) and matches of every length.
  std::vector<std::uint8_t> runs;
  for (int length = 1; length < 700; length += 37)
    runs.insert(runs.end(), static_cast<std::size_t>(length), static_cast<std::uint8_t>(length));
  expect_round_trip(runs, "runs");
  // A block repeated at distances just inside and just beyond the farthest reference (8192).
  for (std::size_t gap : {8189, 8190, 8191, 8192, 8193, 8194, 9000}) {
    std::vector<std::uint8_t> v = random_bytes(gap, gap);
    const std::vector<std::uint8_t> head(v.begin(), v.begin() + 300);
    v.insert(v.end(), head.begin(), head.end());
    expect_round_trip(v, "repeat at a distance");
  }
  // Floats of a smooth curve as PCD stores them (one plane per field): partly compressible.
  std::vector<std::uint8_t> planes;
  for (int i = 0; i < 50000; ++i) {
    const float x = static_cast<float>(i % 977) * 0.25f;
    const auto* b = reinterpret_cast<const std::uint8_t*>(&x);
    planes.insert(planes.end(), b, b + 4);
  }
  expect_round_trip(planes, "float plane");
}

TEST(Lzf, CompressesWhatRepeats) {
  const std::vector<std::uint8_t> zeros(100000, 0);
  // A back reference of 3 bytes copies at most 264: about 1.1% of the input.
  EXPECT_LT(compress(zeros).size(), zeros.size() / 80);
  const std::vector<std::uint8_t> noise = random_bytes(100000, 5);
  EXPECT_LE(compress(noise).size(), noise.size() + noise.size() / 32 + 1);
}

TEST(Lzf, RefusesAnOutputThatDoesNotFit) {
  const std::vector<std::uint8_t> noise = random_bytes(4096, 9);
  std::vector<std::uint8_t> out(noise.size());  // incompressible: needs a control byte more
  EXPECT_EQ(lzf_compress(noise.data(), noise.size(), out.data(), out.size()), 0u);
  const std::vector<std::uint8_t> zeros(4096, 0);
  std::vector<std::uint8_t> tiny(8);
  EXPECT_EQ(lzf_compress(zeros.data(), zeros.size(), tiny.data(), tiny.size()), 0u);
}

TEST(Lzf, DecoderRejectsWhatDoesNotFillTheOutputExactly) {
  const std::vector<std::uint8_t> in = random_bytes(500, 1);
  const std::vector<std::uint8_t> packed = compress(in);
  std::vector<std::uint8_t> back(in.size() + 1);
  EXPECT_FALSE(lzf_decompress(packed.data(), packed.size(), back.data(), back.size()));
  EXPECT_FALSE(lzf_decompress(packed.data(), packed.size() - 1, back.data(), in.size()));
}

}  // namespace
}  // namespace nurbsreg::io::detail

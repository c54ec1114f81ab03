// FrameVector / LargeBufferAllocator: small arrays come from operator new, large ones from their
// own 2 MiB-aligned mapping; contents survive growth, copies and moves either way.
#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>

#include "nurbsreg/engine/large_buffer.hpp"
#include "nurbsreg/engine/types.hpp"

namespace nurbsreg::engine {
namespace {

TEST(LargeBuffer, LargeArraysAreHugePageAlignedAndKeepTheirContents) {
  FrameVector<double> v(3'000'000);  // 24 MB: its own mapping
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(v.data()) % (std::size_t{2} << 20), 0u);
  std::iota(v.begin(), v.end(), 0.0);
  v.resize(5'000'000, -1.0);  // grows into a new mapping
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(v.data()) % (std::size_t{2} << 20), 0u);
  for (std::size_t i = 0; i < 3'000'000; i += 99'991)
    ASSERT_EQ(v[i], static_cast<double>(i));
  EXPECT_EQ(v.back(), -1.0);
  const FrameVector<double> copy = v;
  EXPECT_EQ(copy, v);
  FrameVector<double> moved = std::move(v);
  EXPECT_EQ(moved, copy);
}

TEST(LargeBuffer, SmallArraysWorkAsUsual) {
  FrameVector<Vec3> v;
  for (int i = 0; i < 1000; ++i)
    v.emplace_back(i, 2 * i, 3 * i);
  EXPECT_EQ(reinterpret_cast<std::uintptr_t>(v.data()) % alignof(Vec3), 0u);
  EXPECT_EQ(v[999], Vec3(999, 1998, 2997));
  v.clear();
  v.shrink_to_fit();
  EXPECT_TRUE(v.empty());
}

}  // namespace
}  // namespace nurbsreg::engine

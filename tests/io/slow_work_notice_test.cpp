// io's notice for work that can take seconds (a STEP conversion, a model's features): its line
// comes once the work has run for the given time, never for quicker work (whose failure must
// stay the only line a malformed file gives).
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "../../io/src/slow_work_notice.hpp"
#include "support/log_capture.hpp"

namespace nurbsreg::io::detail {
namespace {

using namespace std::chrono_literals;

TEST(SlowWorkNotice, SpeaksOnlyWhenTheWorkOutlastsItsTime) {
  const auto slow = test::log_lines_of(spdlog::level::info, [] {
    const SlowWorkNotice notice("converting part.step", 20ms);
    std::this_thread::sleep_for(300ms);
  });
  ASSERT_EQ(slow.size(), 1u);
  EXPECT_EQ(slow.front(), "converting part.step");
  const auto quick = test::log_lines_of(spdlog::level::info, [] {
    const SlowWorkNotice notice("converting part.step", 10s);
  });
  EXPECT_TRUE(quick.empty());
}

// Work that throws: the notice ends with it (no line when quick, no hang).
TEST(SlowWorkNotice, EndsWithWorkThatThrows) {
  const auto lines = test::log_lines_of(spdlog::level::info, [] {
    try {
      const SlowWorkNotice notice("converting broken.step", 10s);
      throw std::runtime_error("broken");
    } catch (const std::runtime_error&) {
    }
  });
  EXPECT_TRUE(lines.empty());
}

}  // namespace
}  // namespace nurbsreg::io::detail

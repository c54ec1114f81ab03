// Corrupted model files: truncated or with flipped bytes, every reader must either accept the
// file or throw InputError naming it -- never another exception type, a crash or a hang. The
// CLI relies on this to map every bad input to exit status 3 with a one-line message.
#include <gtest/gtest.h>

#include <functional>
#include <random>

#include "nurbsreg/engine/shapes.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "nurbsreg/io/pose.hpp"

namespace nurbsreg::io {
namespace {

using Parser = std::function<void(const std::string&)>;

// Parses `mutations` corrupted copies of `original`; returns how many were rejected.
int run_mutations(const std::string& original, const Parser& parse, std::uint64_t seed,
                  int mutations) {
  std::mt19937_64 rng(seed);
  // Bytes that matter to the grammars (delimiters, signs, digits, letters) plus arbitrary ones.
  const std::string interesting = "(),;'#.=-+eEHD0123456789 \n/*[]{}\":$";
  int rejected = 0;
  for (int m = 0; m < mutations; ++m) {
    std::string text = original;
    switch (m % 3) {
      case 0:  // truncate
        text.resize(rng() % text.size());
        break;
      case 1:  // overwrite a few bytes
        for (int k = 0; k < 4; ++k)
          text[rng() % text.size()] = interesting[rng() % interesting.size()];
        break;
      default:  // delete a span
        text.erase(rng() % text.size(), 1 + rng() % 40);
        break;
    }
    try {
      parse(text);
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), "corrupt") << e.what();
      ++rejected;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "mutation " << m << ": " << typeid(e).name() << ": " << e.what();
    }
  }
  return rejected;
}

TEST(CorruptedModels, JsonNeverFailsOtherwiseThanInputError) {
  engine::Model model;
  model.surfaces.push_back(engine::make_torus(engine::Vec3(0, 0, 0), 3, 1));
  model.curves.push_back(engine::make_circle(engine::Vec3(0, 0, 1), 2));
  const std::string text = model_to_json(model);
  const int rejected = run_mutations(
      text, [](const std::string& t) { parse_model(t, "corrupt"); }, 3, 600);
  EXPECT_GT(rejected, 300);
}

TEST(CorruptedModels, PoseNeverFailsOtherwiseThanInputError) {
  const std::string text = "0.36 0.48 -0.8 1\n-0.8 0.6 0 2\n0.48 0.64 0.6 3\n0 0 0 1\n";
  ASSERT_NO_THROW(parse_pose(text, "corrupt"));
  run_mutations(
      text, [](const std::string& t) { parse_pose(t, "corrupt"); }, 4, 600);
}

}  // namespace
}  // namespace nurbsreg::io

// The fuzz_request harness's checks (tests/fuzz/request_checks.hpp) over its committed corpus,
// in the normal suite: every seed and every input a fuzzer found stays a regression test (a
// failed check aborts the test binary, naming what went wrong). Plus the body decoders'
// behaviour on the malformed bodies of the corpus, stated explicitly.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "fuzz/request_checks.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/point_cloud_memory.hpp"
#include "support/run_command.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::fuzz::request {
namespace {

namespace fs = std::filesystem;

const fs::path kCorpus = fs::path(nurbsreg::test::examples_dir()).parent_path() / "tests" / "fuzz" /
                         "corpus" / "fuzz_request";

TEST(RequestCorpus, EverySeedPassesTheHarnessChecks) {
  std::size_t files = 0;
  for (const auto& entry : fs::directory_iterator(kCorpus)) {
    SCOPED_TRACE(entry.path().string());
    check_request(test::read_text(entry.path()));
    ++files;
  }
  EXPECT_GE(files, 10u) << kCorpus;
}

std::string body_error(const std::string& body, io::CloudEncoding encoding) {
  try {
    io::parse_point_cloud(body, encoding, "request body");
  } catch (const io::InputError& e) {
    return e.what();
  }
  return "";
}

TEST(RequestCorpus, MalformedBodiesAreNamedErrors) {
  // A float32 body that is not whole points (16 bytes).
  const std::string partial(16, '\0');
  EXPECT_EQ(body_error(partial, io::CloudEncoding::float32_xyz).rfind("request body: ", 0), 0u);
  // The PCD header whose COUNT wraps the row size (a fuzz finding as a file) as a body.
  const std::string wrap = test::read_text(kCorpus / "project_pcd_count_wrap");
  const std::string pcd = wrap.substr(wrap.find("\n\n") + 2);
  const std::string error = body_error(pcd, io::CloudEncoding::pcd);
  EXPECT_NE(error.find("makes the row size overflow"), std::string::npos) << error;
}

}  // namespace
}  // namespace nurbsreg::fuzz::request

// The model-features cache from the command line: the second `align` from any pose of the same
// model reads the features from the cache (the -v log says so) and gives the same output to the
// bit; --no-cache builds them and gives it too; a corrupt entry is rebuilt with a warning naming
// it; `batch` shares the cache.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "nurbsreg/io/alignment_report.hpp"
#include "support/run_command.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::test {
namespace {

namespace fs = std::filesystem;

const std::string kPanel = nurbsreg::test::examples_dir() + "/panel.json";

// The features cache's entries in `dir`.
std::vector<fs::path> feature_entries(const fs::path& dir) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.path().extension() == ".nrbfeat") out.push_back(e.path());
  return out;
}

// stdout without the coarse stage's wall time (the one number that differs between runs).
std::string untimed(const std::string& out) {
  return std::regex_replace(out, std::regex(R"(\) in [0-9.]+ s;)"), ") in - s;");
}

class CliFeaturesCache : public ::testing::Test {
 protected:
  void SetUp() override {
    scan_ = dir_ / "far.pcd";
    const CommandResult r = run_nurbsreg("synth --model " + kPanel +
                                             " --points 3000 --seed 5 --noise 0.01 --pose \"150 "
                                             "-60 20 1000 0 0\" --out " +
                                             scan_,
                                         dir_.path());
    ASSERT_EQ(r.status, 0) << r.err;
  }
  // `nurbsreg -v <args>` with the cache in dir_/cache (the tests' own cache directory is set
  // for every test: this one replaces it).
  CommandResult sh(const std::string& prefix, const std::string& args) const {
    const std::string out = dir_ / "out.txt", err = dir_ / "err.txt";
    const int status = std::system((prefix + "NURBSREG_CACHE_DIR=" + (dir_ / "cache") + " " +
                                    nurbsreg_binary() + " -v " + args + " >" + out + " 2>" + err)
                                       .c_str());
    return CommandResult{WEXITSTATUS(status), read_text(out), read_text(err)};
  }
  CommandResult align(const std::string& name, const std::string& prefix = "",
                      const std::string& flags = "") const {
    return sh(prefix, flags + "align --threads 2 --model " + kPanel + " --scan " + scan_ +
                          " --out-pose " + (dir_ / (name + ".pose.txt")) + " --report " +
                          (dir_ / (name + ".report.json")));
  }
  std::string pose(const std::string& name) const { return read_text(dir_ / (name + ".pose.txt")); }

  ScratchDir dir_{"features_cache"};
  std::string scan_;
};

TEST_F(CliFeaturesCache, SecondAlignReadsTheFeaturesAndGivesTheSameOutput) {
  const CommandResult first = align("first");
  ASSERT_EQ(first.status, 0) << first.err;
  EXPECT_NE(first.err.find("model features: built"), std::string::npos) << first.err;
  EXPECT_NE(first.err.find("(miss)"), std::string::npos) << first.err;
  // Said at the default level too when done (and while building, past a second: not the
  // panel's), with the coarse stage's outcome.
  EXPECT_NE(first.err.find("info model features: built in "), std::string::npos) << first.err;
  EXPECT_NE(first.err.find("info coarse alignment: a pose in "), std::string::npos) << first.err;
  ASSERT_EQ(feature_entries(dir_ / "cache").size(), 1u);

  const CommandResult second = align("second");
  ASSERT_EQ(second.status, 0) << second.err;
  EXPECT_NE(second.err.find("model features: read from the cache (hit"), std::string::npos)
      << second.err;
  EXPECT_EQ(second.err.find("model features: built"), std::string::npos) << second.err;
  EXPECT_EQ(second.err.find("model features: built"), std::string::npos) << second.err;
  EXPECT_NE(second.err.find("info coarse alignment: a pose in "), std::string::npos) << second.err;
  EXPECT_EQ(pose("second"), pose("first"));  // shortest round-trip numbers: the same bits
  EXPECT_EQ(untimed(second.out), untimed(first.out));
  const io::AlignmentReport a = io::read_alignment_report(dir_ / "first.report.json");
  const io::AlignmentReport b = io::read_alignment_report(dir_ / "second.report.json");
  EXPECT_EQ(a.pose, b.pose);
  EXPECT_EQ(a.rms, b.rms);
  EXPECT_EQ(a.inliers, b.inliers);

  // Without the cache: built, nothing read, the same pose.
  const CommandResult off = align("off", "", "--no-cache ");
  ASSERT_EQ(off.status, 0) << off.err;
  EXPECT_EQ(off.err.find("read from the cache"), std::string::npos) << off.err;
  EXPECT_EQ(pose("off"), pose("first"));
  const CommandResult env_off = align("env_off", "NURBSREG_NO_CACHE=1 ");
  ASSERT_EQ(env_off.status, 0) << env_off.err;
  EXPECT_EQ(env_off.err.find("read from the cache"), std::string::npos) << env_off.err;

  // A corrupt entry: rebuilt with a warning naming it, the same pose, then a hit again.
  const fs::path entry = feature_entries(dir_ / "cache").front();
  {
    std::fstream f(entry, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(static_cast<std::streamoff>(fs::file_size(entry) / 2));
    f.put('\x7f');
  }
  const CommandResult rebuilt = align("rebuilt");
  ASSERT_EQ(rebuilt.status, 0) << rebuilt.err;
  EXPECT_NE(rebuilt.err.find("warning"), std::string::npos) << rebuilt.err;
  EXPECT_NE(rebuilt.err.find(entry.string()), std::string::npos) << rebuilt.err;
  EXPECT_NE(rebuilt.err.find("(rebuilt)"), std::string::npos) << rebuilt.err;
  EXPECT_EQ(pose("rebuilt"), pose("first"));
  EXPECT_NE(align("again").err.find("(hit"), std::string::npos);
}

// From a pose (--init, --no-global) only the area and keypoints are needed: read from a full
// entry when one is there, else from an entry of those two alone, which the first such run
// stores; the alignment and its verdict are the same every way.
TEST_F(CliFeaturesCache, AlignFromAPoseStoresOnlyTheAreaAndKeypoints) {
  std::ofstream(dir_ / "identity.txt") << "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
  const std::string near = dir_ / "near.pcd";  // in place: ICP from the identity converges
  ASSERT_EQ(run_nurbsreg("synth --model " + kPanel + " --points 2000 --noise 0.01 --out " + near,
                         dir_.path())
                .status,
            0);
  const auto from_pose = [&](const std::string& how, const std::string& name) {
    const CommandResult r =
        sh("", "align " + how + " --model " + kPanel + " --scan " + near + " --report " +
                   (dir_ / (name + ".json")) + " --out-pose " + (dir_ / (name + ".pose.txt")));
    EXPECT_EQ(r.status, 0) << how << ": " << r.err;
    EXPECT_NE(r.err.find("icp stage 0 iteration 0"), std::string::npos) << how << ": " << r.err;
    return r.err;
  };
  const auto samples_entries = [&] {
    std::vector<fs::path> out;
    for (const auto& e : fs::directory_iterator(dir_ / "cache"))
      if (e.path().extension() == ".nrbsamp") out.push_back(e.path());
    return out;
  };
  const std::string init = "--init " + (dir_ / "identity.txt");
  EXPECT_NE(from_pose("--no-global", "missed").find("the area and keypoints measured in"),
            std::string::npos);
  EXPECT_TRUE(feature_entries(dir_ / "cache").empty());
  ASSERT_EQ(samples_entries().size(), 1u);
  EXPECT_NE(from_pose(init, "samples").find("the area and keypoints read from the cache (hit"),
            std::string::npos);
  EXPECT_TRUE(feature_entries(dir_ / "cache").empty());
  // An alignment from any pose stores the full entry; from a pose it is read first.
  ASSERT_EQ(align("any").status, 0);
  ASSERT_EQ(feature_entries(dir_ / "cache").size(), 1u);
  EXPECT_NE(from_pose(init, "hit").find("model features: read from the cache (hit"),
            std::string::npos);
  EXPECT_EQ(pose("samples"), pose("missed"));
  EXPECT_EQ(pose("hit"), pose("missed"));
  const auto fit = [&](const std::string& name) {
    const std::string report = read_text(dir_ / (name + ".json"));
    return report.substr(report.find("\"fit_details\""));
  };
  EXPECT_EQ(fit("samples"), fit("missed"));
  EXPECT_EQ(fit("hit"), fit("missed"));
}

TEST_F(CliFeaturesCache, BatchSharesTheCacheWithAlign) {
  fs::create_directories(dir_.path() / "scans");
  fs::copy_file(scan_, dir_.path() / "scans" / "a.pcd");
  const CommandResult single = align("single");
  ASSERT_EQ(single.status, 0) << single.err;
  const CommandResult batch = sh("", "batch --threads 2 --model " + kPanel + " --scans " +
                                         (dir_ / "scans") + " --out " + (dir_ / "out"));
  ASSERT_EQ(batch.status, 0) << batch.err;
  EXPECT_NE(batch.err.find("model features: read from the cache (hit"), std::string::npos)
      << batch.err;
  EXPECT_EQ(read_text(dir_ / "out/a.pose.txt"), pose("single"));
}

// `inspect` from any pose reads the same entry (it built the features anew on every run
// before) and finds the pose `align` does; its progress lines come at the default level.
TEST_F(CliFeaturesCache, InspectSharesTheCacheWithAlign) {
  const CommandResult single = align("single");
  ASSERT_EQ(single.status, 0) << single.err;
  const CommandResult inspect = sh("", "inspect --threads 2 --tolerance 0.05 --model " + kPanel +
                                           " --scan " + scan_ + " --out-dir " + (dir_ / "report"));
  ASSERT_EQ(inspect.status, 0) << inspect.err;
  EXPECT_NE(inspect.err.find("model features: read from the cache (hit"), std::string::npos)
      << inspect.err;
  EXPECT_NE(inspect.err.find("info coarse alignment: a pose in "), std::string::npos)
      << inspect.err;
  EXPECT_EQ(feature_entries(dir_ / "cache").size(), 1u);
}

}  // namespace
}  // namespace nurbsreg::test

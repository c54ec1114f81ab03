// End-to-end tests of `nurbsreg inspect` on the real binary: statistics against an independent
// computation on two planar faces (one reversed: its outer side is -z), NaN points skipped and
// counted, 100 % inside, the band's edges, the contract's files, and bad input (exit 2/3, one
// line, nothing left in or beside the output folder).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numeric>
#include <sstream>
#include <vector>

#include "nurbsreg/io/point_cloud.hpp"
#include "support/run_command.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::test {
namespace {

namespace fs = std::filesystem;

// Two unit-weight bilinear faces in the plane z = 0: "top" over [0,10]^2 (outer side +z) and
// "under" over [20,30]x[0,10], reversed (outer side -z).
constexpr const char* kTwoFaces = R"({"nurbsreg_model": 1, "units": "mm", "surfaces": [
 {"name": "top", "degree": [1, 1], "knots_u": [0,0,1,1], "knots_v": [0,0,1,1],
  "control_points": [[[0,0,0],[0,10,0]], [[10,0,0],[10,10,0]]]},
 {"name": "under", "degree": [1, 1], "knots_u": [0,0,1,1], "knots_v": [0,0,1,1], "reversed": true,
  "control_points": [[[20,0,0],[20,10,0]], [[30,0,0],[30,10,0]]]}]})";

struct Case {
  std::string model, scan, pose;
  std::vector<double> top, under;  // expected signed deviations per face
};

// A scan with offsets z = f(k) over both faces and three NaN points.
Case write_case(const ScratchDir& dir, double amplitude) {
  Case c{dir / "two_faces.json", dir / "scan.xyz", dir / "identity.txt", {}, {}};
  std::ofstream(c.model) << kTwoFaces;
  std::ofstream(c.pose) << "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
  std::ofstream scan(c.scan);
  scan.precision(17);
  int k = 0;
  for (int i = 0; i < 12; ++i) {
    for (int j = 0; j < 12; ++j, ++k) {
      const double z = amplitude * (-1.0 + 2.0 * ((k * 7) % 23) / 22.0);
      const bool top = (i + j) % 3 != 0;
      scan << (top ? 0.4 : 20.4) + 0.8 * i << " " << 0.4 + 0.8 * j << " " << z << "\n";
      (top ? c.top : c.under).push_back(top ? z : -z);
      if (k % 50 == 7) scan << "nan nan nan\n";
    }
  }
  return c;
}

double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  const double rank = q * (v.size() - 1);
  const auto lo = static_cast<std::size_t>(rank);
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (rank - lo) * (v[hi] - v[lo]);
}

void expect_stats(const nlohmann::json& j, const std::vector<double>& d, double lower,
                  double upper) {
  ASSERT_EQ(j["points"].get<std::size_t>(), d.size());
  const double mean = std::accumulate(d.begin(), d.end(), 0.0) / d.size();
  double ss = 0;
  std::size_t inside = 0;
  for (double x : d) {
    ss += (x - mean) * (x - mean);
    inside += x >= lower && x <= upper;
  }
  EXPECT_NEAR(j["mean"].get<double>(), mean, 1e-12);
  EXPECT_NEAR(j["std"].get<double>(), std::sqrt(ss / (d.size() - 1)), 1e-12);
  EXPECT_NEAR(j["min"].get<double>(), *std::min_element(d.begin(), d.end()), 1e-12);
  EXPECT_NEAR(j["max"].get<double>(), *std::max_element(d.begin(), d.end()), 1e-12);
  EXPECT_NEAR(j["p5"].get<double>(), quantile(d, 0.05), 1e-12);
  EXPECT_NEAR(j["p95"].get<double>(), quantile(d, 0.95), 1e-12);
  EXPECT_EQ(j["inside"].get<std::size_t>(), inside);
  EXPECT_DOUBLE_EQ(j["inside_tolerance"].get<double>(), double(inside) / d.size());
}

nlohmann::json read_json(const std::string& path) {
  return nlohmann::json::parse(read_text(path));
}

TEST(InspectCli, StatisticsMatchAnIndependentComputation) {
  ScratchDir dir("inspect-cli-stats");
  const Case c = write_case(dir, 0.08);
  const std::string out = dir / "out";
  const CommandResult r =
      run_nurbsreg("-q inspect --model " + c.model + " --scan " + c.scan + " --pose " + c.pose +
                       " --tolerance 0.05 --out-dir " + out,
                   dir.path());
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* f :
       {"inspect.json", "inspect_faces.csv", "deviations.ply", "report.html", "deviations.png"})
    EXPECT_TRUE(fs::exists(fs::path(out) / f)) << f;
  const nlohmann::json j = read_json(out + "/inspect.json");
  std::vector<double> all = c.top;
  all.insert(all.end(), c.under.begin(), c.under.end());
  expect_stats(j, all, -0.05, 0.05);
  EXPECT_EQ(j["skipped_points"].get<int>(), 3);
  EXPECT_EQ(j["tolerance"]["lower"].get<double>(), -0.05);
  EXPECT_EQ(j["tolerance"]["upper"].get<double>(), 0.05);
  ASSERT_EQ(j["faces"].size(), 2u);
  EXPECT_EQ(j["faces"][0]["name"], "top");
  expect_stats(j["faces"][0], c.top, -0.05, 0.05);
  expect_stats(j["faces"][1], c.under, -0.05, 0.05);  // reversed: the signs flip
  for (const char* key : {"pose", "rms", "iterations", "converged", "inliers", "seconds"})
    EXPECT_TRUE(j.contains(key)) << key;

  const io::PointCloud ply = io::read_point_cloud(out + "/deviations.ply");
  EXPECT_EQ(ply.size(), all.size());
  // The page: offline (no external script, style or image) and carrying the same numbers.
  const std::string html = read_text(out + "/report.html");
  EXPECT_EQ(html.find("src=\"http"), std::string::npos);
  EXPECT_EQ(html.find("href=\"http"), std::string::npos);
  EXPECT_EQ(html.find("<script src"), std::string::npos);
  std::ostringstream inside;
  inside << "data-key=\"inside_tolerance\" data-value=\"" << j["inside_tolerance"].get<double>()
         << "\"";
  EXPECT_NE(html.find("data-key=\"inside_tolerance\""), std::string::npos);
  // The CSV: a row for all points and one per face.
  const std::string csv = read_text(out + "/inspect_faces.csv");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 4);
  EXPECT_NE(csv.find("\n1,under,"), std::string::npos);
}

TEST(InspectCli, EveryPointInsideShowsOneHundredPercent) {
  ScratchDir dir("inspect-cli-inside");
  const Case c = write_case(dir, 0.04);
  const std::string out = dir / "out";
  const CommandResult r =
      run_nurbsreg("-q inspect --model " + c.model + " --scan " + c.scan + " --pose " + c.pose +
                       " --tolerance 0.04 --out-dir " + out,
                   dir.path());
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json j = read_json(out + "/inspect.json");
  // Offsets reach +-0.04 exactly: the band's edges count as inside.
  EXPECT_EQ(j["inside_tolerance"].get<double>(), 1.0);
  EXPECT_EQ(j["verdict"], "pass");
  EXPECT_NE(read_text(out + "/report.html").find(">100.00 %<"), std::string::npos);
  EXPECT_NE(r.out.find("100.00 %"), std::string::npos);
}

TEST(InspectCli, AsymmetricBandEdges) {
  ScratchDir dir("inspect-cli-edges");
  const Case c = write_case(dir, 0.04);
  const std::string out = dir / "out";
  // Upper edge just below the largest offset: those points are above.
  const CommandResult r =
      run_nurbsreg("-q inspect --model " + c.model + " --scan " + c.scan + " --pose " + c.pose +
                       " --tolerance-upper 0.039999 --tolerance-lower -0.04 --out-dir " + out,
                   dir.path());
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json j = read_json(out + "/inspect.json");
  std::vector<double> all = c.top;
  all.insert(all.end(), c.under.begin(), c.under.end());
  const auto above = std::count_if(all.begin(), all.end(), [](double d) { return d > 0.039999; });
  EXPECT_GT(above, 0);
  EXPECT_EQ(j["above"].get<long>(), above);
  EXPECT_EQ(j["below"].get<long>(), 0);
  EXPECT_EQ(j["tolerance"]["upper"].get<double>(), 0.039999);
}

TEST(InspectCli, AlignsFirstWithoutAPose) {
  ScratchDir dir("inspect-cli-align");
  const std::string panel = nurbsreg::test::examples_dir() + "/panel.json";
  const std::string scan = dir / "scan.pcd";
  ASSERT_EQ(run_nurbsreg("-q synth --model " + panel +
                             " --points 3000 --noise 0.01 --pose \"0.01 -0.01 0.02 0.05 -0.03 "
                             "0.02\" --seed 5 --out " +
                             scan,
                         dir.path())
                .status,
            0);
  const std::string out = dir / "out";
  const CommandResult r = run_nurbsreg(
      "-q inspect --model " + panel + " --scan " + scan + " --tolerance 0.03 --out-dir " + out,
      dir.path());
  ASSERT_EQ(r.status, 0) << r.err;
  const nlohmann::json j = read_json(out + "/inspect.json");
  EXPECT_GT(j["iterations"].get<int>(), 0);
  EXPECT_TRUE(j["converged"].get<bool>());
  EXPECT_FALSE(j["pose_given"].get<bool>());
  EXPECT_LT(j["rms"].get<double>(), 0.02);
  EXPECT_GT(j["inside_tolerance"].get<double>(), 0.95);  // noise 0.01 against a band of 0.03
  EXPECT_EQ(j["fit"].get<std::string>(), "good");
  const std::string html = read_text(out + "/report.html");
  EXPECT_NE(html.find("<span data-key=\"fit\">good</span>"), std::string::npos);
  EXPECT_EQ(html.find("data-key=\"fit_warning\""), std::string::npos);
}

// A poor fit accepted with --accept-poor: the page says so above every number, not only the JSON.
TEST(InspectCli, AcceptedPoorFitIsShownOnThePage) {
  ScratchDir dir("inspect-cli-poor");
  const std::string panel = nurbsreg::test::examples_dir() + "/panel.json";
  const std::string scan = dir / "scan.pcd";
  ASSERT_EQ(run_nurbsreg("-q synth --model " + panel +
                             " --points 3000 --noise 0.01 --outliers 0.2 --seed 5 --out " + scan,
                         dir.path())
                .status,
            0);
  const std::string out = dir / "out";
  const std::string base = "-q inspect --model " + panel + " --scan " + scan +
                           " --tolerance 0.03 --min-inlier-fraction 0.95 --out-dir " + out;
  const CommandResult refused = run_nurbsreg(base, dir.path());
  EXPECT_EQ(refused.status, 1) << refused.err;
  EXPECT_FALSE(fs::exists(out));
  const CommandResult r = run_nurbsreg(base + " --accept-poor", dir.path());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(read_json(out + "/inspect.json")["fit"].get<std::string>(), "poor");
  const std::string html = read_text(out + "/report.html");
  EXPECT_NE(html.find("data-key=\"fit_warning\""), std::string::npos);
  EXPECT_NE(html.find("<span data-key=\"fit\">poor</span>"), std::string::npos);
}

void expect_clean_failure(const ScratchDir& dir, const std::string& args, int status,
                          const std::string& needle) {
  const std::string out = dir / "out";
  const CommandResult r = run_nurbsreg("inspect " + args + " --out-dir " + out, dir.path());
  EXPECT_EQ(r.status, status) << args << "\n" << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'),
            r.status == 2 && r.err.find("--help") != std::string::npos ? 2 : 1)
      << r.err;
  EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(out)) << args;
  for (const auto& e : fs::directory_iterator(dir.path()))
    EXPECT_EQ(e.path().filename().string().find(".out.inspect"), std::string::npos)
        << "staging left: " << e.path();
}

// Clutter (points far off the part, like a fixture) decides the verdict unless it is excluded:
// without --exclude-beyond the run says so and names the option; with it the far points are
// left out of every statistic and of the PLY, and counted in the JSON, the page and stdout.
TEST(InspectCli, ClutterIsExcludedOnlyOnRequestAndCounted) {
  ScratchDir dir("inspect-cli-clutter");
  const Case c = write_case(dir, 0.04);
  {
    std::ofstream scan(c.scan, std::ios::app);
    for (int k = 0; k < 12; ++k)  // 8 above the top face, 4 below it: |d| 5 and 3
      scan << 0.5 + 0.7 * k << " 5.5 " << (k < 8 ? 5.0 : -3.0) << "\n";
  }
  std::vector<double> part = c.top;
  part.insert(part.end(), c.under.begin(), c.under.end());
  const std::string base = "inspect --model " + c.model + " --scan " + c.scan + " --pose " +
                           c.pose + " --tolerance 0.05 --out-dir ";

  const CommandResult plain = run_nurbsreg(base + (dir / "plain"), dir.path());
  ASSERT_EQ(plain.status, 0) << plain.err;
  EXPECT_NE(plain.out.find("FAIL"), std::string::npos) << plain.out;
  EXPECT_NE(plain.err.find("--exclude-beyond=0.5"), std::string::npos) << plain.err;
  const nlohmann::json p = read_json(dir / "plain/inspect.json");
  EXPECT_EQ(p["points"].get<std::size_t>(), part.size() + 12);
  EXPECT_EQ(p["excluded_points"].get<std::size_t>(), 0u);
  EXPECT_TRUE(p["exclude_beyond"].is_null());

  const CommandResult cut = run_nurbsreg(base + (dir / "cut") + " --exclude-beyond 1", dir.path());
  ASSERT_EQ(cut.status, 0) << cut.err;
  EXPECT_NE(cut.out.find("12 farther than 1 excluded): PASS"), std::string::npos) << cut.out;
  EXPECT_EQ(cut.err.find("--exclude-beyond="), std::string::npos) << cut.err;
  const nlohmann::json j = read_json(dir / "cut/inspect.json");
  expect_stats(j, part, -0.05, 0.05);
  EXPECT_EQ(j["excluded_points"].get<std::size_t>(), 12u);
  EXPECT_EQ(j["exclude_beyond"].get<double>(), 1.0);
  EXPECT_EQ(j["verdict"], "pass");
  EXPECT_EQ(io::read_point_cloud(dir / "cut/deviations.ply").size(), part.size());
  const std::string html = read_text(dir / "cut/report.html");
  EXPECT_NE(html.find("data-key=\"excluded_points\" data-value=\"12\""), std::string::npos);

  // Inside or at the band it would drop deviations, not clutter.
  const CommandResult bad =
      run_nurbsreg(base + (dir / "bad") + " --exclude-beyond 0.05", dir.path());
  EXPECT_EQ(bad.status, 2) << bad.err;
  EXPECT_NE(bad.err.find("--exclude-beyond"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(dir / "bad"));
}

TEST(InspectCli, BadInputFailsWithOneLineAndLeavesNothing) {
  ScratchDir dir("inspect-cli-bad");
  const Case c = write_case(dir, 0.04);
  const std::string base = "--model " + c.model + " --scan " + c.scan + " --pose " + c.pose;
  expect_clean_failure(dir, base + " --tolerance 0", 2, "--tolerance");
  expect_clean_failure(dir, base + " --tolerance -0.1", 2, "--tolerance");
  expect_clean_failure(dir, base + " --tolerance-lower 0.1 --tolerance-upper -0.1", 2, "lower");
  expect_clean_failure(dir, base + " --tolerance-lower 0.1 --tolerance-upper 0.1", 2, "lower");
  expect_clean_failure(dir, base, 2, "--tolerance");
  expect_clean_failure(dir, base + " --tolerance 0.1 --colour-max 0.05", 2, "--colour-max");
  expect_clean_failure(dir, base + " --tolerance 0.1 --init " + c.pose, 2, "--pose");
  expect_clean_failure(dir, base + " --tolerance 0.1 --colour-scale rainbow", 2, "--colour-scale");
  expect_clean_failure(dir,
                       "--model " + c.model + " --scan " + (dir / "missing.xyz") + " --pose " +
                           c.pose + " --tolerance 0.1",
                       3, "missing.xyz");
  std::ofstream(dir / "garbage.xyz") << "1 2\n";
  expect_clean_failure(dir,
                       "--model " + c.model + " --scan " + (dir / "garbage.xyz") + " --pose " +
                           c.pose + " --tolerance 0.1",
                       3, "garbage.xyz");

  // An output folder that cannot be made: its parent is a file.
  std::ofstream(dir / "plain_file") << "x";
  const CommandResult r = run_nurbsreg(
      "inspect " + base + " --tolerance 0.1 --out-dir " + (dir / "plain_file") + "/out",
      dir.path());
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("plain_file"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace nurbsreg::test

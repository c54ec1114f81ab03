// Files of `nurbsreg modify`: the targets CSV, nearest-scan targets (FLANN vs brute force) and
// the JSON report.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include <nlohmann/json.hpp>

#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/modify_io.hpp"
#include "support/random_entities.hpp"

namespace nurbsreg::io {
namespace {

namespace fs = std::filesystem;

class ModifyIo : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() /
        ("nurbsreg_modify_io_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
         "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
  }
  // The InputError message of reading `text` as a targets file.
  std::string error_of(const std::string& text) {
    try {
      read_modify_targets(write("bad.csv", text));
    } catch (const InputError& e) {
      return e.what();
    }
    return "no error";
  }
  fs::path dir_;
};

TEST_F(ModifyIo, ReadsTargetsByColumnName) {
  const auto t = read_modify_targets(
      write("t.csv", "# nose targets\nsegment,x,y,z\n0, 1.5, 2, 3\n\n2,4,5e1,-6\r\n"));
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0].segment, 0);
  EXPECT_EQ(t[0].point, engine::Vec3(1.5, 2, 3));
  EXPECT_EQ(t[1].segment, 2);
  EXPECT_EQ(t[1].point, engine::Vec3(4, 50, -6));
  // z optional, columns in any order, extra columns ignored.
  const auto u = read_modify_targets(write("u.csv", "y,label,x,segment\n7,a,8,3\n"));
  ASSERT_EQ(u.size(), 1u);
  EXPECT_EQ(u[0].segment, 3);
  EXPECT_EQ(u[0].point, engine::Vec3(8, 7, 0));
}

TEST_F(ModifyIo, RejectsMalformedTargets) {
  EXPECT_NE(error_of("").find("empty file"), std::string::npos);
  EXPECT_NE(error_of("seg,x,y\n0,1,2\n").find("line 1: expected the header"), std::string::npos);
  EXPECT_NE(error_of("segment,x,y\n").find("no target rows"), std::string::npos);
  EXPECT_NE(error_of("segment,x,y\n-1,1,2\n").find("line 2: segment"), std::string::npos);
  EXPECT_NE(error_of("segment,x,y\n0.5,1,2\n").find("line 2: segment"), std::string::npos);
  EXPECT_NE(error_of("segment,x,y\n0,nan,2\n").find("line 2: x"), std::string::npos);
  EXPECT_NE(error_of("segment,x,y\n0,1\n").find("line 2: expected 3 columns"), std::string::npos);
  EXPECT_NE(error_of("segment,x,y\n0,1,2\n0,3,4\n").find("line 3: segment 0 appears twice"),
            std::string::npos);
  EXPECT_NE(error_of("segment,x,y\n0,1,2\n").find("no error"), std::string::npos);
  try {
    read_modify_targets((dir_ / "missing.csv").string());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.csv: cannot open"), std::string::npos);
  }
}

TEST_F(ModifyIo, NearestScanTargetsMatchBruteForce) {
  std::mt19937_64 rng(11);
  std::vector<engine::Vec3> scan;
  for (int i = 0; i < 5000; ++i) {
    scan.emplace_back(test::uniform(rng, -10, 10), test::uniform(rng, -10, 10),
                      test::uniform(rng, -1, 1));
  }
  scan.push_back(scan[17]);  // a duplicate: the lowest index must win
  const engine::NurbsCurve curve = test::random_curve(4, 2, 12, true);
  std::vector<engine::NosePoint> noses = engine::nose_points(curve);
  for (engine::NosePoint& n : noses)
    n.point *= 10.0;  // spread over the scan
  noses[0].point = scan[17];
  const auto targets = nearest_scan_targets(scan, noses, "scan.xyz");
  ASSERT_EQ(targets.size(), noses.size());
  for (std::size_t j = 0; j < noses.size(); ++j) {
    std::size_t best = 0;
    for (std::size_t i = 1; i < scan.size(); ++i) {
      if ((scan[i] - noses[j].point).squaredNorm() < (scan[best] - noses[j].point).squaredNorm()) {
        best = i;
      }
    }
    EXPECT_EQ(targets[j].segment, noses[j].segment);
    EXPECT_EQ(targets[j].point, scan[best]) << j;
  }
  EXPECT_THROW(nearest_scan_targets({}, noses, "empty.xyz"), InputError);
}

TEST_F(ModifyIo, ReportHoldsTheErrorTable) {
  engine::NurbsCurve c;
  c.name = "figure7";
  c.degree = 2;
  c.dimension = 2;
  c.knots = {0, 0, 0, 1, 1.855, 2.843, 3.287, 3.287, 3.287};
  c.control_points = {{124.39, 175.54, 0}, {167.68, 286.47, 0}, {281.62, 192.61, 0},
                      {407.82, 323.98, 0}, {454.80, 163.49, 0}, {362.84, 81.97, 0}};
  const auto noses = engine::nose_points(c);
  ModifyReport report;
  report.model_file = "m.json";
  report.curve_name = c.name;
  report.target_source = "t.csv";
  report.options.method = engine::ModifyMethod::points;
  report.targets = {{1, noses[1].point + engine::Vec3(3, 4, 0)}};
  report.result = engine::modify_curve(c, report.targets, report.options);
  const std::string path = (dir_ / "r.json").string();
  write_modify_report(path, report);
  std::ifstream in(path);
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["curve"], "figure7");
  EXPECT_EQ(j["method"], "points");
  ASSERT_EQ(j["steps"].size(), 2u);
  EXPECT_EQ(j["steps"][0]["operation"], "initial");
  EXPECT_NEAR(j["initial_errors"][1].get<double>(), 5.0, 1e-9);
  EXPECT_NEAR(j["initial_total"].get<double>(), 5.0, 1e-9);
  EXPECT_LT(j["final_total"].get<double>(), 1e-9);
  EXPECT_EQ(j["steps"][1]["weights"].size(), 6u);
}

}  // namespace
}  // namespace nurbsreg::io

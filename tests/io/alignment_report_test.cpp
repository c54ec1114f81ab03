// Alignment reports: the contract's fields as an independent JSON parser sees them, exact round
// trips including undefined (NaN) values, and errors naming the missing or mistyped field.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include <Eigen/Geometry>

#include "nurbsreg/io/alignment_report.hpp"
#include "nurbsreg/io/errors.hpp"

namespace nurbsreg::io {
namespace {

AlignmentReport sample_report() {
  AlignmentReport r;
  r.pose.topLeftCorner<3, 3>() =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  r.pose.topRightCorner<3, 1>() << 12.5, -0.001, 1.0 / 3.0;
  r.rms = 0.0123456789012345;
  r.iterations = 3;
  r.converged = true;
  r.inliers = 9876543210;  // beyond 32 bits
  r.points = 9876543299;
  r.skipped_points = 17;
  r.seconds = 1.25;
  r.method = "point-to-plane";
  r.termination = "converged: pose increment < 1e-06";
  for (int k = 0; k < 3; ++k) {
    r.history.push_back({k + 1, 1.0 / (k + 1), static_cast<std::size_t>(1000 - k), 0.1 / (k + 1),
                         2.0 / (k + 3), 0.01 * k});
  }
  return r;
}

TEST(AlignmentReport, HasTheContractFields) {
  const AlignmentReport r = sample_report();
  const nlohmann::json j = nlohmann::json::parse(report_to_json(r));
  ASSERT_TRUE(j.is_object());
  for (const char* key :
       {"pose", "rms", "iterations", "converged", "inliers", "points", "seconds"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  ASSERT_EQ(j["pose"].size(), 4u);
  for (int i = 0; i < 4; ++i) {
    ASSERT_EQ(j["pose"][i].size(), 4u);
    for (int k = 0; k < 4; ++k)
      EXPECT_EQ(j["pose"][i][k].get<double>(), r.pose(i, k));
  }
  EXPECT_EQ(j["pose"][0][3].get<double>(), 12.5);  // row-major: pose[row][column]
  EXPECT_EQ(j["rms"].get<double>(), r.rms);
  EXPECT_EQ(j["iterations"], 3);
  EXPECT_EQ(j["converged"], true);
  EXPECT_EQ(j["inliers"].get<std::size_t>(), 9876543210u);
  EXPECT_EQ(j["points"].get<std::size_t>(), 9876543299u);
  EXPECT_EQ(j["history"].size(), 3u);
  EXPECT_EQ(j["history"][2]["inliers"], 998);
}

TEST(AlignmentReport, WriteThenReadIsExact) {
  const AlignmentReport r = sample_report();
  const auto dir = std::filesystem::path(::testing::TempDir()) / "nurbsreg_io_report";
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "report.json").string();
  write_alignment_report(path, r);
  const AlignmentReport back = read_alignment_report(path);
  EXPECT_TRUE((back.pose.array() == r.pose.array()).all());
  EXPECT_EQ(back.rms, r.rms);
  EXPECT_EQ(back.iterations, r.iterations);
  EXPECT_EQ(back.converged, r.converged);
  EXPECT_EQ(back.inliers, r.inliers);
  EXPECT_EQ(back.points, r.points);
  EXPECT_EQ(back.skipped_points, r.skipped_points);
  EXPECT_EQ(back.seconds, r.seconds);
  EXPECT_EQ(back.method, r.method);
  EXPECT_EQ(back.termination, r.termination);
  ASSERT_EQ(back.history.size(), r.history.size());
  for (std::size_t k = 0; k < r.history.size(); ++k) {
    EXPECT_EQ(back.history[k].iteration, r.history[k].iteration);
    EXPECT_EQ(back.history[k].rms, r.history[k].rms);
    EXPECT_EQ(back.history[k].inliers, r.history[k].inliers);
    EXPECT_EQ(back.history[k].rotation_step, r.history[k].rotation_step);
    EXPECT_EQ(back.history[k].translation_step, r.history[k].translation_step);
    EXPECT_EQ(back.history[k].seconds, r.history[k].seconds);
  }
}

TEST(AlignmentReport, UndefinedValuesAreNull) {
  AlignmentReport r;
  r.rms = std::numeric_limits<double>::quiet_NaN();  // no inliers
  r.history.push_back({1, std::numeric_limits<double>::infinity(), 0, 0, 0, 0});
  const std::string text = report_to_json(r);
  const nlohmann::json j = nlohmann::json::parse(text);
  EXPECT_TRUE(j["rms"].is_null());
  EXPECT_TRUE(j["history"][0]["rms"].is_null());
  const AlignmentReport back = parse_alignment_report(text, "r.json");
  EXPECT_TRUE(std::isnan(back.rms));
  EXPECT_TRUE(std::isnan(back.history[0].rms));
}

std::string parse_error(const std::string& text) {
  try {
    parse_alignment_report(text, "r.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(AlignmentReport, ErrorsNameTheField) {
  nlohmann::json j = nlohmann::json::parse(report_to_json(sample_report()));
  auto without = [&](const char* key) {
    nlohmann::json copy = j;
    copy.erase(key);
    return copy.dump();
  };
  EXPECT_NE(parse_error(without("converged")).find("r.json: converged: missing"),
            std::string::npos);
  EXPECT_NE(parse_error(without("pose")).find("r.json: pose: missing"), std::string::npos);
  nlohmann::json bad = j;
  bad["pose"][2] = {1, 2, 3};
  EXPECT_NE(parse_error(bad.dump()).find("pose[2]: expected 4 numbers"), std::string::npos);
  bad = j;
  bad["inliers"] = -3;
  EXPECT_NE(parse_error(bad.dump()).find("inliers: expected a non-negative integer"),
            std::string::npos);
  bad = j;
  bad["history"][1].erase("rms");
  EXPECT_NE(parse_error(bad.dump()).find("history[1].rms: missing"), std::string::npos);
  EXPECT_NE(parse_error("{\"pose\": [1,\n 2,]}").find("line 2, column 4: invalid JSON"),
            std::string::npos);
  EXPECT_NE(parse_error("[]").find("expected a JSON object"), std::string::npos);
  // A value quoted in the message keeps to one printable line, shortened (JSON escapes control
  // characters only: DEL and UTF-8 letters are shown as \xHH).
  bad = j;
  bad["converged"] = std::string("\x7f\xc3\xa9") + std::string(100, 'a');
  const std::string shown = parse_error(bad.dump());
  EXPECT_NE(shown.find("converged: expected true or false, got '\"\\x7f\\xc3\\xa9aaa"),
            std::string::npos)
      << shown;
  EXPECT_LT(shown.size(), 120u) << shown;
}

}  // namespace
}  // namespace nurbsreg::io

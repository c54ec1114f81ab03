// Pose files: exact round trips, real ground truth from the Stanford bunny (bun.conf) checked
// against a textbook quaternion-to-matrix formula, the rigidity checks, and line-numbered errors.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <Eigen/Geometry>

#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/pose.hpp"
#include "support/random_entities.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::io {
namespace {

std::filesystem::path temp_dir() {
  const auto dir = std::filesystem::path(::testing::TempDir()) / "nurbsreg_io_pose";
  std::filesystem::create_directories(dir);
  return dir;
}

std::string parse_error(const std::string& text) {
  try {
    parse_pose(text, "T.txt");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

Eigen::Matrix4d random_pose(std::mt19937_64& rng) {
  Eigen::Quaterniond q(test::uniform(rng, -1, 1), test::uniform(rng, -1, 1),
                       test::uniform(rng, -1, 1), test::uniform(rng, -1, 1));
  q.normalize();
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = q.toRotationMatrix();
  T.topRightCorner<3, 1>() = Eigen::Vector3d(
      test::uniform(rng, -1e3, 1e3), test::uniform(rng, -1e-3, 1e-3), test::uniform(rng, -1, 1));
  return T;
}

double orthogonality(const Eigen::Matrix4d& T) {
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  return (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
}

TEST(Pose, WriteThenReadIsBitExact) {
  std::mt19937_64 rng(5);
  const std::string path = (temp_dir() / "pose.txt").string();
  for (int k = 0; k < 200; ++k) {
    const Eigen::Matrix4d T = random_pose(rng);
    ASSERT_LT(orthogonality(T), 1e-12);
    write_pose(path, T);
    const Eigen::Matrix4d back = read_pose(path);
    ASSERT_TRUE((back.array() == T.array()).all()) << "pose " << k << "\n" << T << "\n" << back;
  }
}

// Stanford bunny ground truth (bun.conf: `bmesh bun045.ply tx ty tz qi qj qk qr`), written the
// way other tools print poses (6 decimals). The rotation comes from the unit-quaternion formula
// (Shoemake 1985), independent of Eigen's Quaternion.
TEST(Pose, ReadsRoundedRealGroundTruthAsAnExactRotation) {
  const std::string conf =
      nurbsreg::test::shared_dir() + "/data/real/stanford-bunny-scans/bun.conf";
  std::ifstream in(conf);
  ASSERT_TRUE(in) << "missing shared data: " << conf;
  std::string line;
  double t[3] = {0, 0, 0};
  double qi = 0, qj = 0, qk = 0, qr = 1;
  bool found = false;
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::string kind, file;
    fields >> kind >> file;
    if (kind == "bmesh" && file == "bun045.ply") {
      fields >> t[0] >> t[1] >> t[2] >> qi >> qj >> qk >> qr;
      found = true;
    }
  }
  ASSERT_TRUE(found);
  const double n = std::sqrt(qi * qi + qj * qj + qk * qk + qr * qr);
  qi /= n, qj /= n, qk /= n, qr /= n;
  Eigen::Matrix4d expected = Eigen::Matrix4d::Identity();
  expected.topLeftCorner<3, 3>() << 1 - 2 * (qj * qj + qk * qk), 2 * (qi * qj - qk * qr),
      2 * (qi * qk + qj * qr), 2 * (qi * qj + qk * qr), 1 - 2 * (qi * qi + qk * qk),
      2 * (qj * qk - qi * qr), 2 * (qi * qk - qj * qr), 2 * (qj * qk + qi * qr),
      1 - 2 * (qi * qi + qj * qj);
  expected.topRightCorner<3, 1>() << t[0], t[1], t[2];

  char text[512];
  std::snprintf(text, sizeof(text),
                "# bun045 -> common frame\n%.6f %.6f %.6f %.6f\r\n%.6f,%.6f,%.6f,%.6f\n\n"
                "%.6f %.6f %.6f %.6f  # third row\n0 0 0 1\n",
                expected(0, 0), expected(0, 1), expected(0, 2), expected(0, 3), expected(1, 0),
                expected(1, 1), expected(1, 2), expected(1, 3), expected(2, 0), expected(2, 1),
                expected(2, 2), expected(2, 3));
  const Eigen::Matrix4d T = parse_pose(text, "bun045.txt");
  EXPECT_LE(orthogonality(T), 2 * std::numeric_limits<double>::epsilon());
  EXPECT_NEAR((T.topLeftCorner<3, 3>().determinant()), 1.0, 1e-15);
  EXPECT_LT((T - expected).cwiseAbs().maxCoeff(), 1.5e-6);
  // About 34 degrees about -y, as the README says.
  const double angle = std::acos((T.topLeftCorner<3, 3>().trace() - 1) / 2) * 180 / M_PI;
  EXPECT_NEAR(angle, 34.3, 0.5);
}

TEST(Pose, RoundedInputIsProjectedToTheNearestRotation) {
  std::mt19937_64 rng(9);
  for (int k = 0; k < 50; ++k) {
    const Eigen::Matrix4d T = random_pose(rng);
    Eigen::Matrix4d rounded = T;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j)
        rounded(i, j) = std::round(T(i, j) * 1e5) / 1e5;
    }
    ASSERT_GT(orthogonality(rounded), 1e-12);  // the projection path is exercised
    const Eigen::Matrix4d back = parse_pose(pose_to_text(rounded), "T.txt");
    EXPECT_LE(orthogonality(back), 2 * std::numeric_limits<double>::epsilon());
    EXPECT_LT((back - T).cwiseAbs().maxCoeff(), 2e-5);
    // Nearest rotation: no other rotation (here the original) is closer to the input.
    EXPECT_LE((back - rounded).norm(), (T - rounded).norm() + 1e-15);
    EXPECT_TRUE((back.col(3).array() == rounded.col(3).array()).all());
  }
}

struct ErrorCase {
  const char* what;
  std::string text;
  const char* expected;
};

class PoseErrors : public ::testing::TestWithParam<ErrorCase> {};

TEST_P(PoseErrors, NameTheFileAndLine) {
  const std::string message = parse_error(GetParam().text);
  ASSERT_FALSE(message.empty()) << GetParam().what << ": accepted";
  EXPECT_EQ(message.rfind("T.txt: ", 0), 0u) << message;
  EXPECT_NE(message.find(GetParam().expected), std::string::npos) << message;
}

const std::string kRow2 = "0 1 0 0\n";
const std::string kRow3 = "0 0 1 0\n";
const std::string kRow4 = "0 0 0 1\n";

INSTANTIATE_TEST_SUITE_P(
    Table, PoseErrors,
    ::testing::Values(ErrorCase{"short row", "1 0 0\n" + kRow2 + kRow3 + kRow4,
                                "line 1: expected 4 numbers, got 3"},
                      ErrorCase{"long row", "1 0 0 0\n# c\n0 1 0 0 7\n" + kRow3 + kRow4,
                                "line 3: expected 4 numbers, got more"},
                      ErrorCase{"word", "1 0 0 0\n" + kRow2 + "0 0 one 0\n" + kRow4,
                                "line 3: 'one' is not a finite number"},
                      ErrorCase{"nan", "1 0 0 nan\n" + kRow2 + kRow3 + kRow4,
                                "line 1: 'nan' is not a finite number"},
                      ErrorCase{
                          "three rows", "1 0 0 0\n" + kRow2 + kRow3,
                          "expected 4 lines of 4 numbers (a 4x4 rigid transform), got 3 lines"},
                      ErrorCase{"empty", "", "got 0 lines"},
                      ErrorCase{"fifth row", "1 0 0 0\n" + kRow2 + kRow3 + kRow4 + "0 0 0 1\n",
                                "line 5: unexpected extra data"},
                      ErrorCase{"projective", "1 0 0 0\n" + kRow2 + kRow3 + "0 0 0.5 1\n",
                                "last row must be 0 0 0 1"},
                      ErrorCase{"scale", "2 0 0 0\n" + kRow2 + kRow3 + kRow4,
                                "rotation block is not orthonormal (max |R^T R - I| = 3)"},
                      ErrorCase{"shear", "1 0.1 0 0\n" + kRow2 + kRow3 + kRow4, "not orthonormal"},
                      ErrorCase{"reflection", "-1 0 0 0\n" + kRow2 + kRow3 + kRow4,
                                "determinant -1 (a reflection)"}),
    [](const ::testing::TestParamInfo<ErrorCase>& info) {
      std::string name = info.param.what;
      for (char& ch : name) {
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
      }
      return name;
    });

TEST(Pose, WriteRefusesNonFiniteEntriesAndLeavesNoFile) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T(1, 3) = std::numeric_limits<double>::infinity();
  const auto path = temp_dir() / "bad_pose.txt";
  std::filesystem::remove(path);
  EXPECT_THROW(write_pose(path.string(), T), OutputError);
  EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(Pose, MissingFileIsAnInputError) {
  EXPECT_THROW(read_pose((temp_dir() / "none.txt").string()), InputError);
}

}  // namespace
}  // namespace nurbsreg::io

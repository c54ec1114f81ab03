// End-to-end: the real `nurbsreg modify` binary on the curve of seed paper 004's Figure 7.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "nurbsreg/engine/curve_modification.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg {
namespace {

namespace fs = std::filesystem;

struct RunResult {
  int status = -1;
  std::string err;
};

class ModifyCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("nurbsreg_modify_cli_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // The paper's curve (degree 2, six control points, four segments) and a second curve that
    // must come out untouched.
    write("model.json", R"({"nurbsreg_model": 1, "units": "mm", "curves": [
      {"name": "other", "degree": 1, "knots": [0, 0, 1, 1], "control_points": [[0, 0], [1, 1]]},
      {"name": "profile", "degree": 2, "knots": [0, 0, 0, 1, 1.855, 2.843, 3.287, 3.287, 3.287],
       "control_points": [[124.39, 175.54], [167.68, 286.47], [281.62, 192.61],
                          [407.82, 323.98], [454.80, 163.49], [362.84, 81.97]],
       "weights": [1, 1, 1, 1, 1, 1]}]})");
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  void write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name, std::ios::binary) << text;
  }
  RunResult run(const std::string& arguments) {
    const std::string err = path("stderr.txt");
    const std::string command = nurbsreg::test::nurbsreg_binary() + " modify " + arguments + " > " +
                                path("stdout.txt") + " 2> " + err;
    const int raw = std::system(command.c_str());
    RunResult r;
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
    std::ifstream in(err);
    std::stringstream s;
    s << in.rdbuf();
    r.err = s.str();
    return r;
  }
  std::string base() const {
    return "--model " + path("model.json") + " --curve profile --out " + path("out.json");
  }
  static const engine::NurbsCurve& curve_named(const engine::Model& m, const std::string& name) {
    for (const engine::NurbsCurve& c : m.curves) {
      if (c.name == name) return c;
    }
    throw std::runtime_error("no curve " + name);
  }

  fs::path dir_;
};

TEST_F(ModifyCommand, ControlPointsPutEveryNoseOnItsTarget) {
  const engine::Model before = io::read_model_json(path("model.json"));
  const std::vector<engine::NosePoint> noses = engine::nose_points(curve_named(before, "profile"));
  std::string csv = "segment,x,y\n";
  std::vector<engine::Vec3> targets;
  for (const engine::NosePoint& n : noses) {
    targets.push_back(n.point + engine::Vec3(3.0 - n.segment, 2.0 + n.segment, 0.0));
    csv += std::to_string(n.segment) + "," + std::to_string(targets.back().x()) + "," +
           std::to_string(targets.back().y()) + "\n";
  }
  write("t.csv", csv);
  // std::to_string rounds to 6 decimals: compare against what the file says.
  targets.clear();
  std::istringstream rows(csv);
  std::string line;
  std::getline(rows, line);
  while (std::getline(rows, line)) {
    double s, x, y;
    char c;
    std::istringstream(line) >> s >> c >> x >> c >> y;
    targets.emplace_back(x, y, 0.0);
  }
  const RunResult r = run(base() + " --targets " + path("t.csv") + " --report " + path("r.json"));
  ASSERT_EQ(r.status, 0) << r.err;
  const engine::Model after = io::read_model_json(path("out.json"));
  const engine::NurbsCurve& modified = curve_named(after, "profile");
  for (std::size_t j = 0; j < noses.size(); ++j) {
    EXPECT_LT((modified.evaluate(noses[j].u) - targets[j]).norm(), 1e-9) << j;
  }
  EXPECT_EQ(curve_named(after, "other").control_points,
            curve_named(before, "other").control_points);
  std::ifstream in(path("r.json"));
  const nlohmann::json report = nlohmann::json::parse(in);
  EXPECT_EQ(report["method"], "points");
  EXPECT_GT(report["initial_total"].get<double>(), 10.0);
  EXPECT_LT(report["final_total"].get<double>(), 1e-9);
}

TEST_F(ModifyCommand, ScanTargetsWithTheIteratedRecipe) {
  const engine::Model before = io::read_model_json(path("model.json"));
  const engine::NurbsCurve& curve = curve_named(before, "profile");
  // A "scan" of the built part: the curve pushed outwards by 2 mm along its normal, sampled.
  std::string xyz = "# x y z\n";
  std::vector<engine::Vec3> scan;
  for (int k = 0; k <= 400; ++k) {
    const double u = 3.287 * k / 400.0;
    engine::Vec3 d[2];
    curve.derivatives(u, 1, d);
    const engine::Vec3 p = d[0] + 2.0 * engine::Vec3(-d[1].y(), d[1].x(), 0).normalized();
    scan.push_back(p);
    xyz += std::to_string(p.x()) + " " + std::to_string(p.y()) + " 0\n";
  }
  write("scan.xyz", xyz);
  const RunResult r = run(base() + " --points " + path("scan.xyz") +
                          " --method combined --iterate --report " + path("r.json"));
  ASSERT_EQ(r.status, 0) << r.err;
  std::ifstream in(path("r.json"));
  const nlohmann::json report = nlohmann::json::parse(in);
  ASSERT_EQ(report["targets"].size(), 4u);
  EXPECT_EQ(report["steps"].back()["operation"], "dB");
  EXPECT_LT(report["final_total"].get<double>(), 1e-9);
  EXPECT_GT(report["initial_total"].get<double>(), 4.0);  // about 2 mm per nose point
}

TEST_F(ModifyCommand, InvalidInputExitsWith3) {
  write("t.csv", "segment,x,y\n4,1,2\n");
  RunResult r = run(base() + " --targets " + path("t.csv"));
  EXPECT_EQ(r.status, 3);
  EXPECT_NE(r.err.find("has 4 segments"), std::string::npos) << r.err;
  r = run("--model " + path("model.json") + " --curve nope --targets " + path("t.csv") + " --out " +
          path("out.json"));
  EXPECT_EQ(r.status, 3);
  EXPECT_NE(r.err.find("no curve named \"nope\""), std::string::npos) << r.err;
  write("empty.xyz", "# nothing\n");
  r = run(base() + " --points " + path("empty.xyz"));
  EXPECT_EQ(r.status, 3);
  EXPECT_NE(r.err.find("empty.xyz"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(path("out.json")));
  // Neither or both target sources: a usage error.
  EXPECT_EQ(run(base()).status, 2);
  EXPECT_EQ(run(base() + " --targets " + path("t.csv") + " --points " + path("empty.xyz")).status,
            2);
}

}  // namespace
}  // namespace nurbsreg

// End-to-end tests of the real `nurbsreg` binary: the contract's exit codes and messages, and
// the main jobs (synth -> project, synth -> align) on the bundled examples.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/io/point_table.hpp"
#include "nurbsreg/io/pose.hpp"
#include "support/run_command.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::test {
namespace {

const std::string kPanel = nurbsreg::test::examples_dir() + "/panel.json";
const std::string kSphere = nurbsreg::test::examples_dir() + "/sphere.json";

int count_lines(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n'));
}

// `nurbsreg synth` of the panel into dir / name with the given options; the scan's path.
std::string synth_panel_scan(const ScratchDir& dir, const std::string& name,
                             const std::string& options) {
  const std::string scan = dir / name;
  const CommandResult r =
      run_nurbsreg("synth --model " + kPanel + " " + options + " --out " + scan, dir.path());
  EXPECT_EQ(r.status, 0) << r.err;
  return scan;
}

// `nurbsreg project` of the panel for `text` written as dir / name, into dir / "r.csv" (`out`).
CommandResult project_text_points(const ScratchDir& dir, const std::string& name,
                                  const std::string& text, std::string& out) {
  const std::string points = dir / name;
  std::ofstream(points) << text;
  out = dir / "r.csv";
  return run_nurbsreg("project --model " + kPanel + " --points " + points + " --out " + out,
                      dir.path());
}

TEST(Cli, HelpForEverySubcommand) {
  ScratchDir dir("help");
  for (const char* sub : {"", "info", "project", "synth", "align"}) {
    const CommandResult r = run_nurbsreg(std::string(sub) + " --help", dir.path());
    EXPECT_EQ(r.status, 0) << sub;
    EXPECT_NE(r.out.find("Usage"), std::string::npos) << sub;
  }
}

TEST(Cli, UsageErrorsExitTwo) {
  ScratchDir dir("usage");
  EXPECT_EQ(run_nurbsreg("", dir.path()).status, 2);
  EXPECT_EQ(run_nurbsreg("frobnicate", dir.path()).status, 2);
  EXPECT_EQ(run_nurbsreg("project --model " + kPanel, dir.path()).status, 2);  // missing options
  EXPECT_EQ(run_nurbsreg("synth --model " + kPanel + " --points 10 --out " + (dir / "s.pcd") +
                             " --pose \"1 2 3\"",
                         dir.path())
                .status,
            2);
  // More clutter than points: named, and nothing written.
  const CommandResult crowded = run_nurbsreg("synth --model " + kPanel + " --points 10 --out " +
                                                 (dir / "c.pcd") + " --outliers 0.6 --fixture 0.5",
                                             dir.path());
  EXPECT_EQ(crowded.status, 2);
  EXPECT_NE(crowded.err.find("outliers and fixture"), std::string::npos) << crowded.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "c.pcd"));
  const CommandResult r = run_nurbsreg(
      "project --model " + kPanel + " --points x.xyz --out " + (dir / "r.txt"), dir.path());
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("r.txt"), std::string::npos);
  // align checks its output names before it reads anything (the scan here does not exist).
  const CommandResult aligned = run_nurbsreg(
      "align --model " + kPanel + " --scan missing.xyz --aligned " + (dir / "a.ply"), dir.path());
  EXPECT_EQ(aligned.status, 2) << aligned.err;
  EXPECT_NE(aligned.err.find("--aligned: " + (dir / "a.ply")), std::string::npos) << aligned.err;
}

TEST(Cli, BadInputExitsThreeWithOneLineNamingTheFile) {
  ScratchDir dir("bad");
  const std::string model = dir / "broken.json";
  std::ofstream(model) << R"({"nurbsreg_model": 1, "surfaces": [{"name": "s", "degree": [3, 3],
    "knots_u": [0, 0, 0, 0, 1, 0.5, 1, 1, 1], "knots_v": [0, 0, 0, 0, 1, 1, 1, 1],
    "control_points": []}]})";
  const CommandResult info = run_nurbsreg("info --model " + model, dir.path());
  EXPECT_EQ(info.status, 3);
  EXPECT_EQ(count_lines(info.err), 1) << info.err;
  EXPECT_EQ(info.err.rfind("error: ", 0), 0u) << info.err;
  EXPECT_NE(info.err.find("broken.json"), std::string::npos) << info.err;

  const std::string scan = dir / "scan.xyz";
  std::ofstream(scan) << "1 2 3\n4 five 6\n";
  const std::string out = dir / "r.csv";
  const CommandResult project =
      run_nurbsreg("project --model " + kPanel + " --points " + scan + " --out " + out, dir.path());
  EXPECT_EQ(project.status, 3);
  EXPECT_NE(project.err.find("scan.xyz"), std::string::npos) << project.err;
  EXPECT_NE(project.err.find("line 2"), std::string::npos) << project.err;
  EXPECT_FALSE(std::filesystem::exists(out)) << "no partial output";

  EXPECT_EQ(run_nurbsreg("info --model " + (dir / "missing.json"), dir.path()).status, 3);
}

TEST(Cli, InfoReportsTheExamplePanel) {
  ScratchDir dir("info");
  const CommandResult r = run_nurbsreg("info --json --model " + kPanel, dir.path());
  ASSERT_EQ(r.status, 0) << r.err;
  const auto doc = nlohmann::json::parse(r.out);
  EXPECT_EQ(doc["bezier_patches"], 49);
  EXPECT_EQ(doc["surfaces"].size(), 1u);
}

// `info` says how many patches the engine searches where it cuts a surface's own finer: a long
// twisted strip is cut along its length; a plane is not.
TEST(Cli, InfoCountsThePatchesTheSearchCutsFiner) {
  ScratchDir dir("info_search_patches");
  std::string strip = "[";
  for (int i = 0; i < 4; ++i) {
    const double a = 1.0 * i, x = 100.0 * i / 3;
    strip += std::string(i ? ", " : "") + "[[" + std::to_string(x) + ", " +
             std::to_string(-0.5 * std::cos(a)) + ", " + std::to_string(-0.5 * std::sin(a)) +
             "], [" + std::to_string(x) + ", " + std::to_string(0.5 * std::cos(a)) + ", " +
             std::to_string(0.5 * std::sin(a)) + "]]";
  }
  strip += "]";
  const std::string model = dir / "strip.json";
  std::ofstream(model)
      << R"({"nurbsreg_model": 1, "surfaces": [{"name": "twisted", "degree": [3, 1],
      "knots_u": [0, 0, 0, 0, 1, 1, 1, 1], "knots_v": [0, 0, 1, 1], "control_points": )" +
             strip + R"(}, {"name": "plane", "degree": [1, 1],
      "knots_u": [0, 0, 1, 1], "knots_v": [0, 0, 1, 1],
      "control_points": [[[0, 0, 5], [0, 10, 5]], [[10, 0, 5], [10, 10, 5]]]}]})";
  const CommandResult json = run_nurbsreg("info --json --model " + model, dir.path());
  ASSERT_EQ(json.status, 0) << json.err;
  const auto doc = nlohmann::json::parse(json.out);
  EXPECT_EQ(doc["surfaces"][0]["bezier_patches"], 1);
  EXPECT_GT(doc["surfaces"][0]["search_patches"].get<int>(), 1);
  EXPECT_EQ(doc["surfaces"][1]["search_patches"], 1);
  EXPECT_EQ(doc["search_patches"].get<int>(), doc["surfaces"][0]["search_patches"].get<int>() + 1);
  const CommandResult text = run_nurbsreg("info --model " + model, dir.path());
  ASSERT_EQ(text.status, 0) << text.err;
  EXPECT_NE(text.out.find("patches far from flat are cut finer"), std::string::npos) << text.out;
  const std::size_t twisted = text.out.find("\"twisted\"");
  ASSERT_NE(twisted, std::string::npos) << text.out;
  EXPECT_NE(text.out.substr(twisted, text.out.find('\n', twisted) - twisted).find("(searched as "),
            std::string::npos)
      << text.out;
  EXPECT_EQ(text.out.find("(searched as ", text.out.find("\"plane\"")), std::string::npos)
      << text.out;
}

// A face whose loop is a rectangle of its domain is named so (the engine projects it untrimmed);
// a triangle's face is not.
TEST(Cli, InfoNamesTheFacesTrimmedToARectangle) {
  ScratchDir dir("info_rectangle");
  const auto face = [](const std::string& name, const std::string& loop) {
    return R"({"name": ")" + name +
           R"(", "degree": [1, 1], "knots_u": [0, 0, 1, 1], "knots_v": [0, 0, 1, 1],
        "control_points": [[[0, 0, 0], [0, 10, 0]], [[10, 0, 0], [10, 10, 0]]],
        "trim_loops": [{"curves": [)" +
           loop + "]}]}";
  };
  const auto side = [](double u0, double v0, double u1, double v1) {
    return R"({"uv": {"degree": 1, "knots": [0, 0, 1, 1], "control_points": [[)" +
           std::to_string(u0) + ", " + std::to_string(v0) + "], [" + std::to_string(u1) + ", " +
           std::to_string(v1) + "]]}}";
  };
  const std::string half = side(0, 0.5, 1, 0.5) + ", " + side(1, 0.5, 1, 1) + ", " +
                           side(1, 1, 0, 1) + ", " + side(0, 1, 0, 0.5);
  const std::string triangle = side(0, 0, 1, 0) + ", " + side(1, 0, 0, 1) + ", " + side(0, 1, 0, 0);
  const std::string model = dir / "faces.json";
  std::ofstream(model) << R"({"nurbsreg_model": 1, "surfaces": [)" + face("half", half) + ", " +
                              face("triangle", triangle) + "]}";
  const CommandResult json = run_nurbsreg("info --json --model " + model, dir.path());
  ASSERT_EQ(json.status, 0) << json.err;
  const auto doc = nlohmann::json::parse(json.out);
  EXPECT_EQ(doc["surfaces"][0]["trimmed_to_rectangle"], true);
  EXPECT_EQ(doc["surfaces"][1]["trimmed_to_rectangle"], false);
  const CommandResult text = run_nurbsreg("info --model " + model, dir.path());
  ASSERT_EQ(text.status, 0) << text.err;
  const std::size_t half_line = text.out.find("\"half\"");
  ASSERT_NE(half_line, std::string::npos) << text.out;
  EXPECT_NE(text.out.substr(half_line, text.out.find('\n', half_line) - half_line)
                .find("a rectangle of its domain, projected untrimmed"),
            std::string::npos)
      << text.out;
  EXPECT_EQ(text.out.find("a rectangle of its domain", text.out.find("\"triangle\"")),
            std::string::npos)
      << text.out;
}

TEST(Cli, ProjectWritesTheContractColumnsAndSkipsNaN) {
  ScratchDir dir("project");
  std::string out;
  const CommandResult r =
      project_text_points(dir, "points.xyz", "# x y z\n10 20 30\nnan 1 2\n50,50,-10\n0 0 0\n", out);
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string csv = read_text(out);
  EXPECT_EQ(csv.rfind("index,x,y,z,foot_x,foot_y,foot_z,distance,entity,u,v", 0), 0u);
  EXPECT_EQ(count_lines(csv), 4);  // header + 3 finite points
  EXPECT_NE(csv.find("\n3,0,0,0,"), std::string::npos) << "input index kept after the NaN row";
  EXPECT_EQ(csv.find("\n1,"), std::string::npos) << "the NaN point has no row";
}

TEST(Cli, ProjectIsTheSameForOneAndTwoThreads) {
  ScratchDir dir("threads");
  const std::string scan = dir / "scan.pcd";
  ASSERT_EQ(run_nurbsreg("synth --model " + kSphere +
                             " --points 3000 --noise 0.5 --outliers 0.2 "
                             "--out " +
                             scan,
                         dir.path())
                .status,
            0);
  ASSERT_EQ(run_nurbsreg("project --threads 1 --model " + kSphere + " --points " + scan +
                             " --out " + (dir / "one.csv"),
                         dir.path())
                .status,
            0);
  ASSERT_EQ(run_nurbsreg("project --threads 2 --model " + kSphere + " --points " + scan +
                             " --out " + (dir / "two.csv"),
                         dir.path())
                .status,
            0);
  EXPECT_EQ(read_text(dir / "one.csv"), read_text(dir / "two.csv"));
}

TEST(Cli, AlignRecoversTheSynthPose) {
  ScratchDir dir("align");
  const std::string scan = synth_panel_scan(
      dir, "scan.pcd",
      "--points 20000 --seed 3 --pose \"4 -3 5 4 -2 3\" --out-pose " + (dir / "true.txt"));
  const CommandResult align = run_nurbsreg(
      "align --model " + kPanel + " --scan " + scan + " --out-pose " + (dir / "pose.txt") +
          " --report " + (dir / "report.json") + " --aligned " + (dir / "aligned.pcd"),
      dir.path());
  ASSERT_EQ(align.status, 0) << align.err;
  const Eigen::Matrix4d truth = io::read_pose(dir / "true.txt");
  const Eigen::Matrix4d pose = io::read_pose(dir / "pose.txt");
  // Noise-free scan: exact projections make the recovered pose exact to rounding, here the
  // scan's float coordinates (up to ~8e-6 mm on this panel); 1.3e-7 on this sample set.
  EXPECT_LT((truth - pose).cwiseAbs().maxCoeff(), 1e-6) << pose;
  const auto report = nlohmann::json::parse(read_text(dir / "report.json"));
  for (const char* key :
       {"pose", "rms", "iterations", "converged", "inliers", "points", "seconds"}) {
    EXPECT_TRUE(report.contains(key)) << key;
  }
  EXPECT_TRUE(report["converged"].get<bool>());
  EXPECT_LT(report["rms"].get<double>(), 1e-6);
  EXPECT_EQ(report["points"].get<int>(), 20000);
  EXPECT_TRUE(std::filesystem::exists(dir / "aligned.pcd"));
  EXPECT_NE(align.out.find("deviation"), std::string::npos);
}

// The deviation line's statistics are those of the aligned scan's |signed_distance| column
// (independent order statistics here: a full sort), to the line's 4 significant digits.
TEST(Cli, AlignDeviationSummaryMatchesTheAlignedScan) {
  ScratchDir dir("deviation");
  const std::string scan = synth_panel_scan(
      dir, "scan.pcd", "--points 5000 --noise 0.05 --seed 4 --pose \"2 -1 3 1 0.5 -0.5\"");
  const CommandResult align = run_nurbsreg(
      "-q align --model " + kPanel + " --scan " + scan + " --aligned " + (dir / "aligned.pcd"),
      dir.path());
  ASSERT_EQ(align.status, 0) << align.err;
  const io::PointTable table = io::read_point_table(dir / "aligned.pcd");
  const std::vector<float>* signed_distance = table.values<float>("signed_distance");
  ASSERT_NE(signed_distance, nullptr);
  std::vector<double> d;
  for (float x : *signed_distance)
    d.push_back(std::abs(static_cast<double>(x)));
  ASSERT_EQ(d.size(), 5000u);
  std::sort(d.begin(), d.end());
  double sum = 0.0, sum_sq = 0.0;
  for (double x : d) {
    sum += x;
    sum_sq += x * x;
  }
  const auto at = [&](double q) { return d[static_cast<std::size_t>(q * (d.size() - 1))]; };
  const std::map<std::string, double> expected = {
      {"mean", sum / d.size()}, {"rms", std::sqrt(sum_sq / d.size())},
      {"median", at(0.5)},      {"p95", at(0.95)},
      {"p99", at(0.99)},        {"max", d.back()}};
  const std::size_t line = align.out.find("deviation |d| of 5000 points within ");
  ASSERT_NE(line, std::string::npos) << align.out;
  // The bound is named, and no point of this clean scan lies beyond it.
  EXPECT_NE(align.out.find("(the max distance; 0 beyond): ", line), std::string::npos) << align.out;
  const std::size_t colon = align.out.find(": ", line);  // after "within max distance"
  std::istringstream words(align.out.substr(colon + 2, align.out.find('\n', line) - colon - 2));
  std::string word;
  std::size_t checked = 0;
  while (words >> word) {
    const auto it = expected.find(word);
    if (it == expected.end()) continue;
    double value = 0.0;
    ASSERT_TRUE(words >> value) << word;
    EXPECT_NEAR(value, it->second, 1e-3 * it->second) << word;
    ++checked;
  }
  EXPECT_EQ(checked, expected.size()) << align.out;
}

// A run that ends on --max-iterations still gives its pose (exit 0), says so on stderr and in
// the report.
TEST(Cli, AlignOutOfIterationsWarnsAndKeepsItsPose) {
  ScratchDir dir("align_iterations");
  const std::string scan =
      synth_panel_scan(dir, "scan.pcd", "--points 2000 --seed 6 --pose \"4 -3 5 4 -2 3\"");
  const CommandResult align = run_nurbsreg(
      "align --model " + kPanel + " --scan " + scan + " --max-iterations 1 --out-pose " +
          (dir / "pose.txt") + " --report " + (dir / "report.json"),
      dir.path());
  EXPECT_EQ(align.status, 0) << align.err;
  EXPECT_NE(align.err.find(scan + ": no convergence within 1 iterations per stage"),
            std::string::npos)
      << align.err;
  EXPECT_TRUE(std::filesystem::exists(dir / "pose.txt"));
  const auto report = nlohmann::json::parse(read_text(dir / "report.json"));
  EXPECT_FALSE(report["converged"].get<bool>());
  EXPECT_EQ(report["termination"].get<std::string>().rfind("max_iterations", 0), 0u);
}

// ICP that loses its correspondences has no pose to give: a scan far beside the panel (every foot
// on an edge, off the normal) fails with exit 1 and one line naming the scan and the cause. No
// pose or aligned scan is written; the report is, and says converged: false. (--no-global: the
// local run from the identity; without it the global stage finds the pose, see below.)
TEST(Cli, AlignThatLosesItsCorrespondencesFails) {
  ScratchDir dir("align_fails");
  const std::string scan =
      synth_panel_scan(dir, "beside.pcd", "--points 2000 --seed 5 --pose \"0 0 0 1000 0 0\"");
  const CommandResult align =
      run_nurbsreg("-q align --no-global --model " + kPanel + " --scan " + scan + " --out-pose " +
                       (dir / "pose.txt") + " --aligned " + (dir / "aligned.pcd") + " --report " +
                       (dir / "report.json"),
                   dir.path());
  EXPECT_EQ(align.status, 1) << align.err;
  EXPECT_EQ(count_lines(align.err), 1) << align.err;
  EXPECT_EQ(align.err.rfind("error: " + scan + ": alignment failed", 0), 0u) << align.err;
  EXPECT_NE(align.err.find("too_few_correspondences"), std::string::npos) << align.err;
  EXPECT_NE(align.err.find("2000 beyond the model's free edges"), std::string::npos) << align.err;
  EXPECT_NE(align.err.find("--init"), std::string::npos) << align.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "pose.txt"));
  EXPECT_FALSE(std::filesystem::exists(dir / "aligned.pcd"));
  const auto report = nlohmann::json::parse(read_text(dir / "report.json"));
  EXPECT_FALSE(report["converged"].get<bool>());
  EXPECT_EQ(report["inliers"].get<int>(), 0);
  EXPECT_EQ(report["termination"].get<std::string>().rfind("too_few_correspondences", 0), 0u);
}

// The same scan far beside the panel, without --init: the global stage finds the pose, the fit
// is good, and the report says how (coarse method, hypotheses, scores) and why (fit numbers).
TEST(Cli, AlignWithoutInitFindsThePoseFromAnywhere) {
  ScratchDir dir("align_global");
  const std::string scan = synth_panel_scan(
      dir, "far.pcd",
      "--points 5000 --seed 5 --noise 0.01 --pose \"150 -60 20 1000 0 0\" --out-pose " +
          (dir / "truth.txt"));
  const CommandResult align =
      run_nurbsreg("-q align --model " + kPanel + " --scan " + scan + " --out-pose " +
                       (dir / "pose.txt") + " --report " + (dir / "report.json"),
                   dir.path());
  ASSERT_EQ(align.status, 0) << align.err;
  const Eigen::Matrix4d truth = io::read_pose(dir / "truth.txt");
  const Eigen::Matrix4d found = io::read_pose(dir / "pose.txt");
  // found * truth^-1 is the identity up to noise: it moves the panel's middle by a few hundredths.
  const Eigen::Matrix4d error = found * truth.inverse();
  EXPECT_LT((error.topLeftCorner<3, 3>() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(),
            1e-3);
  const Eigen::Vector4d middle(50, 50, 5, 1);
  EXPECT_LT((error * middle - middle).norm(), 0.05);
  const auto report = nlohmann::json::parse(read_text(dir / "report.json"));
  EXPECT_EQ(report["fit"].get<std::string>(), "good");
  EXPECT_GT(report["fit_details"]["inlier_fraction"].get<double>(), 0.95);
  EXPECT_EQ(report["coarse"]["method"].get<std::string>(), "fpfh-ransac");
  EXPECT_GE(report["coarse"]["verified"].get<int>(), 1);
  EXPECT_GT(report["coarse"]["winner"]["inlier_fraction"].get<double>(), 0.9);
}

// Clutter near the panel (30% outliers in its thin box) inflates the scan's own noise estimate:
// the verdict's noise comes from the distances at the pose, and the align line, the report and
// inspect's page name both estimates.
TEST(Cli, UnderClutterTheVerdictNamesBothNoiseEstimates) {
  ScratchDir dir("align_clutter_noise");
  const std::string scan = synth_panel_scan(
      dir, "cluttered.pcd", "--points 20000 --seed 3 --noise 0.0146 --outliers 0.3");
  const CommandResult align = run_nurbsreg("-q align --threads 1 --model " + kPanel + " --scan " +
                                               scan + " --report " + (dir / "report.json"),
                                           dir.path());
  ASSERT_EQ(align.status, 0) << align.err;
  EXPECT_NE(align.out.find("of the distances; the scan's own estimate"), std::string::npos)
      << align.out;
  const auto details = nlohmann::json::parse(read_text(dir / "report.json"))["fit_details"];
  const double scan_noise = details["scan_noise"].get<double>();
  const double fit_noise = details["fit_noise"].get<double>();
  EXPECT_GT(scan_noise, 1.3 * 0.0146);
  EXPECT_NEAR(fit_noise, 0.0146, 0.0015);
  EXPECT_EQ(details["noise"].get<double>(), fit_noise);
  EXPECT_NEAR(details["tolerance"].get<double>(), 3.0 * fit_noise, 1e-12);
  const CommandResult inspect =
      run_nurbsreg("-q inspect --threads 1 --model " + kPanel + " --scan " + scan +
                       " --tolerance 0.05 --out-dir " + (dir / "inspection"),
                   dir.path());
  ASSERT_EQ(inspect.status, 0) << inspect.err;
  const std::string html = read_text(dir / "inspection/report.html");
  EXPECT_NE(html.find("of the distances; the scan's own estimate"), std::string::npos);
}

// A wrong pose from --init is never a plain success: exit 1 with one line naming the scan and
// the poor fit; --accept-poor writes it, reported "poor".
TEST(Cli, APoorFitFailsUnlessAccepted) {
  ScratchDir dir("align_poor");
  const std::string scan =
      synth_panel_scan(dir, "turned.pcd", "--points 3000 --seed 4 --pose \"0 0 90 100 0 0\"");
  const CommandResult poor = run_nurbsreg(
      "-q align --no-global --model " + kPanel + " --scan " + scan + " --max-iterations 3",
      dir.path());
  EXPECT_EQ(poor.status, 1) << poor.err;
  EXPECT_EQ(count_lines(poor.err), 1) << poor.err;
  EXPECT_EQ(poor.err.rfind("error: " + scan + ": poor fit", 0), 0u) << poor.err;
  const CommandResult accepted =
      run_nurbsreg("-q align --no-global --accept-poor --model " + kPanel + " --scan " + scan +
                       " --max-iterations 3 --report " + (dir / "report.json"),
                   dir.path());
  EXPECT_EQ(accepted.status, 0) << accepted.err;
  const auto report = nlohmann::json::parse(read_text(dir / "report.json"));
  EXPECT_EQ(report["fit"].get<std::string>(), "poor");
}

// Noise far beyond any surface's (3 mm on a panel sampled at ~1.4 mm): no neighbourhood reads as
// a surface, the noise estimate is 0, and the poor-fit line says the tolerance came from the
// model's sample spacing instead of printing "3 x the scan's noise 0".
TEST(Cli, APoorFitSaysWhenTheNoiseCouldNotBeEstimated) {
  ScratchDir dir("align_noise_unknown");
  const std::string scan = synth_panel_scan(dir, "noisy.pcd", "--points 5000 --seed 1 --noise 3");
  const CommandResult poor =
      run_nurbsreg("-q align --no-global --model " + kPanel + " --scan " + scan, dir.path());
  EXPECT_EQ(poor.status, 1) << poor.err;
  EXPECT_EQ(count_lines(poor.err), 1) << poor.err;
  EXPECT_NE(poor.err.find("(a twentieth of the model's sample spacing: the scan's noise could "
                          "not be estimated)"),
            std::string::npos)
      << poor.err;
  EXPECT_EQ(poor.err.find("noise 0)"), std::string::npos) << poor.err;
}

// A synthetic panel scan with every coordinate multiplied by `scale` (another unit), as XYZ.
std::string scaled_panel_scan(const ScratchDir& dir, const std::string& name, double scale) {
  const io::PointCloud cloud =
      io::read_point_cloud(synth_panel_scan(dir, name + ".mm.xyz", "--points 2000 --seed 7"));
  const std::string scan = dir / name;
  std::ofstream out(scan);
  out.precision(17);
  for (const engine::Vec3& p : cloud.points)
    out << scale * p.x() << ' ' << scale * p.y() << ' ' << scale * p.z() << '\n';
  return scan;
}

// A scan in metres against the panel in millimetres: local ICP (--no-global) settles the small
// scan on some patch. That pose means nothing, and the verdict says so (it covers 0.1% of the
// model: exit 1), with the sizes that differ by 1000 as the likely cause.
TEST(Cli, AlignOfAScanInOtherUnitsWarns) {
  ScratchDir dir("align_metres");
  const std::string scan = scaled_panel_scan(dir, "metres.xyz", 1e-3);
  const CommandResult align = run_nurbsreg("align --no-global --model " + kPanel + " --scan " +
                                               scan + " --out-pose " + (dir / "pose.txt"),
                                           dir.path());
  EXPECT_EQ(align.status, 1) << align.err;
  EXPECT_NE(align.err.find(scan + ": poor fit"), std::string::npos) << align.err;
  EXPECT_NE(align.err.find("the scan is 1/"), std::string::npos) << align.err;
  EXPECT_NE(align.err.find("of the size of the model"), std::string::npos) << align.err;
  EXPECT_NE(align.err.find("are both in the same units"), std::string::npos) << align.err;
  // Sizes 1000 apart: the units lead the reasons, before the verdict's numbers.
  EXPECT_LT(align.err.find("the scan is 1/"), align.err.find("of the points lie within"))
      << align.err;
  // project warns the same way; a scan of the panel's own size does not.
  const CommandResult project = run_nurbsreg(
      "project --model " + kPanel + " --points " + scan + " --out " + (dir / "r.csv"), dir.path());
  EXPECT_EQ(project.status, 0) << project.err;
  EXPECT_NE(project.err.find("are both in the same units"), std::string::npos) << project.err;
  const CommandResult same = run_nurbsreg(
      "project --model " + kPanel + " --points " + scan + ".mm.xyz --out " + (dir / "r2.csv"),
      dir.path());
  EXPECT_EQ(same.status, 0) << same.err;
  EXPECT_EQ(same.err.find("same units"), std::string::npos) << same.err;
}

// A scan still in the scanner's frame (moved by 1000 mm, seven times the panel's size) is
// projected as asked, but its distances say nothing about the part: project warns, last, and
// names the likely cause. The same scan in the model's frame, with 30% outliers, stays quiet.
TEST(Cli, ProjectOfAScanOutsideTheModelsFrameWarns) {
  ScratchDir dir("project_far");
  const std::string moved =
      synth_panel_scan(dir, "moved.pcd", "--points 3000 --seed 3 --pose \"10 0 0 1000 0 0\"");
  const CommandResult far = run_nurbsreg(
      "project --model " + kPanel + " --points " + moved + " --out " + (dir / "far.csv"),
      dir.path());
  EXPECT_EQ(far.status, 0) << far.err;
  EXPECT_TRUE(std::filesystem::exists(dir / "far.csv"));
  const std::size_t note = far.err.find(moved + ": half of the points lie ");
  ASSERT_NE(note, std::string::npos) << far.err;
  EXPECT_NE(far.err.find("is the scan in the model's frame?", note), std::string::npos) << far.err;
  EXPECT_EQ(far.err.find('\n', note), far.err.size() - 1) << far.err;   // the last line
  EXPECT_EQ(far.err.find("same units"), std::string::npos) << far.err;  // the sizes agree

  const std::string near =
      synth_panel_scan(dir, "near.pcd", "--points 3000 --seed 3 --outliers 0.3");
  const CommandResult quiet = run_nurbsreg(
      "project --model " + kPanel + " --points " + near + " --out " + (dir / "near.csv"),
      dir.path());
  EXPECT_EQ(quiet.status, 0) << quiet.err;
  EXPECT_EQ(quiet.err.find("half of the points"), std::string::npos) << quiet.err;

  // batch --mode project warns per frame the same way.
  std::filesystem::create_directories(dir / "frames");
  std::filesystem::copy_file(moved, (dir / "frames") + "/a.pcd");
  std::filesystem::copy_file(near, (dir / "frames") + "/b.pcd");
  const CommandResult batch = run_nurbsreg("batch --mode project --model " + kPanel + " --scans " +
                                               (dir / "frames") + " --out " + (dir / "out"),
                                           dir.path());
  EXPECT_EQ(batch.status, 0) << batch.err;
  EXPECT_NE(batch.err.find("a.pcd: half of the points lie "), std::string::npos) << batch.err;
  EXPECT_EQ(batch.err.find("b.pcd: half of the points"), std::string::npos) << batch.err;
}

// A scan in inches (1/25.4 of the panel) loses its correspondences: the failure line names the
// sizes as the likely cause.
TEST(Cli, AlignFailureNamesTheSizeMismatch) {
  ScratchDir dir("align_inches");
  const std::string scan = scaled_panel_scan(dir, "inches.xyz", 1.0 / 25.4);
  const CommandResult align =
      run_nurbsreg("-q align --model " + kPanel + " --scan " + scan, dir.path());
  EXPECT_EQ(align.status, 1) << align.err;
  EXPECT_EQ(count_lines(align.err), 1) << align.err;
  EXPECT_NE(align.err.find("alignment failed"), std::string::npos) << align.err;
  // ~1/26: the model's size is its control points' box.
  EXPECT_NE(align.err.find("the scan is 1/2"), std::string::npos) << align.err;
  EXPECT_NE(align.err.find("are both in the same units"), std::string::npos) << align.err;
  // Without -q the info lines come too, but the failure is said once: on its error line.
  const CommandResult loud =
      run_nurbsreg("align --model " + kPanel + " --scan " + scan, dir.path());
  EXPECT_EQ(loud.status, 1) << loud.err;
  const std::string cause = "too few points for features";
  const std::size_t first = loud.err.find(cause);
  ASSERT_NE(first, std::string::npos) << loud.err;
  EXPECT_EQ(loud.err.find(cause, first + 1), std::string::npos) << loud.err;
  EXPECT_EQ(loud.err.rfind("\n", first), loud.err.rfind("\nerror: ", first)) << loud.err;
}

// A scan with fewer points than a pose needs fails for that reason alone: no hint about where it
// lies.
TEST(Cli, AlignOfTooFewPointsSaysSo) {
  ScratchDir dir("align_few");
  const std::string scan = dir / "three.xyz";
  std::ofstream(scan) << "0 0 0\n10 0 0\n0 10 0\n";
  const CommandResult align =
      run_nurbsreg("-q align --model " + kPanel + " --scan " + scan, dir.path());
  EXPECT_EQ(align.status, 1) << align.err;
  EXPECT_NE(align.err.find("scan has 3 points, fewer than min_correspondences (6)"),
            std::string::npos)
      << align.err;
  EXPECT_EQ(align.err.find("--init"), std::string::npos) << align.err;
}

// A JSON face whose trim loop runs half a domain beyond its surface: the part beyond is not in
// the model, and every command that loads it says so, naming the face.
TEST(Cli, AFaceBeyondItsSurfaceIsNamed) {
  ScratchDir dir("face_beyond");
  const std::string model = dir / "plate.json";
  const auto side = [](double u0, double v0, double u1, double v1) {
    return "{\"uv\": {\"degree\": 1, \"knots\": [0, 0, 1, 1], \"control_points\": [[" +
           std::to_string(u0) + ", " + std::to_string(v0) + "], [" + std::to_string(u1) + ", " +
           std::to_string(v1) + "]]}}";
  };
  std::ofstream(model) << R"({"nurbsreg_model": 1, "surfaces": [{"name": "plate", "degree": [1, 1],
    "knots_u": [0, 0, 1, 1], "knots_v": [0, 0, 1, 1],
    "control_points": [[[0, 0, 0], [0, 10, 0]], [[10, 0, 0], [10, 10, 0]]],
    "trim_loops": [{"curves": [)"
                       << side(0.5, 0.2, 1.5, 0.2) << ", " << side(1.5, 0.2, 1.5, 0.8) << ", "
                       << side(1.5, 0.8, 0.5, 0.8) << ", " << side(0.5, 0.8, 0.5, 0.2) << "]}]}]}";
  const CommandResult r = run_nurbsreg("info --model " + model, dir.path());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find("the trim loops of 1 faces leave their surface's parameter domain (plate "
                       "by 50% of its width)"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(run_nurbsreg("info --model " + kPanel, dir.path()).err.find("warning"),
            std::string::npos);
}

// An empty scan is bad input for every command (issue 24): project of a file without finite
// points exits 3 naming it, and writes no table.
TEST(Cli, ProjectOfNoPointsIsBadInput) {
  ScratchDir dir("project_empty");
  std::string out;
  CommandResult r = project_text_points(dir, "nan.xyz", "nan 0 0\n1 inf 2\n", out);
  EXPECT_EQ(r.status, 3) << r.err;
  EXPECT_NE(r.err.find("nan.xyz: the scan has no finite points (all 2 are NaN or infinite)"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(std::filesystem::exists(out));
  r = project_text_points(dir, "empty.xyz", "# nothing\n", out);
  EXPECT_EQ(r.status, 3) << r.err;
  EXPECT_NE(r.err.find("empty.xyz: the scan has no points"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace nurbsreg::test

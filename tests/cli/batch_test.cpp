// End-to-end tests of `nurbsreg batch` (README "Batch jobs"): every good frame gives exactly the
// outputs of a single `align` / `project` run, bad frames are reported and fail only
// themselves (exit 4), a resumed run equals an uninterrupted one, and shards partition the
// inputs.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <map>
#include <sstream>
#include <thread>
#include <vector>

#include "nurbsreg/io/alignment_report.hpp"
#include "nurbsreg/io/pose.hpp"
#include "support/run_command.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::test {
namespace {

namespace fs = std::filesystem;

const std::string kPanel = nurbsreg::test::examples_dir() + "/panel.json";

constexpr int kGoodFrames = 5;
const std::vector<std::string> kGood = {"f0", "f1", "f2", "f3", "f4"};
// Sorted order of the directory: f0..f4, g_empty, g_truncated.
const std::vector<std::string> kAllFiles = {"f0.pcd", "f1.pcd",      "f2.pcd",         "f3.pcd",
                                            "f4.pcd", "g_empty.pcd", "g_truncated.pcd"};

// The summary CSV as rows of fields (RFC 4180 quoting: reasons may contain commas).
std::vector<std::vector<std::string>> read_summary(const std::string& path) {
  std::istringstream in(read_text(path));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "file,points,skipped,status,rms,iterations,pose,seconds,reason");
  std::vector<std::vector<std::string>> rows;
  while (std::getline(in, line)) {
    std::vector<std::string> fields(1);
    bool quoted = false;
    for (std::size_t i = 0; i < line.size(); ++i) {
      const char c = line[i];
      if (c == '"' && quoted && i + 1 < line.size() && line[i + 1] == '"') {
        fields.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = !quoted;
      } else if (c == ',' && !quoted) {
        fields.emplace_back();
      } else {
        fields.back() += c;
      }
    }
    rows.push_back(fields);
  }
  return rows;
}

// Frames shared by all tests: 5 synthetic scans of the panel (2,500 points, noise, different
// poses and seeds), one empty file and one binary PCD cut in the middle of its data.
class Batch : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new ScratchDir("batch");
    const fs::path scans = dir_->path() / "scans";
    fs::create_directories(scans);
    for (int i = 0; i < kGoodFrames; ++i) {
      const CommandResult r = run_nurbsreg(
          "synth --model " + kPanel + " --points 2500 --noise 0.02 --seed " +
              std::to_string(i + 1) + " --pose \"" + std::to_string(0.5 * i) + " -1 0.7 " +
              std::to_string(0.3 * i) + " 0.4 -0.2\" --out " + (scans / kAllFiles[i]).string(),
          dir_->path());
      ASSERT_EQ(r.status, 0) << r.err;
    }
    std::ofstream(scans / "g_empty.pcd").close();
    const std::string whole = read_text(scans / "f0.pcd");
    std::ofstream(scans / "g_truncated.pcd", std::ios::binary) << whole.substr(0, whole.size() / 2);
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::string scans() { return (dir_->path() / "scans").string(); }
  static std::string scan(const std::string& stem) { return scans() + "/" + stem + ".pcd"; }
  static std::string path(const std::string& name) { return (*dir_) / name; }
  static CommandResult run(const std::string& args) {
    return run_nurbsreg("-q " + args, dir_->path());
  }

  static ScratchDir* dir_;
};
ScratchDir* Batch::dir_ = nullptr;

void expect_same_report(const std::string& a, const std::string& b) {
  const io::AlignmentReport ra = io::read_alignment_report(a);
  const io::AlignmentReport rb = io::read_alignment_report(b);
  EXPECT_EQ(ra.pose, rb.pose) << a;
  EXPECT_EQ(ra.rms, rb.rms) << a;
  EXPECT_EQ(ra.iterations, rb.iterations) << a;
  EXPECT_EQ(ra.converged, rb.converged) << a;
  EXPECT_EQ(ra.inliers, rb.inliers) << a;
  EXPECT_EQ(ra.points, rb.points) << a;
  EXPECT_EQ(ra.termination, rb.termination) << a;
  ASSERT_EQ(ra.history.size(), rb.history.size()) << a;
  for (std::size_t k = 0; k < ra.history.size(); ++k)
    EXPECT_EQ(ra.history[k].rms, rb.history[k].rms) << a << " iteration " << k;
}

// Output files of two batch runs (align mode) are the same; reports up to their timings.
void expect_same_align_outputs(const std::string& a, const std::string& b) {
  for (const std::string& stem : kGood) {
    for (const char* ext : {".pose.txt", ".aligned.pcd"}) {
      const std::string fa = a + "/" + stem + ext;
      ASSERT_TRUE(fs::exists(fa)) << fa;
      EXPECT_EQ(read_text(fa), read_text(b + "/" + stem + ext)) << stem << ext;
    }
    expect_same_report(a + "/" + stem + ".report.json", b + "/" + stem + ".report.json");
  }
}

// Summary rows without the timing column.
std::vector<std::vector<std::string>> untimed(std::vector<std::vector<std::string>> rows) {
  for (auto& row : rows) {
    if (row.size() > 7) row[7] = "";
  }
  return rows;
}

// An interim summary against the finished one: the same frames in the same order, each row
// either the finished row or `pending` with nothing else filled in.
void expect_rows_done_or_pending(const std::vector<std::vector<std::string>>& finished,
                                 const std::vector<std::vector<std::string>>& interim) {
  ASSERT_EQ(finished.size(), interim.size());
  for (std::size_t i = 0; i < finished.size(); ++i) {
    ASSERT_GT(interim[i].size(), 3u);
    if (interim[i][3] != "pending") {
      EXPECT_EQ(finished[i], interim[i]);
      continue;
    }
    EXPECT_EQ(interim[i][0], finished[i][0]);
    for (std::size_t c = 1; c < interim[i].size(); ++c) {
      if (c != 3) {
        EXPECT_EQ(interim[i][c], "") << interim[i][0] << " column " << c;
      }
    }
  }
}

TEST_F(Batch, AlignMatchesSingleRunsAndReportsBadFrames) {
  const std::string out = path("align_out");
  const CommandResult r =
      run("batch --model " + kPanel + " --scans " + scans() + " --out " + out + " --threads 2");
  // Documented exit status: 4 = some frames failed, the others are done.
  EXPECT_EQ(r.status, 4) << r.err;
  EXPECT_NE(r.err.find("error: 2 of 7 frames failed"), std::string::npos) << r.err;
  EXPECT_NE(r.out.find("5 frames ok (0 resumed), 2 failed"), std::string::npos) << r.out;

  const auto rows = read_summary(out + "/summary.csv");
  ASSERT_EQ(rows.size(), kAllFiles.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    ASSERT_EQ(rows[i].size(), 9u) << i;
    EXPECT_EQ(rows[i][0], scans() + "/" + kAllFiles[i]) << "input order";
  }
  for (int i = 0; i < kGoodFrames; ++i) {
    const std::string& stem = kGood[static_cast<std::size_t>(i)];
    const auto& row = rows[static_cast<std::size_t>(i)];
    EXPECT_EQ(row[3], "ok") << stem;
    EXPECT_EQ(row[1], "2500");
    EXPECT_EQ(row[2], "0");
    EXPECT_TRUE(fs::exists(out + "/" + stem + ".done.csv"));

    // The single command on the same frame writes the same bytes.
    const std::string single = path("single_" + stem);
    const CommandResult s = run("align --threads 1 --model " + kPanel + " --scan " + scan(stem) +
                                " --out-pose " + single + ".pose.txt --aligned " + single +
                                ".aligned.pcd --report " + single + ".report.json");
    ASSERT_EQ(s.status, 0) << s.err;
    EXPECT_EQ(read_text(single + ".pose.txt"), read_text(out + "/" + stem + ".pose.txt"));
    EXPECT_EQ(read_text(single + ".aligned.pcd"), read_text(out + "/" + stem + ".aligned.pcd"));
    expect_same_report(single + ".report.json", out + "/" + stem + ".report.json");

    // The summary's pose, rms and iterations are those of the report, exactly.
    const io::AlignmentReport report = io::read_alignment_report(single + ".report.json");
    std::istringstream pose_text(row[6]);
    Eigen::Matrix4d pose;
    for (int k = 0; k < 16; ++k)
      pose_text >> pose(k / 4, k % 4);
    EXPECT_EQ(pose, report.pose) << stem;
    EXPECT_EQ(std::stod(row[4]), report.rms) << stem;
    EXPECT_EQ(std::stoi(row[5]), report.iterations) << stem;
  }
  for (std::size_t i = kGoodFrames; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i][3], "failed") << rows[i][0];
    EXPECT_NE(rows[i][8].find(kAllFiles[i]), std::string::npos) << "reason names the file";
    const std::string stem = fs::path(kAllFiles[i]).stem().string();
    for (const char* ext : {".pose.txt", ".aligned.pcd", ".report.json", ".done.csv"})
      EXPECT_FALSE(fs::exists(out + "/" + stem + ext)) << stem << ext;
  }
  EXPECT_NE(rows[5][8].find("no DATA line"), std::string::npos) << rows[5][8];
  // Nothing else in the output directory: no temporaries, no outputs of failed frames.
  std::size_t files = 0;
  for (const auto& entry : fs::directory_iterator(out)) {
    EXPECT_NE(entry.path().filename().string()[0], '.') << entry.path();
    ++files;
  }
  EXPECT_EQ(files, 4u * kGoodFrames + 1);
}

TEST_F(Batch, ProjectMatchesSingleRuns) {
  const std::string out = path("project_out");
  const CommandResult r = run("batch --mode project --model " + kPanel + " --scans " + scans() +
                              " --out " + out + " --threads 1");
  EXPECT_EQ(r.status, 4) << r.err;
  const auto rows = read_summary(out + "/summary.csv");
  ASSERT_EQ(rows.size(), kAllFiles.size());
  for (const std::string& stem : kGood) {
    const std::string single = path("single_" + stem + ".csv");
    const CommandResult s =
        run("project --model " + kPanel + " --points " + scan(stem) + " --out " + single);
    ASSERT_EQ(s.status, 0) << s.err;
    EXPECT_EQ(read_text(single), read_text(out + "/" + stem + ".projection.csv")) << stem;
  }
  EXPECT_EQ(rows[5][3], "failed");
  EXPECT_EQ(rows[6][3], "failed");
}

TEST_F(Batch, AllGoodFramesExitZeroWithAListFile) {
  // Relative paths in the list are relative to the list's directory.
  const std::string list = path("scans/good.txt");
  std::ofstream(list) << "# good frames only\nf3.pcd\n\n  f1.pcd\n";
  const std::string out = path("list_out");
  const CommandResult r = run("batch --mode project --model " + kPanel + " --list " + list +
                              " --out " + out + " --format pcd");
  EXPECT_EQ(r.status, 0) << r.err;
  const auto rows = read_summary(out + "/summary.csv");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0][0], scans() + "/f3.pcd") << "list order";
  EXPECT_EQ(rows[1][0], scans() + "/f1.pcd");
  EXPECT_TRUE(fs::exists(out + "/f3.projection.pcd"));
  fs::remove(list);
}

TEST_F(Batch, ResumeAfterInterruptionMatchesUninterruptedRun) {
  const std::string full = path("resume_full");
  const std::string part = path("resume_part");
  ASSERT_EQ(run("batch --model " + kPanel + " --scans " + scans() + " --out " + full).status, 4);
  ASSERT_EQ(run("batch --model " + kPanel + " --scans " + scans() + " --out " + part).status, 4);
  // Reproduce on disk what a batch killed mid-way leaves behind (killing a process at a
  // chosen point is not deterministic, but its traces are): every output is written
  // atomically and the `.done.csv` marker last, so a kill leaves
  //  - f1: outputs written but no marker yet (killed before the marker); one output stale
  //    (from an older run),
  //  - f3: killed while writing its first output: only a temporary `.f3.pose.txt.tmp-*`,
  //  - f4: not started.
  fs::remove(part + "/f1.done.csv");
  std::ofstream(part + "/f1.pose.txt") << "stale\n";
  for (const char* stem : {"f3", "f4"}) {
    for (const char* ext : {".pose.txt", ".aligned.pcd", ".report.json", ".done.csv"})
      fs::remove(part + "/" + stem + ext);
  }
  std::ofstream(part + "/.f3.pose.txt.tmp-999999-0") << "1 0 0";
  fs::remove(part + "/summary.csv");
  // f0 is complete: resume must leave it alone (same inode and time).
  const auto f0_time = fs::last_write_time(part + "/f0.aligned.pcd");
  const std::vector<std::string> f0_marker = read_summary(part + "/f0.done.csv").at(0);

  const CommandResult r =
      run("batch --resume --model " + kPanel + " --scans " + scans() + " --out " + part);
  EXPECT_EQ(r.status, 4) << r.err;
  EXPECT_NE(r.out.find("5 frames ok (2 resumed), 2 failed"), std::string::npos) << r.out;
  EXPECT_EQ(fs::last_write_time(part + "/f0.aligned.pcd"), f0_time);
  EXPECT_FALSE(fs::exists(part + "/.f3.pose.txt.tmp-999999-0")) << "leftover temporary";
  expect_same_align_outputs(full, part);
  EXPECT_EQ(untimed(read_summary(full + "/summary.csv")),
            untimed(read_summary(part + "/summary.csv")));
  // Resumed rows are rebuilt from the markers, timing included.
  EXPECT_EQ(f0_marker, read_summary(part + "/summary.csv")[0]);
}

// A real interruption: SIGTERM at some moment of the run (as `scancel` or a pod eviction would
// send). Whenever it lands, the outputs left are complete files (no partial or temporary file,
// every frame with a marker has all its outputs), and --resume then gives the uninterrupted
// run's outputs.
TEST_F(Batch, SigtermLeavesNoPartialOutputAndResumeCompletes) {
  const std::string full = path("term_full");
  const std::string part = path("term_part");
  ASSERT_EQ(run("batch --model " + kPanel + " --scans " + scans() + " --out " + full).status, 4);

  const std::string binary = nurbsreg::test::nurbsreg_binary();
  std::vector<std::string> args = {binary,  "-q",    "batch", "--model",   kPanel, "--scans",
                                   scans(), "--out", part,    "--threads", "1"};
  std::vector<char*> argv;
  for (std::string& a : args)
    argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
  pid_t pid = 0;
  ASSERT_EQ(posix_spawn(&pid, binary.c_str(), &actions, nullptr, argv.data(), environ), 0);
  posix_spawn_file_actions_destroy(&actions);
  ::usleep(250 * 1000);
  ::kill(pid, SIGTERM);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  // Exit 1 if stopped mid-way, 4 if it had finished; killed outright (-1) only if the signal
  // came before the batch installed its handler, i.e. before writing anything.
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  EXPECT_TRUE(code == 1 || code == 4 || code == -1) << code;
  if (fs::exists(part)) {
    for (const auto& entry : fs::directory_iterator(part)) {
      const std::string name = entry.path().filename().string();
      EXPECT_NE(name[0], '.') << "temporary left: " << name;
      if (name.ends_with(".done.csv")) {
        const std::string stem = name.substr(0, name.size() - 9);
        for (const char* ext : {".pose.txt", ".aligned.pcd", ".report.json"})
          EXPECT_TRUE(fs::exists(part + "/" + stem + ext)) << stem << ext;
      }
    }
  }
  const CommandResult r =
      run("batch --resume --model " + kPanel + " --scans " + scans() + " --out " + part);
  EXPECT_EQ(r.status, 4) << r.err;
  expect_same_align_outputs(full, part);
  EXPECT_EQ(untimed(read_summary(full + "/summary.csv")),
            untimed(read_summary(part + "/summary.csv")));
}

// A frame that fails in the middle of a batch (two workers, frames in flight around it) costs
// only itself: every other frame's outputs are byte for byte those of a batch of the good frames
// alone, and the summary keeps the list's order.
TEST_F(Batch, FramesFailingMidBatchLeaveTheOthersComplete) {
  const std::string good_out = path("midfail_good");
  const std::string out = path("midfail_out");
  const std::string good_list = path("midfail_good.txt");
  const std::string list = path("midfail.txt");
  std::ofstream(good_list) << scan("f0") << "\n" << scan("f1") << "\n" << scan("f2") << "\n";
  std::ofstream(list) << scan("f0") << "\n"
                      << scans() << "/g_truncated.pcd\n"
                      << scan("f1") << "\n"
                      << scans() << "/g_empty.pcd\n"
                      << scan("f2") << "\n";
  ASSERT_EQ(run("batch --model " + kPanel + " --list " + good_list + " --out " + good_out).status,
            0);
  const CommandResult r = run("batch --model " + kPanel + " --list " + list + " --out " + out +
                              " --threads 2 --in-flight 3");
  EXPECT_EQ(r.status, 4) << r.err;
  const auto rows = read_summary(out + "/summary.csv");
  ASSERT_EQ(rows.size(), 5u);
  const std::vector<std::string> status = {"ok", "failed", "ok", "failed", "ok"};
  for (std::size_t i = 0; i < rows.size(); ++i)
    EXPECT_EQ(rows[i][3], status[i]) << rows[i][0];
  const auto good_rows = untimed(read_summary(good_out + "/summary.csv"));
  const auto all_rows = untimed(rows);
  EXPECT_EQ(all_rows[0], good_rows[0]);
  EXPECT_EQ(all_rows[2], good_rows[1]);
  EXPECT_EQ(all_rows[4], good_rows[2]);
  for (const char* stem : {"f0", "f1", "f2"}) {
    for (const char* ext : {".pose.txt", ".aligned.pcd"}) {
      EXPECT_EQ(read_text(out + "/" + stem + ext), read_text(good_out + "/" + stem + ext))
          << stem << ext;
    }
    expect_same_report(good_out + "/" + stem + ".report.json", out + "/" + stem + ".report.json");
    EXPECT_TRUE(fs::exists(out + "/" + stem + ".done.csv")) << stem;
  }
  for (const char* stem : {"g_truncated", "g_empty"}) {
    for (const char* ext : {".pose.txt", ".aligned.pcd", ".report.json", ".done.csv"})
      EXPECT_FALSE(fs::exists(out + "/" + stem + ext)) << stem << ext;
  }
}

// SIGKILL (the OOM killer, `kill -9`, a node lost): no handler runs, nothing is cleaned up.
// Wherever the kill lands, every visible file in the output directory is complete: byte for
// byte the uninterrupted run's file (atomic writes: a temporary, hidden, renamed into place), a
// frame with a marker has all its outputs, and --resume then gives the uninterrupted outputs.
// The kill times are fractions of the uninterrupted run's own time, so that they fall inside
// the run on a slow (sanitizer) build too.
TEST_F(Batch, SigkillLeavesOnlyCompleteFilesAndResumeCompletes) {
  const std::string full = path("kill_full");
  const auto start = std::chrono::steady_clock::now();
  ASSERT_EQ(run("batch --model " + kPanel + " --scans " + scans() + " --out " + full).status, 4);
  const auto full_time = std::chrono::steady_clock::now() - start;
  const std::string binary = nurbsreg::test::nurbsreg_binary();
  int killed_mid_run = 0;
  for (const double fraction : {0.3, 0.7}) {
    const std::string part = path("kill_part_" + std::to_string(static_cast<int>(fraction * 100)));
    // Interim summaries often, so that a kill can land beside one on any build.
    std::vector<std::string> args = {
        binary, "-q",        "batch", "--model",         kPanel, "--scans", scans(), "--out",
        part,   "--threads", "2",     "--summary-every", "0.05"};
    std::vector<char*> argv;
    for (std::string& a : args)
      argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
    pid_t pid = 0;
    ASSERT_EQ(posix_spawn(&pid, binary.c_str(), &actions, nullptr, argv.data(), environ), 0);
    posix_spawn_file_actions_destroy(&actions);
    std::this_thread::sleep_for(
        std::chrono::duration_cast<std::chrono::microseconds>(full_time * fraction));
    ::kill(pid, SIGKILL);
    int status = 0;
    ASSERT_EQ(::waitpid(pid, &status, 0), pid);
    if (WIFSIGNALED(status)) ++killed_mid_run;
    if (!fs::exists(part)) continue;
    for (const auto& entry : fs::directory_iterator(part)) {
      const std::string name = entry.path().filename().string();
      if (name[0] == '.') continue;  // a killed writer's temporary: resume removes it
      const std::string full_file = full + "/" + name;
      ASSERT_TRUE(fs::exists(full_file)) << "a file the full run does not write: " << name;
      if (name.ends_with(".report.json")) {
        expect_same_report(full_file, entry.path().string());
      } else if (name == "summary.csv") {
        // An interim summary (written every --summary-every seconds, which a sanitizer build's
        // slow run reaches): each row is the uninterrupted run's, or the frame is still pending.
        expect_rows_done_or_pending(untimed(read_summary(full_file)),
                                    untimed(read_summary(entry.path())));
      } else if (name.ends_with(".csv")) {
        // Markers: complete rows (timings differ).
        EXPECT_EQ(untimed(read_summary(full_file)), untimed(read_summary(entry.path()))) << name;
      } else {
        EXPECT_EQ(read_text(full_file), read_text(entry.path())) << "incomplete file " << name;
      }
      if (name.ends_with(".done.csv")) {
        const std::string stem = name.substr(0, name.size() - 9);
        for (const char* ext : {".pose.txt", ".aligned.pcd", ".report.json"})
          EXPECT_TRUE(fs::exists(part + "/" + stem + ext)) << stem << ext;
      }
    }
    const CommandResult r =
        run("batch --resume --model " + kPanel + " --scans " + scans() + " --out " + part);
    EXPECT_EQ(r.status, 4) << r.err;
    expect_same_align_outputs(full, part);
    EXPECT_EQ(untimed(read_summary(full + "/summary.csv")),
              untimed(read_summary(part + "/summary.csv")));
    for (const auto& entry : fs::directory_iterator(part))
      EXPECT_NE(entry.path().filename().string()[0], '.') << "left after resume: " << entry.path();
  }
  // At least one kill must have hit a running batch, or the test checked nothing.
  EXPECT_GT(killed_mid_run, 0);
}

TEST_F(Batch, ShardsCoverEveryInputExactlyOnce) {
  const std::string full = path("shard_full");
  const std::string sharded = path("shard_out");
  ASSERT_EQ(run("batch --model " + kPanel + " --scans " + scans() + " --out " + full).status, 4);
  constexpr int kShards = 3;
  std::map<std::string, int> seen;
  for (int i = 0; i < kShards; ++i) {
    const CommandResult r =
        run("batch --model " + kPanel + " --scans " + scans() + " --out " + sharded + " --shard " +
            std::to_string(i) + "/" + std::to_string(kShards));
    // Shard 2 gets f2 and g_empty (k % 3 == 2), shard 0 f0, f3, g_truncated: both fail one.
    EXPECT_EQ(r.status, i == 1 ? 0 : 4) << i << r.err;
    const auto rows = read_summary(sharded + "/summary.shard-" + std::to_string(i) + "-of-" +
                                   std::to_string(kShards) + ".csv");
    for (const auto& row : rows)
      ++seen[row[0]];
  }
  ASSERT_EQ(seen.size(), kAllFiles.size());
  for (const std::string& file : kAllFiles)
    EXPECT_EQ(seen[scans() + "/" + file], 1) << file;
  expect_same_align_outputs(full, sharded);
}

// A frame whose alignment fails (ICP loses every correspondence: the scan lies far beside the
// panel) is a failed frame: exit 4, its reason in the summary, none of its outputs; the other
// frame is done as usual.
TEST_F(Batch, AFailedAlignmentIsAFailedFrame) {
  const std::string beside = path("beside.pcd");
  const CommandResult synth =
      run("synth --model " + kPanel + " --points 1000 --seed 9 --pose \"0 0 0 1000 0 0\" --out " +
          beside);
  ASSERT_EQ(synth.status, 0) << synth.err;
  const std::string list = path("failing_list.txt");
  std::ofstream(list) << scan("f0") << "\n" << beside << "\n";
  const std::string out = path("failing_out");
  // --no-global: the local run from the identity (the global stage would find this pose).
  const CommandResult r =
      run("batch --no-global --model " + kPanel + " --list " + list + " --out " + out);
  EXPECT_EQ(r.status, 4) << r.err;
  const auto rows = read_summary(out + "/summary.csv");
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0][3], "ok");
  EXPECT_TRUE(fs::exists(out + "/f0.pose.txt"));
  EXPECT_EQ(rows[1][3], "failed");
  EXPECT_EQ(rows[1][8].rfind("alignment failed", 0), 0u) << rows[1][8];
  EXPECT_NE(rows[1][8].find("1000 beyond the model's free edges"), std::string::npos) << rows[1][8];
  for (const char* ext : {".pose.txt", ".aligned.pcd", ".report.json", ".done.csv"})
    EXPECT_FALSE(fs::exists(out + "/beside" + std::string(ext))) << ext;
}

TEST_F(Batch, UsageAndModelErrors) {
  const std::string out = path("usage_out");
  const std::string base = "batch --model " + kPanel + " --out " + out;
  const std::string list = path("list.txt");
  std::ofstream(list) << scan("f0") << "\n";
  EXPECT_EQ(run(base).status, 2) << "neither --scans nor --list";
  EXPECT_EQ(run(base + " --scans " + scans() + " --list " + list).status, 2) << "both";
  for (const char* shard : {"3/3", "1", "a/2", "1/0", "1/2/3", "x1/2"}) {
    const CommandResult r = run(base + " --scans " + scans() + " --shard " + shard);
    EXPECT_EQ(r.status, 2) << shard;
    EXPECT_NE(r.err.find("--shard"), std::string::npos) << r.err;
  }
  EXPECT_EQ(run(base + " --scans " + scans() + " --mode frobnicate").status, 2);
  EXPECT_EQ(run("batch --model " + kPanel + " --scans " + scans() + " --out " + scans()).status, 2)
      << "outputs would land among the inputs";

  const std::string model = path("broken.json");
  std::ofstream(model) << R"({"nurbsreg_model": 1, "surfaces": [{"name": "s", "degree": [3, 3],
    "knots_u": [0, 0, 0, 0, 1, 1, 1, 1], "knots_v": [0, 0, 0, 0, 1, 1, 1, 1],
    "weights": [[1, 1, 1, 1]], "control_points": []}]})";
  const CommandResult bad = run("batch --model " + model + " --list " + list + " --out " + out);
  EXPECT_EQ(bad.status, 3);
  EXPECT_NE(bad.err.find("broken.json"), std::string::npos) << bad.err;
  EXPECT_EQ(run("batch --model " + kPanel + " --scans " + path("missing") + " --out " + out).status,
            3);
  EXPECT_FALSE(fs::exists(out)) << "nothing created with a bad model";
}

TEST_F(Batch, HelpDocumentsTheExitStatus) {
  const CommandResult r = run("batch --help");
  EXPECT_EQ(r.status, 0);
  EXPECT_NE(r.out.find("exit 4"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("--shard"), std::string::npos);
  EXPECT_NE(r.out.find("--resume"), std::string::npos);
}

}  // namespace
}  // namespace nurbsreg::test

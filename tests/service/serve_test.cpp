// End-to-end tests of `nurbsreg serve`: the real server on an ephemeral loopback port, real HTTP
// clients (httplib's), answers compared with the CLI's, and the service's limits. Every server
// is started by its test and killed at its end (ServerProcess); every client call has a
// timeout.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>
#include <sys/syscall.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <thread>
#include <vector>

#include "nurbsreg/io/pose.hpp"
#include "support/run_command.hpp"
#include "support/server_process.hpp"

// After Eigen: glibc's <resolv.h>, which httplib includes, defines a macro `_res` that Eigen
// uses as a parameter name.
#include "support/loopback_client.hpp"
#include "support/source_paths.hpp"
#include "support/test_scale.hpp"

namespace nurbsreg::test {
namespace {

using Json = nlohmann::json;
const std::string kPanel = nurbsreg::test::examples_dir() + "/panel.json";
const std::string kSphere = nurbsreg::test::examples_dir() + "/sphere.json";
constexpr const char* kPcd = "application/octet-stream";
// The larger scan: several projection blocks (16,384 points each), and a frame that takes a
// while; smaller in the sanitizer builds, where it takes minutes on a busy machine.
constexpr int kBigPoints = test_size(60000, 24000);

class Serve : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new ScratchDir("serve");
    // A moved and noisy panel scan (binary PCD), a larger one, and an ascii copy.
    for (const auto& [name, points] : {std::pair{"scan.pcd", 5000}, {"big.pcd", kBigPoints}}) {
      const CommandResult r =
          run_nurbsreg("synth --model " + kPanel + " --points " + std::to_string(points) +
                           " --noise 0.01 --pose \"0.02 -0.01 0.03 0.5 -0.3 0.2\" --seed 7 --out " +
                           (*dir_ / name),
                       dir_->path());
      ASSERT_EQ(r.status, 0) << r.err;
    }
    const CommandResult ascii =
        run_nurbsreg("synth --model " + kPanel + " --points 2000 --seed 8 --out " +
                         (*dir_ / "ascii.pcd") + " --noise 0.01",
                     dir_->path());
    ASSERT_EQ(ascii.status, 0) << ascii.err;
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::string path(const std::string& name) { return *dir_ / name; }
  static std::string bytes(const std::string& name) { return read_text(path(name)); }

  static std::unique_ptr<httplib::Client> client(int port) { return loopback_client(port); }
  // The CLI's report for `scan` (`align --report`) with extra options.
  static Json cli_report(const std::string& scan, const std::string& options = "") {
    const std::string report = path("cli_report.json");
    const CommandResult r = run_nurbsreg(
        "align --model " + kPanel + " --scan " + path(scan) + " --report " + report + options,
        dir_->path());
    EXPECT_EQ(r.status, 0) << r.err;
    return Json::parse(read_text(report));
  }
  static void expect_same_alignment(const Json& served, const Json& cli) {
    for (const char* field : {"pose", "rms", "iterations", "converged", "inliers", "points",
                              "skipped_points", "method", "termination"}) {
      EXPECT_EQ(served.at(field), cli.at(field)) << field;
    }
    ASSERT_EQ(served.at("history").size(), cli.at("history").size());
    for (std::size_t k = 0; k < cli.at("history").size(); ++k) {
      for (const char* field : {"rms", "inliers", "rotation_step", "translation_step"}) {
        EXPECT_EQ(served["history"][k].at(field), cli["history"][k].at(field)) << field << k;
      }
    }
  }
  static ScratchDir* dir_;
};
ScratchDir* Serve::dir_ = nullptr;

TEST_F(Serve, AlignAndProjectAnswerAsTheCli) {
  ServerProcess server("--model " + kPanel, path("log_equal.txt"));
  ASSERT_GT(server.port(), 0) << read_text(path("log_equal.txt"));
  auto c = client(server.port());
  const auto health = c->Get("/healthz");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  const auto models = c->Get("/v1/models");
  ASSERT_TRUE(models);
  EXPECT_EQ(Json::parse(models->body).at(0).at("id"), "panel");

  // Without init: from the identity, as `align` without --init.
  const auto aligned = c->Post("/v1/align?model=panel", bytes("scan.pcd"), kPcd);
  ASSERT_TRUE(aligned);
  ASSERT_EQ(aligned->status, 200) << aligned->body;
  expect_same_alignment(Json::parse(aligned->body), cli_report("scan.pcd"));

  // With init (16 numbers, row-major) against `align --init` of the same matrix, and an ICP
  // override against the same CLI option.
  Eigen::Matrix4d init = Eigen::Matrix4d::Identity();
  init(0, 3) = 0.4;
  init(1, 3) = -0.2;
  io::write_pose(path("init.txt"), init);
  std::string numbers;
  for (int r = 0; r < 4; ++r) {
    for (int k = 0; k < 4; ++k)
      numbers += (numbers.empty() ? "" : ",") + std::to_string(init(r, k));
  }
  const auto with_init = c->Post(("/v1/align?model=panel&max_iterations=7&init=" + numbers).c_str(),
                                 bytes("scan.pcd"), kPcd);
  ASSERT_TRUE(with_init);
  ASSERT_EQ(with_init->status, 200) << with_init->body;
  expect_same_alignment(Json::parse(with_init->body),
                        cli_report("scan.pcd", " --max-iterations 7 --init " + path("init.txt")));

  // Projection: the CSV bytes of `project --out r.csv`, for a binary and an ascii PCD body.
  for (const auto& [scan, type] : {std::pair{"scan.pcd", kPcd}, {"ascii.pcd", "text/plain"}}) {
    const auto projected = c->Post("/v1/project?model=panel", bytes(scan), type);
    ASSERT_TRUE(projected);
    ASSERT_EQ(projected->status, 200) << projected->body;
    const CommandResult r = run_nurbsreg(
        "project --model " + kPanel + " --points " + path(scan) + " --out " + path("cli.csv"),
        dir_->path());
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(projected->body, read_text(path("cli.csv"))) << scan;
    EXPECT_EQ(projected->get_header_value("Content-Type"), "text/csv");
    EXPECT_FALSE(projected->has_header("X-Warning")) << projected->get_header_value("X-Warning");
  }
  // Points of the panel's size 5 m above it (not in the model's frame): `project`'s warning as
  // a header, the rows as asked.
  {
    std::string far;
    for (int i = 0; i < 20; ++i) {
      for (int j = 0; j < 20; ++j) {
        const float xyz[3] = {5.0f * i, 5.0f * j, 5000.0f};
        far.append(reinterpret_cast<const char*>(xyz), sizeof xyz);
      }
    }
    const auto moved =
        c->Post("/v1/project?model=panel", far, "application/x-nurbsreg-xyz-float32");
    ASSERT_TRUE(moved);
    ASSERT_EQ(moved->status, 200) << moved->body;
    EXPECT_NE(moved->get_header_value("X-Warning").find("points: half of the points lie"),
              std::string::npos)
        << moved->get_header_value("X-Warning");
  }

  const auto metrics = c->Get("/metrics");
  ASSERT_TRUE(metrics);
  EXPECT_NE(metrics->body.find("nurbsreg_requests_total{endpoint=\"align\",status=\"200\"} 2"),
            std::string::npos)
      << metrics->body;
  EXPECT_NE(metrics->body.find("nurbsreg_points_total{endpoint=\"project\"} 7400"),
            std::string::npos);
  EXPECT_EQ(server.terminate(30), 0);
}

// A served model's features come through the features cache (README "Caches"), with the same
// settings as the CLI's: the first server stores them, a corrupt entry is rebuilt with a
// warning naming it, and a frame from any pose is the CLI's either way.
TEST_F(Serve, ModelFeaturesComeThroughTheFeaturesCache) {
  const Json cli = cli_report("scan.pcd");  // before the variable: the CLI stores nothing there
  const std::string cache = path("features-cache");
  // The servers inherit the variable; restored whatever the test's outcome.
  struct ScopedCacheDir {
    std::optional<std::string> before;
    explicit ScopedCacheDir(const std::string& dir) {
      if (const char* v = std::getenv("NURBSREG_CACHE_DIR")) before = v;
      ::setenv("NURBSREG_CACHE_DIR", dir.c_str(), 1);
    }
    ~ScopedCacheDir() {
      if (before) {
        ::setenv("NURBSREG_CACHE_DIR", before->c_str(), 1);
      } else {
        ::unsetenv("NURBSREG_CACHE_DIR");
      }
    }
  } scoped(cache);
  const auto entries = [&] {
    std::vector<std::filesystem::path> out;
    std::error_code ec;
    for (const auto& e : std::filesystem::directory_iterator(cache, ec))
      if (e.path().extension() == ".nrbfeat") out.push_back(e.path());
    return out;
  };
  // Stored, then rebuilt from a corrupt entry; `nurbsreg --no-cache serve` reads and writes no
  // entry (the service once read only the environment and stored them whatever the flag said).
  for (const std::string run : {"stored", "rebuilt", "off"}) {
    if (run == "off") std::filesystem::remove_all(cache);
    const std::string log = path("log_cache_" + run + ".txt");
    ServerProcess server("--model " + kPanel, log, run == "off" ? "--no-cache" : "");
    ASSERT_GT(server.port(), 0) << read_text(log);
    const auto aligned =
        client(server.port())->Post("/v1/align?model=panel", bytes("scan.pcd"), kPcd);
    ASSERT_TRUE(aligned);
    ASSERT_EQ(aligned->status, 200) << aligned->body;
    expect_same_alignment(Json::parse(aligned->body), cli);
    const std::vector<std::filesystem::path> stored = entries();
    if (run == "off") {
      EXPECT_TRUE(stored.empty());
      continue;
    }
    ASSERT_EQ(stored.size(), 1u) << run;
    if (run == "stored") {
      EXPECT_EQ(read_text(log).find("warning"), std::string::npos) << read_text(log);
      std::fstream f(stored[0], std::ios::in | std::ios::out | std::ios::binary);
      f.seekp(static_cast<std::streamoff>(std::filesystem::file_size(stored[0]) / 2));
      f.put('\x7f');
    } else {
      EXPECT_NE(read_text(log).find(stored[0].string() + " is not usable"), std::string::npos)
          << read_text(log);
    }
  }
}

TEST_F(Serve, CurlAsInTheReadme) {
  ServerProcess server("--model " + kPanel, path("log_curl.txt"));
  ASSERT_GT(server.port(), 0);
  const std::string url = "http://127.0.0.1:" + std::to_string(server.port());
  // Expect: 100-continue, as curl sends by itself for bodies over 1 MB.
  const std::string out = path("curl_answer.json");
  const std::string command =
      "curl -s --max-time " + std::to_string(test_size(120, 900)) + " -o " + out +
      " -w '%{http_code}' " + "-H 'Expect: 100-continue' -X POST --data-binary @" +
      path("big.pcd") + " -H 'Content-Type: application/octet-stream' '" + url +
      "/v1/align?model=panel&session=cam1' > " + path("curl_status.txt");
  ASSERT_EQ(std::system(command.c_str()), 0);
  EXPECT_EQ(read_text(path("curl_status.txt")), "200");
  const Json answer = Json::parse(read_text(out));
  EXPECT_EQ(answer.at("session"), "cam1");
  EXPECT_EQ(answer.at("points"), kBigPoints);
  EXPECT_EQ(answer.at("converged"), true);
}

TEST_F(Serve, BadRequestsGetAnErrorNamingTheProblem) {
  ServerProcess server("--model " + kPanel, path("log_bad.txt"));
  ASSERT_GT(server.port(), 0);
  auto c = client(server.port());
  const std::string scan = bytes("scan.pcd");
  const auto error_of = [&](const httplib::Result& r, int status) {
    EXPECT_TRUE(r);
    if (!r) return std::string();
    EXPECT_EQ(r->status, status) << r->body;
    EXPECT_EQ(r->get_header_value("Content-Type"), "application/json");
    return Json::parse(r->body).at("error").get<std::string>();
  };
  EXPECT_NE(
      error_of(c->Post("/v1/align?model=panel", scan.substr(0, 2000), kPcd), 400).find("truncated"),
      std::string::npos);
  EXPECT_NE(error_of(c->Post("/v1/align?model=panel", scan, "image/png"), 400)
                .find("Content-Type \"image/png\""),
            std::string::npos);
  EXPECT_NE(error_of(c->Post("/v1/align?model=hood", scan, kPcd), 404).find("\"hood\""),
            std::string::npos);
  EXPECT_NE(error_of(c->Post("/v1/align", scan, kPcd), 400).find("model"), std::string::npos);
  EXPECT_NE(error_of(c->Post("/v1/align?model=panel&init=1,0,0", scan, kPcd), 400).find("init"),
            std::string::npos);
  EXPECT_NE(
      error_of(c->Post("/v1/align?model=panel&init=2,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1", scan, kPcd),
               400)
          .find("orthonormal"),
      std::string::npos);
  EXPECT_NE(error_of(c->Post("/v1/align?model=panel&max_iterations=x", scan, kPcd), 400)
                .find("max_iterations"),
            std::string::npos);
  EXPECT_NE(error_of(c->Post("/v1/align?model=panel&max_iterations=100000", scan, kPcd), 400)
                .find("at most 50"),
            std::string::npos);
  EXPECT_NE(error_of(c->Post("/v1/align?model=panel", "", kPcd), 400).find("request body"),
            std::string::npos);
  EXPECT_NE(
      error_of(c->Post("/v1/project?model=panel&target=curves", scan, kPcd), 400).find("no curves"),
      std::string::npos);
  EXPECT_NE(error_of(c->Get("/v2/nothing"), 404).find("no such endpoint"), std::string::npos);
  // The service is still there and still right after all of that.
  const auto ok = c->Post("/v1/align?model=panel", scan, kPcd);
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->status, 200);
}

TEST_F(Serve, SessionsStartFromThePreviousPose) {
  ServerProcess server("--model " + kPanel + " --model " + kSphere + " --max-sessions 2",
                       path("log_sessions.txt"));
  ASSERT_GT(server.port(), 0);
  auto c = client(server.port());
  const std::string scan = bytes("scan.pcd");
  // The first frame from the identity (without init it would start from the global stage's
  // pose, already close), the second from the session's converged pose.
  const auto first = c->Post(
      "/v1/align?model=panel&session=cam-1&init=1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1", scan, kPcd);
  ASSERT_TRUE(first);
  ASSERT_EQ(first->status, 200) << first->body;
  const Json a = Json::parse(first->body);
  EXPECT_EQ(a.at("frame"), 1);
  EXPECT_EQ(a.at("init"), "request");
  const auto second = c->Post("/v1/align?model=panel&session=cam-1", scan, kPcd);
  ASSERT_TRUE(second);
  ASSERT_EQ(second->status, 200);
  const Json b = Json::parse(second->body);
  EXPECT_EQ(b.at("frame"), 2);
  EXPECT_EQ(b.at("init"), "session");
  // From the converged pose the same frame needs no more iterations, and its first iteration's
  // RMS is already the converged one's order (not the identity's).
  EXPECT_LE(b.at("iterations").get<int>(), a.at("iterations").get<int>());
  EXPECT_LT(b["history"][0]["rms"].get<double>(), 0.5 * a["history"][0]["rms"].get<double>());
  // The second frame borrowed the first's certificates (README "Sessions"): exact, so it is
  // `align --init <first pose>` of a fresh process up to the last bits of the feet.
  Eigen::Matrix4d first_pose;
  for (int r = 0; r < 4; ++r) {
    for (int k = 0; k < 4; ++k)
      first_pose(r, k) = a.at("pose").at(r).at(k).get<double>();
  }
  io::write_pose(path("session_init.txt"), first_pose);
  const Json cli = cli_report("scan.pcd", " --init " + path("session_init.txt"));
  EXPECT_EQ(b.at("iterations"), cli.at("iterations"));
  EXPECT_EQ(b.at("inliers"), cli.at("inliers"));
  EXPECT_NEAR(b.at("rms").get<double>(), cli.at("rms").get<double>(), 1e-12);
  for (int r = 0; r < 4; ++r) {
    for (int k = 0; k < 4; ++k) {
      EXPECT_NEAR(b.at("pose").at(r).at(k).get<double>(), cli.at("pose").at(r).at(k).get<double>(),
                  1e-9)
          << r << k;
    }
  }
  // A session belongs to its model.
  const auto other = c->Post("/v1/align?model=sphere&session=cam-1", scan, kPcd);
  ASSERT_TRUE(other);
  EXPECT_EQ(other->status, 409);
  // Bounded: a third session evicts the least recently used idle one (cam-1 starts afresh).
  for (const char* id : {"cam-2", "cam-3"}) {
    const auto r =
        c->Post((std::string("/v1/align?model=panel&session=") + id).c_str(), scan, kPcd);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200);
  }
  const auto again = c->Post("/v1/align?model=panel&session=cam-1", scan, kPcd);
  ASSERT_TRUE(again);
  EXPECT_EQ(Json::parse(again->body).at("frame"), 1);
  const auto metrics = c->Get("/metrics");
  ASSERT_TRUE(metrics);
  EXPECT_NE(metrics->body.find("nurbsreg_sessions 2"), std::string::npos);
}

TEST_F(Serve, ConcurrentClientsGetTheSerialAnswer) {
  ServerProcess server("--model " + kPanel + " --max-inflight 8", path("log_concurrent.txt"));
  ASSERT_GT(server.port(), 0);
  const std::string scan = bytes("scan.pcd");
  const auto serial = client(server.port())->Post("/v1/align?model=panel", scan, kPcd);
  ASSERT_TRUE(serial);
  ASSERT_EQ(serial->status, 200) << serial->body;
  const Json expected = Json::parse(serial->body);
  constexpr int kClients = 4, kFrames = 3;
  std::vector<std::string> answers(kClients * kFrames);
  std::vector<int> statuses(kClients * kFrames, -1);
  std::vector<std::thread> clients;
  for (int t = 0; t < kClients; ++t) {
    clients.emplace_back([&, t] {
      auto c = client(server.port());
      for (int f = 0; f < kFrames; ++f) {
        const auto r = c->Post("/v1/align?model=panel", scan, kPcd);
        if (!r) continue;
        statuses[t * kFrames + f] = r->status;
        answers[t * kFrames + f] = r->body;
      }
    });
  }
  for (std::thread& t : clients)
    t.join();
  for (std::size_t k = 0; k < answers.size(); ++k) {
    ASSERT_EQ(statuses[k], 200) << answers[k];
    const Json j = Json::parse(answers[k]);
    EXPECT_EQ(j.at("pose"), expected.at("pose"));
    EXPECT_EQ(j.at("rms"), expected.at("rms"));
  }
}

TEST_F(Serve, OverloadIs503WithRetryAfterAndBigBodiesAre413) {
  const std::string scan = bytes("big.pcd");  // under the limit; twice it is over
  ServerProcess server(
      "--model " + kPanel + " --max-inflight 1 --max-body " + std::to_string(scan.size() * 3 / 2),
      path("log_overload.txt"));
  ASSERT_GT(server.port(), 0);
  constexpr int kClients = 6;
  std::vector<int> statuses(kClients, -1);
  std::vector<std::string> retry_after(kClients);
  std::vector<std::thread> clients;
  for (int t = 0; t < kClients; ++t) {
    clients.emplace_back([&, t] {
      const auto r = client(server.port())->Post("/v1/align?model=panel", scan, kPcd);
      if (!r) return;
      statuses[t] = r->status;
      retry_after[t] = r->get_header_value("Retry-After");
    });
  }
  for (std::thread& t : clients)
    t.join();
  int ok = 0, busy = 0;
  for (int t = 0; t < kClients; ++t) {
    EXPECT_TRUE(statuses[t] == 200 || statuses[t] == 503) << statuses[t];
    if (statuses[t] == 200) ++ok;
    if (statuses[t] == 503) {
      ++busy;
      EXPECT_EQ(retry_after[t], "1");
    }
  }
  EXPECT_GE(ok, 1);
  EXPECT_GE(busy, 1);
  // Over --max-body: 413 from Content-Length, and the connection's next request still works.
  auto c = client(server.port());
  const auto big = c->Post("/v1/align?model=panel", scan + scan, kPcd);
  ASSERT_TRUE(big);
  EXPECT_EQ(big->status, 413);
  EXPECT_NE(big->body.find("--max-body"), std::string::npos);
  const auto health = client(server.port())->Get("/healthz");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
}

TEST_F(Serve, TokenIsRequiredWhenSet) {
  std::ofstream(path("token.txt")) << "s3cret-token\n";
  ServerProcess server("--model " + kPanel + " --token-file " + path("token.txt"),
                       path("log_token.txt"));
  ASSERT_GT(server.port(), 0);
  auto c = client(server.port());
  const std::string scan = bytes("scan.pcd");
  const auto none = c->Post("/v1/align?model=panel", scan, kPcd);
  ASSERT_TRUE(none);
  EXPECT_EQ(none->status, 401);
  const auto models = c->Get("/v1/models");
  ASSERT_TRUE(models);
  EXPECT_EQ(models->status, 401);
  const auto wrong =
      c->Post("/v1/align?model=panel", {{"Authorization", "Bearer s3cret-tokeX"}}, scan, kPcd);
  ASSERT_TRUE(wrong);
  EXPECT_EQ(wrong->status, 401);
  const auto right =
      c->Post("/v1/align?model=panel", {{"Authorization", "Bearer s3cret-token"}}, scan, kPcd);
  ASSERT_TRUE(right);
  EXPECT_EQ(right->status, 200) << right->body;
  const auto health = c->Get("/healthz");  // probes need no token
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
}

TEST_F(Serve, ModelsLoadFromBelowTheRootOnly) {
  namespace fs = std::filesystem;
  const fs::path root = fs::path(path("root"));
  fs::create_directories(root / "parts");
  fs::copy_file(kPanel, root / "parts" / "door.json", fs::copy_options::overwrite_existing);
  fs::copy_file(kSphere, path("outside.json"), fs::copy_options::overwrite_existing);
  fs::remove(root / "parts" / "escape.json");
  fs::create_symlink(path("outside.json"), root / "parts" / "escape.json");
  ServerProcess server("--model " + kPanel + " --model-root " + root.string(),
                       path("log_root.txt"));
  ASSERT_GT(server.port(), 0);
  auto c = client(server.port());
  const auto load = [&](const std::string& body) {
    return c->Post("/v1/models", body, "application/json");
  };
  for (const std::string& bad :
       {std::string("../outside.json"), std::string("parts/../../outside.json"),
        path("outside.json"), std::string("parts/escape.json"), std::string("/etc/passwd")}) {
    const auto r = load(Json{{"path", bad}}.dump());
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 403) << bad << ": " << r->body;
  }
  const auto missing = load(Json{{"path", "parts/none.json"}}.dump());
  ASSERT_TRUE(missing);
  EXPECT_EQ(missing->status, 404);
  const auto good = load(Json{{"path", "parts/door.json"}, {"id", "door"}}.dump());
  ASSERT_TRUE(good);
  ASSERT_EQ(good->status, 201) << good->body;
  const auto aligned = c->Post("/v1/align?model=door", bytes("scan.pcd"), kPcd);
  ASSERT_TRUE(aligned);
  EXPECT_EQ(aligned->status, 200);
  const auto twice = load(Json{{"path", "parts/door.json"}, {"id", "door"}}.dump());
  ASSERT_TRUE(twice);
  EXPECT_EQ(twice->status, 409);
}

TEST_F(Serve, SigtermAnswersTheRequestsInFlightAndExitsZero) {
  ServerProcess server("--model " + kPanel + " --max-inflight 4", path("log_term.txt"));
  ASSERT_GT(server.port(), 0);
  const std::string scan = bytes("big.pcd");
  constexpr int kClients = 3;
  std::vector<int> statuses(kClients, -1);
  std::vector<std::thread> clients;
  for (int t = 0; t < kClients; ++t) {
    clients.emplace_back([&, t] {
      const auto r = client(server.port())->Post("/v1/align?model=panel", scan, kPcd);
      if (r) statuses[t] = r->status;
    });
  }
  // Wait until all three frames are being computed (accepted: their bodies have been read).
  auto c = client(server.port());
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < deadline) {
    const auto m = c->Get("/metrics");
    if (m && m->body.find("nurbsreg_in_flight 3\n") != std::string::npos) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  c.reset();
  const int exit_status = server.terminate(test_size(120, 900));
  for (std::thread& t : clients)
    t.join();
  EXPECT_EQ(exit_status, 0) << read_text(path("log_term.txt"));
  for (int t = 0; t < kClients; ++t)
    EXPECT_EQ(statuses[t], 200) << t;
}

TEST_F(Serve, SigtermClosesIdleKeepAliveConnectionsAtOnce) {
  // Idle keep-alive connections would be kept 600 s: SIGTERM must not wait for them, only for
  // the frame in flight (tens of seconds in the sanitizer builds).
  ServerProcess server("--model " + kPanel + " --keep-alive 600", path("log_idle.txt"));
  ASSERT_GT(server.port(), 0);
  std::vector<std::unique_ptr<httplib::Client>> idle;
  for (int k = 0; k < 3; ++k) {
    idle.push_back(client(server.port()));
    idle.back()->set_keep_alive(true);
    const auto r = idle.back()->Get("/healthz");
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 200);
  }
  // One frame in flight beside them (its body read: nurbsreg_in_flight 1).
  int status = -1;
  std::thread busy([&] {
    const auto r = client(server.port())->Post("/v1/align?model=panel", bytes("big.pcd"), kPcd);
    if (r) status = r->status;
  });
  auto c = client(server.port());
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::chrono::steady_clock::now() < deadline) {
    const auto m = c->Get("/metrics");
    if (m && m->body.find("nurbsreg_in_flight 1\n") != std::string::npos) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const auto start = std::chrono::steady_clock::now();
  const double bound = test_size(120.0, 500.0);  // below --keep-alive
  const int exit_status = server.terminate(bound);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  busy.join();
  EXPECT_EQ(exit_status, 0) << read_text(path("log_idle.txt"));
  EXPECT_EQ(status, 200);  // the frame in flight is answered
  EXPECT_LT(seconds, bound);
  // The idle connections were closed: a request on one finds no server.
  const auto after = idle.front()->Get("/healthz");
  EXPECT_FALSE(after);
  EXPECT_NE(read_text(path("log_idle.txt")).find("idle connection(s)"), std::string::npos);
}

// The server's connections have TCP_NODELAY: httplib writes an answer's headers and its body in
// two writes, and with Nagle's algorithm the body waits for the client's delayed acknowledgement
// of the headers (about 40 ms on Linux, a warm frame's whole budget). Read from the server's own
// sockets (pidfd_getfd: the test is the server's parent), not from a round trip's time.
TEST_F(Serve, ConnectionsSendWithoutNaglesDelay) {
  ServerProcess server("--model " + kPanel, path("log_nodelay.txt"));
  ASSERT_GT(server.port(), 0);
  auto c = client(server.port());
  c->set_keep_alive(true);
  const auto r = c->Get("/healthz");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200);

  const int pidfd = static_cast<int>(::syscall(SYS_pidfd_open, server.pid(), 0));
  ASSERT_GE(pidfd, 0) << "pidfd_open: " << std::strerror(errno);
  int connections = 0;
  for (const auto& entry :
       std::filesystem::directory_iterator("/proc/" + std::to_string(server.pid()) + "/fd")) {
    const int fd = static_cast<int>(
        ::syscall(SYS_pidfd_getfd, pidfd, std::atoi(entry.path().filename().c_str()), 0));
    if (fd < 0 && errno == EBADF) continue;  // closed since the listing
    ASSERT_GE(fd, 0) << "pidfd_getfd: " << std::strerror(errno);
    sockaddr_in local{}, peer{};
    socklen_t local_length = sizeof local, peer_length = sizeof peer;
    // The server's accepted connections: its port locally, a peer on the other end.
    if (getsockname(fd, reinterpret_cast<sockaddr*>(&local), &local_length) == 0 &&
        local.sin_family == AF_INET && ntohs(local.sin_port) == server.port() &&
        getpeername(fd, reinterpret_cast<sockaddr*>(&peer), &peer_length) == 0) {
      int nodelay = 0;
      socklen_t length = sizeof nodelay;
      ASSERT_EQ(getsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &nodelay, &length), 0);
      EXPECT_NE(nodelay, 0) << "connection from port " << ntohs(peer.sin_port);
      ++connections;
    }
    ::close(fd);
  }
  ::close(pidfd);
  EXPECT_GE(connections, 1) << "no accepted connection found among the server's descriptors";
}

}  // namespace
}  // namespace nurbsreg::test

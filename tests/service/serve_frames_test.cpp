// End-to-end tests of `nurbsreg serve`'s frame bodies and answers: a raw float32 body answers as
// the PCD body it was cut from, per-point signed distances equal the CLI's, and the time limit
// stops a frame's work with 504 while the service stays up. The real server on an ephemeral
// loopback port (ServerProcess kills it at the test's end); every client call has a timeout.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "nurbsreg/io/point_table.hpp"
#include "support/run_command.hpp"
#include "support/server_process.hpp"
#include "support/test_scale.hpp"

// After Eigen (see serve_test.cpp): glibc's <resolv.h> defines a macro `_res`.
#include "support/loopback_client.hpp"
#include "support/source_paths.hpp"

namespace nurbsreg::test {
namespace {

using Json = nlohmann::json;
const std::string kPanel = nurbsreg::test::examples_dir() + "/panel.json";
constexpr const char* kPcd = "application/octet-stream";
// The larger scan: several projection blocks (16,384 points each), and a frame that takes a
// while; smaller in the sanitizer builds, where it takes minutes on a busy machine.
constexpr int kBigPoints = test_size(60000, 24000);
constexpr const char* kFloat32 = "application/x-nurbsreg-xyz-float32";
const std::string kIdentity = "1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1";

class ServeFrames : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new ScratchDir("serve_frames");
    for (const auto& [name, points] : {std::pair{"scan.pcd", 5000}, {"big.pcd", kBigPoints}}) {
      const CommandResult r = run_nurbsreg(
          "synth --model " + kPanel + " --points " + std::to_string(points) +
              " --noise 0.01 --pose \"0.02 -0.01 0.03 0.5 -0.3 0.2\" --seed 11 --out " +
              (*dir_ / name),
          dir_->path());
      ASSERT_EQ(r.status, 0) << r.err;
    }
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::string path(const std::string& name) { return *dir_ / name; }
  static std::string bytes(const std::string& name) { return read_text(path(name)); }
  static std::unique_ptr<httplib::Client> client(int port) { return loopback_client(port); }
  // The answer without its timings (the only fields two runs of one frame may differ in): every
  // "seconds" and "*_seconds" field but the limit that was asked for.
  static Json without_seconds(Json j) {
    if (j.is_object()) {
      std::vector<std::string> timings;
      for (const auto& [key, value] : j.items()) {
        const bool timing =
            key == "seconds" || (key.ends_with("_seconds") && key != "time_limit_seconds");
        if (timing) timings.push_back(key);
      }
      for (const std::string& key : timings)
        j.erase(key);
      for (auto& [key, value] : j.items())
        value = without_seconds(value);
    } else if (j.is_array()) {
      for (auto& value : j)
        value = without_seconds(value);
    }
    return j;
  }
  static ScratchDir* dir_;
};
ScratchDir* ServeFrames::dir_ = nullptr;

// The point data of a binary PCD whose fields are exactly x y z as float32: the same bytes a raw
// little-endian float32 body carries (x86 and every platform Debian builds this on for it are
// little-endian; checked below).
std::string float32_payload(const std::string& pcd) {
  EXPECT_NE(pcd.find("\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"), std::string::npos);
  const std::string marker = "\nDATA binary\n";
  const std::size_t at = pcd.find(marker);
  EXPECT_NE(at, std::string::npos);
  return pcd.substr(at + marker.size());
}

TEST_F(ServeFrames, RawFloat32BodyAnswersAsThePcdBodyBitForBit) {
  const std::uint32_t one = 1;
  unsigned char first_byte = 0;
  std::memcpy(&first_byte, &one, 1);
  ASSERT_EQ(first_byte, 1) << "the raw body is little-endian: this test needs such a host";
  ServerProcess server("--model " + kPanel, path("log_float32.txt"));
  ASSERT_GT(server.port(), 0) << read_text(path("log_float32.txt"));
  auto c = client(server.port());
  const std::string pcd = bytes("scan.pcd");
  const std::string raw = float32_payload(pcd);
  ASSERT_EQ(raw.size(), 5000u * 12u);

  // From any pose (the global stage, then ICP) and from a given pose.
  for (const std::string& query :
       {std::string("/v1/align?model=panel"), "/v1/align?model=panel&init=" + kIdentity}) {
    const auto from_pcd = c->Post(query.c_str(), pcd, kPcd);
    const auto from_raw = c->Post(query.c_str(), raw, kFloat32);
    ASSERT_TRUE(from_pcd && from_raw);
    ASSERT_EQ(from_pcd->status, 200) << from_pcd->body;
    ASSERT_EQ(from_raw->status, 200) << from_raw->body;
    const Json a = without_seconds(Json::parse(from_pcd->body));
    const Json b = without_seconds(Json::parse(from_raw->body));
    EXPECT_EQ(a.at("points"), 5000);
    EXPECT_EQ(a, b) << query;  // every number, to the last bit (JSON doubles round-trip)
  }
  const auto projected_pcd = c->Post("/v1/project?model=panel", pcd, kPcd);
  const auto projected_raw = c->Post("/v1/project?model=panel", raw, kFloat32);
  ASSERT_TRUE(projected_pcd && projected_raw);
  ASSERT_EQ(projected_raw->status, 200) << projected_raw->body;
  EXPECT_EQ(projected_pcd->body, projected_raw->body);

  // A raw body that is not whole points is refused, naming the problem.
  const auto torn = c->Post("/v1/align?model=panel", raw.substr(0, raw.size() - 5), kFloat32);
  ASSERT_TRUE(torn);
  EXPECT_EQ(torn->status, 400);
  EXPECT_NE(torn->body.find("request body"), std::string::npos) << torn->body;
}

TEST_F(ServeFrames, SignedDistancesEqualTheClis) {
  ServerProcess server("--model " + kPanel, path("log_distances.txt"));
  ASSERT_GT(server.port(), 0);
  const auto answer =
      client(server.port())->Post("/v1/align?model=panel&distances=true", bytes("scan.pcd"), kPcd);
  ASSERT_TRUE(answer);
  ASSERT_EQ(answer->status, 200) << answer->body;
  const Json served = Json::parse(answer->body).at("signed_distances");

  // `align --aligned A.pcd` writes each point's signed distance (float32) at the same pose.
  const CommandResult r = run_nurbsreg("align --model " + kPanel + " --scan " + path("scan.pcd") +
                                           " --aligned " + path("aligned.pcd"),
                                       dir_->path());
  ASSERT_EQ(r.status, 0) << r.err;
  const io::PointTable table = io::read_point_table(path("aligned.pcd"));
  const std::vector<float>* cli = table.values<float>("signed_distance");
  const std::vector<std::uint64_t>* index = table.values<std::uint64_t>("index");
  ASSERT_TRUE(cli && index);
  ASSERT_EQ(served.size(), cli->size());
  double largest = 0.0;
  int negative = 0;
  for (std::size_t i = 0; i < cli->size(); ++i) {
    ASSERT_EQ((*index)[i], i);
    const double d = served[i].get<double>();
    EXPECT_EQ(static_cast<float>(d), (*cli)[i]) << "point " << i;
    largest = std::max(largest, std::abs(d));
    negative += d < 0.0;
  }
  // Noisy points lie on both sides of the surface: the distances are signed, not zero.
  EXPECT_GT(largest, 0.005);
  EXPECT_GT(negative, 500);
  EXPECT_LT(negative, 4500);
}

// The service asks for every point's exact projection only when the answer carries per-point
// distances (as `align` only with --aligned): the report is the same either way, and with a
// distance bound the points beyond it still get their exact signed distance when asked for.
TEST_F(ServeFrames, DistancesBeyondTheBoundAreExactAndTheReportIsTheSame) {
  ServerProcess server("--model " + kPanel, path("log_bounded.txt"));
  ASSERT_GT(server.port(), 0);
  auto c = client(server.port());
  // A bound below the scan's noise (0.01): about 40% of the points lie beyond it, and a few
  // beyond the verdict's tolerance (3 noise) too. From any pose: the global stage, then ICP.
  const std::string query = "/v1/align?model=panel&max_distance=0.008";
  const auto plain = c->Post(query.c_str(), bytes("scan.pcd"), kPcd);
  const auto with = c->Post((query + "&distances=true").c_str(), bytes("scan.pcd"), kPcd);
  ASSERT_TRUE(plain && with);
  ASSERT_EQ(plain->status, 200) << plain->body;
  ASSERT_EQ(with->status, 200) << with->body;
  Json a = without_seconds(Json::parse(plain->body));
  Json b = without_seconds(Json::parse(with->body));
  const Json distances = b.at("signed_distances");
  b.erase("signed_distances");
  EXPECT_EQ(a, b);
  ASSERT_EQ(distances.size(), 5000u);
  int beyond = 0;
  for (const Json& d : distances) {
    ASSERT_TRUE(d.is_number()) << d;  // NaN (null) would be a point left unprojected
    beyond += std::abs(d.get<double>()) > 0.008;
  }
  EXPECT_GT(beyond, 1000);
  EXPECT_EQ(server.terminate(30), 0);
}

TEST_F(ServeFrames, TimeLimitStopsTheWorkWith504AndTheServiceStaysUp) {
  // The server's limit, above the full frames' time (the sanitizer builds' too).
  const int limit = test_size(30, 600);
  ServerProcess server("--model " + kPanel + " --time-limit " + std::to_string(limit),
                       path("log_limit.txt"));
  ASSERT_GT(server.port(), 0);
  auto c = client(server.port());
  const std::string big = bytes("big.pcd");
  const auto timed_out = [&](const std::string& query, const char* says) {
    const auto r = c->Post(query.c_str(), big, kPcd);
    EXPECT_TRUE(r);
    if (!r) return Json();
    EXPECT_EQ(r->status, 504) << r->body;
    EXPECT_EQ(r->get_header_value("Content-Type"), "application/json");
    const Json j = Json::parse(r->body);
    const std::string error = j.at("error");
    EXPECT_NE(error.find(says), std::string::npos) << error;
    EXPECT_NE(error.find("time_limit 1e-09 s"), std::string::npos) << error;
    EXPECT_EQ(j.at("time_limit_seconds"), 1e-9);
    EXPECT_EQ(j.at("iterations"), 0);
    return j;
  };
  // One full frame first: the server's one-time work (the model's features, its first
  // allocations) is not counted in a limited frame's time below.
  const auto warm_up = c->Post("/v1/align?model=panel", big, kPcd);
  ASSERT_TRUE(warm_up);
  ASSERT_EQ(warm_up->status, 200) << warm_up->body;
  // A limit that has passed before ICP's first iteration (1 ns after the body is in): no
  // iteration runs, from a given pose and from any pose (the coarse stage stops at its first
  // check).
  const Json icp = timed_out("/v1/align?model=panel&time_limit=1e-9&init=" + kIdentity,
                             "time limit exceeded after 0 iterations");
  const Json global =
      timed_out("/v1/align?model=panel&time_limit=1e-9", "time limit exceeded in the global");

  // The same frames without a limit, on the same connection: the service is up and answers them
  // in full. The limited ICP frame ran no iteration (above); its time is not compared with the
  // full one's, whose few iterations on this scan are about as long as reading the body (on a
  // loaded machine the limited one took 0.134 s against 0.124 s). The global stage is long
  // enough that the limited one must take clearly less.
  const auto full_icp = c->Post(("/v1/align?model=panel&init=" + kIdentity).c_str(), big, kPcd);
  ASSERT_TRUE(full_icp);
  ASSERT_EQ(full_icp->status, 200) << full_icp->body;
  const Json a = Json::parse(full_icp->body);
  EXPECT_GT(a.at("iterations").get<int>(), 2);
  const auto full_global = c->Post("/v1/align?model=panel", big, kPcd);
  ASSERT_TRUE(full_global);
  ASSERT_EQ(full_global->status, 200) << full_global->body;
  EXPECT_LT(global.at("seconds").get<double>(),
            0.5 * Json::parse(full_global->body).at("seconds").get<double>());

  // A frame may tighten the server's limit, not loosen it.
  const auto looser =
      c->Post(("/v1/align?model=panel&time_limit=" + std::to_string(limit + 1)).c_str(), big, kPcd);
  ASSERT_TRUE(looser);
  EXPECT_EQ(looser->status, 400);
  EXPECT_NE(looser->body.find("--time-limit"), std::string::npos) << looser->body;
  const auto health = c->Get("/healthz");
  ASSERT_TRUE(health);
  EXPECT_EQ(health->status, 200);
  const auto metrics = c->Get("/metrics");
  ASSERT_TRUE(metrics);
  EXPECT_NE(metrics->body.find("nurbsreg_requests_total{endpoint=\"align\",status=\"504\"} 2"),
            std::string::npos)
      << metrics->body;
  EXPECT_EQ(server.terminate(30), 0);
}

TEST_F(ServeFrames, TimeLimitStopsAProjectionWith504AndTheServiceStaysUp) {
  ServerProcess server("--model " + kPanel + " --time-limit 30", path("log_project_limit.txt"));
  ASSERT_GT(server.port(), 0);
  auto c = client(server.port());
  const std::string big = bytes("big.pcd");
  // A limit that has passed before the first block (1 ns after the body is in), and one that
  // passes during the projection (1 ms: a block of 16,384 cold projections takes longer; on a
  // loaded machine it may also pass before the first block). Both stop at a block boundary.
  for (const char* limit : {"1e-09", "0.001"}) {
    const auto r =
        c->Post((std::string("/v1/project?model=panel&time_limit=") + limit).c_str(), big, kPcd);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 504) << r->body;
    EXPECT_EQ(r->get_header_value("Content-Type"), "application/json");
    const Json j = Json::parse(r->body);
    const std::string error = j.at("error");
    EXPECT_NE(error.find("time limit exceeded after "), std::string::npos) << error;
    EXPECT_NE(error.find(std::string("time_limit ") + limit + " s"), std::string::npos) << error;
    EXPECT_EQ(j.at("points"), kBigPoints);
    const std::size_t done = j.at("projected_points");
    EXPECT_LT(done, static_cast<std::size_t>(kBigPoints));
    EXPECT_EQ(done % 16384, 0u);
    if (std::string(limit) == "1e-09") {
      EXPECT_EQ(done, 0u);
    }
  }
  // The same body without a limit on the same connection: answered in full, as the CLI does.
  const auto full = c->Post("/v1/project?model=panel", big, kPcd);
  ASSERT_TRUE(full);
  ASSERT_EQ(full->status, 200) << full->body.substr(0, 200);
  const CommandResult r = run_nurbsreg("project --model " + kPanel + " --points " +
                                           path("big.pcd") + " --out " + path("big_cli.csv"),
                                       dir_->path());
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(full->body == read_text(path("big_cli.csv")));
  // A request may tighten the server's limit, not loosen it.
  const auto looser = c->Post("/v1/project?model=panel&time_limit=31", big, kPcd);
  ASSERT_TRUE(looser);
  EXPECT_EQ(looser->status, 400);
  const auto metrics = c->Get("/metrics");
  ASSERT_TRUE(metrics);
  EXPECT_NE(metrics->body.find("nurbsreg_requests_total{endpoint=\"project\",status=\"504\"} 2"),
            std::string::npos)
      << metrics->body;
  EXPECT_EQ(server.terminate(30), 0);
}

}  // namespace
}  // namespace nurbsreg::test

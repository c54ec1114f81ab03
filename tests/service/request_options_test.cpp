// The request options the service parses before reading a body: poses, ids, content types and
// model paths under the root (traversal and symbolic links).
#include "nurbsreg/service/request_options.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "nurbsreg/io/pose.hpp"
#include "support/run_command.hpp"

namespace nurbsreg::service {
namespace {

TEST(RequestOptions, InitPoseIsReadLikeAPoseFile) {
  const Eigen::Matrix4d T = parse_init_pose("1,0,0,5, 0,1,0,-2, 0,0,1,0.5, 0,0,0,1");
  EXPECT_EQ(T, io::parse_pose("1 0 0 5\n0 1 0 -2\n0 0 1 0.5\n0 0 0 1\n", "x"));
  EXPECT_THROW(parse_init_pose("1,0,0"), std::invalid_argument);
  EXPECT_THROW(parse_init_pose("1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1,7"), std::invalid_argument);
  EXPECT_THROW(parse_init_pose("1,0,0,0,0,1,0,0,0,0,1,0,0,0,,1"), std::invalid_argument);
  EXPECT_THROW(parse_init_pose("1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,nan"), std::invalid_argument);
  EXPECT_THROW(parse_init_pose("2,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1"), std::invalid_argument);
}

TEST(RequestOptions, TimeLimitIsPositiveAndAtMostTheServers) {
  EXPECT_EQ(parse_time_limit("0.25", 30.0), 0.25);
  EXPECT_EQ(parse_time_limit("1e-9", 30.0), 1e-9);
  EXPECT_EQ(parse_time_limit("30", 30.0), 30.0);
  for (const char* bad : {"0", "-1", "nan", "inf", "", "1s", "x"})
    EXPECT_THROW(parse_time_limit(bad, 30.0), std::invalid_argument) << bad;
  try {
    parse_time_limit("31", 30.0);
    ADD_FAILURE() << "31 s accepted above a 30 s server limit";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--time-limit"), std::string::npos) << e.what();
  }
}

TEST(RequestOptions, IdsAndContentTypes) {
  EXPECT_EQ(parse_session_id("cam-1.left_2"), "cam-1.left_2");
  EXPECT_THROW(parse_session_id(""), std::invalid_argument);
  EXPECT_THROW(parse_session_id("a/b"), std::invalid_argument);
  EXPECT_THROW(parse_session_id(std::string(65, 'a')), std::invalid_argument);
  EXPECT_EQ(encoding_for_content_type("application/octet-stream", "# .PCD v0.7"),
            io::CloudEncoding::pcd);
  EXPECT_EQ(encoding_for_content_type("Text/Plain; charset=utf-8", "ply\nformat ascii 1.0"),
            io::CloudEncoding::ply);
  EXPECT_EQ(encoding_for_content_type("application/x-nurbsreg-xyz-float32", ""),
            io::CloudEncoding::float32_xyz);
  EXPECT_FALSE(encoding_for_content_type("application/json", "{}"));
  EXPECT_FALSE(is_cloud_content_type(""));
}

TEST(RequestOptions, IcpOverridesAreValidated) {
  IcpOverrides o;
  o.max_iterations = "7";
  o.method = "point-to-point";
  const icp::IcpOptions options = apply_icp_overrides({}, o);
  EXPECT_EQ(options.max_iterations, 7);
  EXPECT_EQ(options.method, icp::IcpMethod::point_to_point);
  o.keep_fraction = "1.5";
  EXPECT_THROW(apply_icp_overrides({}, o), std::invalid_argument);
  o.keep_fraction = "0.9x";
  EXPECT_THROW(apply_icp_overrides({}, o), std::invalid_argument);
}

TEST(RequestOptions, ModelPathsStayUnderTheRoot) {
  namespace fs = std::filesystem;
  test::ScratchDir dir("model-root");
  const fs::path root = fs::canonical(dir.path()) / "root";
  fs::create_directories(root / "sub");
  std::ofstream(root / "sub" / "a.json") << "{}";
  std::ofstream(dir.path() / "secret.json") << "{}";
  fs::create_symlink(dir.path() / "secret.json", root / "link.json");
  fs::create_symlink(root / "sub" / "a.json", root / "inner.json");
  EXPECT_EQ(resolve_under_root(root, "sub/a.json"), root / "sub" / "a.json");
  EXPECT_EQ(resolve_under_root(root, "inner.json"), root / "sub" / "a.json");  // link inside
  EXPECT_EQ(resolve_under_root(root, (root / "sub" / "a.json").string()), root / "sub" / "a.json");
  EXPECT_THROW(resolve_under_root(root, "../secret.json"), RootEscape);
  EXPECT_THROW(resolve_under_root(root, "sub/../../secret.json"), RootEscape);
  EXPECT_THROW(resolve_under_root(root, "link.json"), RootEscape);
  EXPECT_THROW(resolve_under_root(root, (dir.path() / "secret.json").string()), RootEscape);
  EXPECT_THROW(resolve_under_root(root, "."), RootEscape);
  EXPECT_THROW(resolve_under_root(root, "sub"), std::invalid_argument);  // not a file
  EXPECT_THROW(resolve_under_root(root, "none.json"), std::invalid_argument);
  // A sibling directory whose name starts with the root's is outside it.
  fs::create_directories(dir.path() / "root2");
  std::ofstream(dir.path() / "root2" / "b.json") << "{}";
  EXPECT_THROW(resolve_under_root(root, "../root2/b.json"), RootEscape);
}

}  // namespace
}  // namespace nurbsreg::service

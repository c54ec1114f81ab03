// libFuzzer harness: pose files (parse_pose): every accepted pose is rigid and finite.
#include <cmath>
#include <cstdlib>
#include <string_view>

#include "fuzz_support.hpp"
#include "nurbsreg/io/pose.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string label = "pose.txt";
  try {
    const Eigen::Matrix4d T = nurbsreg::io::parse_pose(
        std::string_view(reinterpret_cast<const char*>(data), size), label);
    if (!T.allFinite()) std::abort();
    const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
    if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-9)
      std::abort();
  } catch (const nurbsreg::io::InputError& e) {
    nurbsreg::fuzz::check_message(e, label);
  }
  return 0;
}

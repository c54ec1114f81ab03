#pragma once
// Poses as text (`--init`, `--out-pose`; CONTRACT.md §2 "Poses"): 4 lines of 4 numbers, a rigid
// 4x4 matrix T_model_scan with model_point = T_model_scan * scan_point.
//
// Reading accepts whitespace- or comma-separated numbers, blank lines and `#` comments. The
// matrix must be rigid: last row 0 0 0 1, rotation block orthonormal with determinant +1 to
// within kPoseRigidityTolerance (so poses printed with 6 decimals by other tools still load).
// The accepted rotation is then replaced by the nearest exact rotation (SVD polar factor,
// Higham 1986), so downstream code can rely on R^T R = I to machine precision. Errors throw
// InputError naming the file and line. Writing prints each number in its shortest exact form.
// Thread-safe; allocates (load-time code).

#include <string>
#include <string_view>

#include <Eigen/Core>

namespace nurbsreg::io {

// Largest accepted |R^T R - I| entry and |det R - 1|, and |last row - (0 0 0 1)| entry.
inline constexpr double kPoseRigidityTolerance = 1e-4;

Eigen::Matrix4d read_pose(const std::string& path);
Eigen::Matrix4d parse_pose(std::string_view text, const std::string& file_label);

// Four lines of four numbers, exact round trip. Does not check rigidity.
std::string pose_to_text(const Eigen::Matrix4d& T_model_scan);
// Writes pose_to_text atomically; throws OutputError if T has non-finite entries or the file
// cannot be written.
void write_pose(const std::string& path, const Eigen::Matrix4d& T_model_scan);

}  // namespace nurbsreg::io

#include "nurbsreg/io/pose.hpp"

#include <Eigen/LU>
#include <Eigen/SVD>
#include <cmath>

#include "nurbsreg/io/atomic_file.hpp"
#include "nurbsreg/io/errors.hpp"
#include "text_io.hpp"

namespace nurbsreg::io {
namespace {

std::string format(double x) {
  std::string s;
  text_detail::append_number(s, x);
  return s;
}

}  // namespace

Eigen::Matrix4d parse_pose(std::string_view text, const std::string& file_label) {
  Eigen::Matrix4d T;
  int row = 0;
  std::size_t line_number = 0;
  std::size_t start = 0;
  while (start <= text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string_view::npos) end = text.size();
    std::string_view line = text.substr(start, end - start);
    start = end + 1;
    ++line_number;
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) {
      line = line.substr(0, hash);
    }
    const std::string where = "line " + std::to_string(line_number);
    // Tokens separated by spaces, tabs, commas or a stray '\r' (files written on Windows).
    int column = 0;
    std::size_t pos = 0;
    while (pos < line.size()) {
      const std::size_t token_start = line.find_first_not_of(" \t,\r", pos);
      if (token_start == std::string_view::npos) break;
      std::size_t token_end = line.find_first_of(" \t,\r", token_start);
      if (token_end == std::string_view::npos) token_end = line.size();
      const std::string_view token = line.substr(token_start, token_end - token_start);
      pos = token_end;
      if (row == 4) {
        throw InputError(file_label,
                         where + ": unexpected extra data after the 4 rows of the pose");
      }
      double value = 0.0;
      if (!text_detail::parse_number(token, value) || !std::isfinite(value)) {
        // Quoted with control bytes escaped: the token may be anything (ESC sequences too).
        throw InputError(file_label,
                         where + ": " + text_detail::quote(token) + " is not a finite number");
      }
      if (column == 4) {
        throw InputError(file_label, where + ": expected 4 numbers, got more");
      }
      T(row, column++) = value;
    }
    if (column == 0) continue;  // blank or comment-only line
    if (column != 4) {
      throw InputError(file_label, where + ": expected 4 numbers, got " + std::to_string(column));
    }
    ++row;
  }
  if (row != 4) {
    throw InputError(file_label, "expected 4 lines of 4 numbers (a 4x4 rigid transform), got " +
                                     std::to_string(row) + " line" + (row == 1 ? "" : "s"));
  }

  const Eigen::RowVector4d last_row = T.row(3);
  if ((last_row - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > kPoseRigidityTolerance) {
    throw InputError(file_label, "last row must be 0 0 0 1 for a rigid transform, got " +
                                     format(last_row[0]) + " " + format(last_row[1]) + " " +
                                     format(last_row[2]) + " " + format(last_row[3]));
  }
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const double orthogonality =
      (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (orthogonality > kPoseRigidityTolerance) {
    throw InputError(file_label, "rotation block is not orthonormal (max |R^T R - I| = " +
                                     format(orthogonality) +
                                     "): expected a rigid transform, no scaling or shear");
  }
  const double det = R.determinant();
  if (std::abs(det - 1.0) > kPoseRigidityTolerance) {
    throw InputError(file_label, "rotation block has determinant " + format(det) +
                                     " (a reflection); expected a proper rotation, det = +1");
  }
  // Nearest rotation in the Frobenius norm: R = U V^T from R = U S V^T (Higham 1986, polar
  // decomposition). det(U V^T) = +1 here because det R is close to +1.
  // A rotation that is already orthonormal to rounding is kept as is, so write -> read is exact.
  if (orthogonality > 1e-12) {
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Matrix3d Q = svd.matrixU() * svd.matrixV().transpose();
    // The product of two computed orthogonal factors is orthonormal only to ~10 ulp; one
    // Newton-Schulz step Q <- Q (3I - Q^T Q) / 2 (Higham, Functions of Matrices, 2008, eq. 8.20)
    // squares that error, leaving plain rounding.
    Q = 0.5 * Q * (3.0 * Eigen::Matrix3d::Identity() - Q.transpose() * Q);
    T.topLeftCorner<3, 3>() = Q;
  }
  T.row(3) << 0, 0, 0, 1;
  return T;
}

Eigen::Matrix4d read_pose(const std::string& path) {
  const std::string text = text_detail::read_text_file(path);
  return parse_pose(text, path);
}

std::string pose_to_text(const Eigen::Matrix4d& T_model_scan) {
  std::string out;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) {
      if (c > 0) out += ' ';
      text_detail::append_number(out, T_model_scan(r, c));
    }
    out += '\n';
  }
  return out;
}

void write_pose(const std::string& path, const Eigen::Matrix4d& T_model_scan) {
  if (!T_model_scan.allFinite())
    throw OutputError(path, "refusing to write a pose with NaN or infinite entries");
  const std::string text = pose_to_text(T_model_scan);
  write_atomically(path, [&](std::ostream& out) {
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
  });
}

}  // namespace nurbsreg::io

#pragma once
// What a request says besides its body, parsed and checked before the body is read (so a bad
// option costs no upload): the starting pose, the session id, ICP overrides, the projection
// target, the content type, and a model path under --model-root. Every error is a
// std::invalid_argument whose message names the parameter, returned to the client as
// 400 {"error": "..."}. Thread-safe, no state.

#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "nurbsreg/engine/projection.hpp"
#include "nurbsreg/icp/icp.hpp"
#include "nurbsreg/io/point_cloud_memory.hpp"

namespace nurbsreg::service {

// `init`: 16 numbers, row-major, comma-separated, a rigid T_model_scan. Checked and corrected
// exactly as `align --init` reads its file (io::parse_pose), so both start from the same matrix.
Eigen::Matrix4d parse_init_pose(std::string_view text);

// Session ids: 1 to 64 characters of [A-Za-z0-9._-].
std::string parse_session_id(std::string_view text);

// `time_limit`: seconds (> 0, finite, at most `server_limit`, the server's --time-limit) for
// one frame's computation, counted from when its body has been read: a client's own deadline
// for a frame, which may be tighter than the server's, never looser.
double parse_time_limit(std::string_view text, double server_limit);

// Model ids (the same alphabet), for POST /v1/models.
std::string parse_model_id(std::string_view text);

// The ICP options a request may override, by query parameter, as the CLI spells them: method,
// max_iterations, max_distance, keep_fraction, kernel, kernel_scale. `get` returns a
// parameter's value or nothing. The result is validated.
struct IcpOverrides {
  std::optional<std::string> method, max_iterations, max_distance, keep_fraction, kernel,
      kernel_scale;
  bool empty() const {
    return !method && !max_iterations && !max_distance && !keep_fraction && !kernel &&
           !kernel_scale;
  }
  bool operator==(const IcpOverrides&) const = default;
};
icp::IcpOptions apply_icp_overrides(icp::IcpOptions base, const IcpOverrides& overrides);

engine::ProjectionTarget parse_projection_target(std::string_view text);

// The body's encoding from its Content-Type (parameters such as charset ignored):
// application/octet-stream and text/plain carry PCD or PLY (told apart by the PLY magic, see
// io::sniff_cloud_encoding), application/x-pcd PCD, application/x-ply PLY, and
// application/x-nurbsreg-xyz-float32 raw little-endian float32 x y z. Nothing for anything else.
std::optional<io::CloudEncoding> encoding_for_content_type(std::string_view content_type,
                                                           std::string_view body_start);
// Whether a content type is one of those (checked before the body arrives).
bool is_cloud_content_type(std::string_view content_type);

// A model path that leads outside --model-root (403 rather than 404).
class RootEscape : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// The real path of `requested` (relative to `root`, or absolute) when it names a regular file
// inside `root` after every symbolic link is resolved; RootEscape when it leads outside (by
// "..", an absolute path or a link), std::invalid_argument naming the request for anything else
// (not found, not a regular file). `root` must be canonical.
std::filesystem::path resolve_under_root(const std::filesystem::path& root,
                                         std::string_view requested);

}  // namespace nurbsreg::service

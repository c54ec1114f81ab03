#pragma once
// The checks of fuzz_request (tests/fuzz/README.md): what `nurbsreg serve` parses from a request
// (service/request_options.hpp) and the body decoders it then calls (io::parse_point_cloud: PCD,
// PLY, raw float32).
//
// Input layout, so that one input drives every parser the way one request does: lines
// "name=value" (the request's query parameters and its Content-Type header, names as the
// service spells them) up to the first empty line; everything after it is the body. Checked
// beyond "no crash":
// - an option error is a std::invalid_argument whose message is one printable line naming the
//   parameter (400 {"error": ...}); an accepted pose is rigid and finite, an accepted id is
//   in the id alphabet, accepted ICP overrides pass IcpOptions::validate;
// - is_cloud_content_type agrees with encoding_for_content_type (the service checks the first
//   before the upload and relies on the second after it);
// - a body error is an io::InputError "request body: ..." (printable); an accepted cloud's counts
//   add up and its points are finite; a PCD or PLY body decodes exactly like the same bytes
//   read as a file (point_cloud_memory.hpp promises bit-identical clouds).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "fuzz_support.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/point_cloud.hpp"
#include "nurbsreg/io/point_cloud_memory.hpp"
#include "nurbsreg/service/request_options.hpp"

namespace nurbsreg::fuzz::request {

namespace service = nurbsreg::service;
namespace io = nurbsreg::io;

[[noreturn]] inline void finding(const char* what, std::string_view detail) {
  std::fprintf(stderr, "%s: %.*s\n", what, static_cast<int>(detail.size()), detail.data());
  std::abort();
}

inline void check_printable(std::string_view message) {
  for (const char c : message) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte >= 0x7f) finding("unprintable byte in a message", message);
  }
}

// An option's error: printable, one line, naming `name` first (the service's 400 body).
inline void check_option_error(const std::invalid_argument& e, std::string_view name) {
  const std::string_view what = e.what();
  check_printable(what);
  if (!what.starts_with(std::string(name) + ":")) finding("the error does not name", what);
}

inline bool is_id(std::string_view id) {
  return !id.empty() && id.size() <= 64 && std::all_of(id.begin(), id.end(), [](unsigned char c) {
    return std::isalnum(c) || c == '.' || c == '_' || c == '-';
  });
}

inline void check_pose(const Eigen::Matrix4d& T) {
  if (!T.allFinite()) finding("non-finite init pose", "");
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-9 ||
      R.determinant() < 0) {
    finding("init pose not a rotation", "");
  }
}

// A model-root with one model in it, for the `path` parameter (resolve_under_root).
inline const std::filesystem::path& model_root() {
  static const std::filesystem::path root = [] {
    const std::filesystem::path dir =
        std::filesystem::path(nurbsreg::fuzz::scratch_file("_root")) / "models";
    std::filesystem::create_directories(dir / "sub");
    std::ofstream(dir / "sub" / "a.json") << "{}";
    return std::filesystem::canonical(dir);
  }();
  return root;
}

inline void check_path(std::string_view requested) {
  try {
    const std::filesystem::path real = service::resolve_under_root(model_root(), requested);
    const std::string r = real.string(), root = model_root().string() + "/";
    if (!r.starts_with(root)) finding("a path outside the root was accepted", r);
  } catch (const std::invalid_argument& e) {  // RootEscape included
    const std::string_view what = e.what();
    check_printable(what);
    if (!what.starts_with("path")) finding("the error does not name", what);
  }
}

inline void check_body(const std::string& content_type, const std::string& body) {
  const auto encoding = service::encoding_for_content_type(content_type, body);
  if (encoding.has_value() != service::is_cloud_content_type(content_type)) {
    finding("content-type checks disagree", content_type);
  }
  if (!encoding) return;
  std::optional<io::PointCloud> from_body;
  try {
    from_body = io::parse_point_cloud(body, *encoding, "request body");
    if (from_body->points.size() + from_body->skipped_nonfinite != from_body->total ||
        from_body->source_index.size() != from_body->points.size()) {
      finding("body cloud counts do not add up", "");
    }
    for (const auto& p : from_body->points) {
      if (!p.allFinite()) finding("non-finite point kept", "");
    }
  } catch (const io::InputError& e) {
    check_printable(e.what());
    if (!std::string_view(e.what()).starts_with("request body: ")) {
      finding("the body error does not name the body", e.what());
    }
  }
  if (*encoding == io::CloudEncoding::float32_xyz) return;
  // The same bytes as a file: the same cloud, or an error in both.
  const char* extension = *encoding == io::CloudEncoding::pcd ? ".pcd" : ".ply";
  const auto* bytes = reinterpret_cast<const std::uint8_t*>(body.data());
  const std::string path = nurbsreg::fuzz::write_input(extension, bytes, body.size());
  std::optional<io::PointCloud> from_file;
  try {
    from_file = io::read_point_cloud(path);
  } catch (const io::InputError& e) {
    nurbsreg::fuzz::check_message(e, path);
  }
  if (from_body.has_value() != from_file.has_value()) {
    finding("body and file readers disagree on acceptance", from_body ? "body ok" : "file ok");
  }
  if (from_body &&
      (from_body->points != from_file->points ||
       from_body->source_index != from_file->source_index || from_body->total != from_file->total ||
       from_body->width != from_file->width || from_body->height != from_file->height)) {
    finding("body and file readers decode different clouds", "");
  }
}

// One request (see the layout above) through every parser; aborts on a finding.
inline void check_request(std::string_view input) {
  std::size_t at = 0;
  std::string content_type = "application/octet-stream";
  service::IcpOverrides overrides;
  while (at < input.size()) {
    const std::size_t eol = std::min(input.find('\n', at), input.size());
    const std::string_view line = input.substr(at, eol - at);
    at = eol + 1;
    if (line.empty()) break;
    const std::size_t eq = line.find('=');
    const std::string_view name = line.substr(0, eq);
    const std::string_view value = eq == std::string_view::npos ? "" : line.substr(eq + 1);
    try {
      if (name == "content-type") {
        content_type = std::string(value);
      } else if (name == "init") {
        check_pose(service::parse_init_pose(value));
      } else if (name == "session") {
        if (!is_id(service::parse_session_id(value))) finding("bad session id accepted", value);
      } else if (name == "id") {
        if (!is_id(service::parse_model_id(value))) finding("bad model id accepted", value);
      } else if (name == "target") {
        (void)service::parse_projection_target(value);
      } else if (name == "path") {
        check_path(value);
      } else if (name == "method") {
        overrides.method = std::string(value);
      } else if (name == "max_iterations") {
        overrides.max_iterations = std::string(value);
      } else if (name == "max_distance") {
        overrides.max_distance = std::string(value);
      } else if (name == "keep_fraction") {
        overrides.keep_fraction = std::string(value);
      } else if (name == "kernel") {
        overrides.kernel = std::string(value);
      } else if (name == "kernel_scale") {
        overrides.kernel_scale = std::string(value);
      }
    } catch (const std::invalid_argument& e) {
      check_option_error(e, name);
    }
  }
  if (!overrides.empty()) {
    try {
      const nurbsreg::icp::IcpOptions options = service::apply_icp_overrides({}, overrides);
      if (auto error = options.validate()) finding("invalid ICP options accepted", *error);
    } catch (const std::invalid_argument& e) {
      // The parameter's name, or IcpOptions::validate's own message (which names the field).
      check_printable(e.what());
    }
  }
  check_body(content_type, std::string(input.substr(std::min(at, input.size()))));
}

}  // namespace nurbsreg::fuzz::request

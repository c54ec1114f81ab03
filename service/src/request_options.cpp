#include "nurbsreg/service/request_options.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/pose.hpp"

namespace nurbsreg::service {
namespace {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t'))
    s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t'))
    s.remove_suffix(1);
  return s;
}

std::string printable(std::string_view s) {
  std::string out;
  for (const char c : s.substr(0, 64))
    out.push_back(c >= 0x20 && c < 0x7f ? c : '?');
  return s.size() > 64 ? out + "..." : out;
}

std::string parse_id(std::string_view text, const char* what) {
  const bool ok = !text.empty() && text.size() <= 64 &&
                  std::all_of(text.begin(), text.end(), [](unsigned char c) {
                    return std::isalnum(c) || c == '.' || c == '_' || c == '-';
                  });
  if (!ok) {
    throw std::invalid_argument(std::string(what) + ": expected 1 to 64 characters of " +
                                "A-Z a-z 0-9 . _ -, got \"" + printable(text) + "\"");
  }
  return std::string(text);
}

template <class T>
T parse_number(const std::string& name, const std::string& text) {
  T value{};
  const char* first = text.data();
  const char* last = first + text.size();
  const auto [end, ec] = std::from_chars(first, last, value);
  if (ec != std::errc() || end != last) {
    throw std::invalid_argument(name + ": not a number: \"" + printable(text) + "\"");
  }
  return value;
}

std::string lower_media_type(std::string_view content_type) {
  content_type = trim(content_type.substr(0, content_type.find(';')));
  std::string out(content_type);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

}  // namespace

Eigen::Matrix4d parse_init_pose(std::string_view text) {
  // Four rows of four numbers, as a pose file has them; io::parse_pose checks each number,
  // rigidity, and makes the rotation exact, as for `align --init`.
  std::string rows;
  int count = 0;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = text.find(',', start);
    const std::string_view token =
        trim(text.substr(start, comma == std::string_view::npos ? comma : comma - start));
    if (token.empty()) {
      throw std::invalid_argument("init: number " + std::to_string(count + 1) +
                                  " is empty (expected 16 comma-separated numbers, row-major)");
    }
    if (count == 16) {
      throw std::invalid_argument("init: more than 16 numbers (expected 16, row-major)");
    }
    rows.append(token);
    rows.push_back(++count % 4 == 0 ? '\n' : ' ');
    if (comma == std::string_view::npos) break;
    start = comma + 1;
  }
  if (count != 16) {
    throw std::invalid_argument("init: expected 16 comma-separated numbers (row-major), got " +
                                std::to_string(count));
  }
  try {
    return io::parse_pose(rows, "init");
  } catch (const io::InputError& e) {
    throw std::invalid_argument(std::string(e.what()) + " (lines are the rows of the 16 numbers)");
  }
}

double parse_time_limit(std::string_view text, double server_limit) {
  const double seconds = parse_number<double>("time_limit", std::string(trim(text)));
  if (!std::isfinite(seconds) || !(seconds > 0.0)) {
    throw std::invalid_argument("time_limit: must be a number of seconds > 0, got \"" +
                                printable(text) + "\"");
  }
  if (seconds > server_limit) {
    std::ostringstream limit;
    limit << server_limit;
    throw std::invalid_argument("time_limit: at most " + limit.str() +
                                " s (the server's --time-limit)");
  }
  return seconds;
}

std::string parse_session_id(std::string_view text) {
  return parse_id(text, "session");
}
std::string parse_model_id(std::string_view text) {
  return parse_id(text, "id");
}

icp::IcpOptions apply_icp_overrides(icp::IcpOptions options, const IcpOverrides& o) {
  if (o.method) {
    const auto method = icp::parse_icp_method(*o.method);
    if (!method) throw std::invalid_argument("method: expected point-to-plane or point-to-point");
    options.method = *method;
  }
  if (o.kernel) {
    const auto kernel = icp::parse_robust_kernel(*o.kernel);
    if (!kernel) {
      throw std::invalid_argument("kernel: expected none, huber, tukey or geman-mcclure");
    }
    options.kernel = *kernel;
  }
  if (o.max_iterations) {
    options.max_iterations = parse_number<int>("max_iterations", *o.max_iterations);
  }
  if (o.max_distance) {
    options.max_correspondence_distance = parse_number<double>("max_distance", *o.max_distance);
  }
  if (o.keep_fraction) {
    options.keep_fraction = parse_number<double>("keep_fraction", *o.keep_fraction);
  }
  if (o.kernel_scale) options.kernel_scale = parse_number<double>("kernel_scale", *o.kernel_scale);
  if (auto error = options.validate()) throw std::invalid_argument(*error);
  return options;
}

engine::ProjectionTarget parse_projection_target(std::string_view text) {
  if (text == "surfaces") return engine::ProjectionTarget::surfaces;
  if (text == "curves") return engine::ProjectionTarget::curves;
  throw std::invalid_argument("target: expected surfaces or curves, got \"" + printable(text) +
                              "\"");
}

bool is_cloud_content_type(std::string_view content_type) {
  const std::string type = lower_media_type(content_type);
  return type == "application/octet-stream" || type == "text/plain" ||
         type == "application/x-pcd" || type == "application/x-ply" ||
         type == "application/x-nurbsreg-xyz-float32";
}

std::optional<io::CloudEncoding> encoding_for_content_type(std::string_view content_type,
                                                           std::string_view body_start) {
  const std::string type = lower_media_type(content_type);
  if (type == "application/octet-stream" || type == "text/plain") {
    return io::sniff_cloud_encoding(body_start);
  }
  if (type == "application/x-pcd") return io::CloudEncoding::pcd;
  if (type == "application/x-ply") return io::CloudEncoding::ply;
  if (type == "application/x-nurbsreg-xyz-float32") return io::CloudEncoding::float32_xyz;
  return std::nullopt;
}

std::filesystem::path resolve_under_root(const std::filesystem::path& root,
                                         std::string_view requested) {
  namespace fs = std::filesystem;
  const std::string shown = "path \"" + printable(requested) + "\"";
  if (requested.empty()) throw std::invalid_argument("path: empty");
  if (requested.find('\0') != std::string_view::npos) {
    throw std::invalid_argument(shown + ": contains a NUL byte");
  }
  const fs::path candidate =
      fs::path(requested).is_absolute() ? fs::path(requested) : root / fs::path(requested);
  std::error_code ec;
  // canonical() resolves every symbolic link and "..": what is left is the file itself.
  const fs::path real = fs::canonical(candidate, ec);
  if (ec) throw std::invalid_argument(shown + ": not found under the model root");
  const auto [root_end, real_it] =
      std::mismatch(root.begin(), root.end(), real.begin(), real.end());
  if (root_end != root.end() || real == root) {
    throw RootEscape(shown + ": outside the model root");
  }
  if (!fs::is_regular_file(real, ec)) throw std::invalid_argument(shown + ": not a regular file");
  return real;
}

}  // namespace nurbsreg::service

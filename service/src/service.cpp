// The HTTP front of `nurbsreg serve` (service.hpp): routes, admission, body reading and the
// answers. Geometry is the library's: registration::Aligner, io::project_cloud and the io
// writers, as in the CLI.
#include "nurbsreg/service/service.hpp"

#include <fcntl.h>
#include <httplib.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <thread>

#include "admission.hpp"
#include "connections.hpp"
#include "http_error.hpp"
#include "metrics.hpp"
#include "models.hpp"
#include "nurbsreg/io/alignment_result_report.hpp"
#include "nurbsreg/io/cad_import.hpp"
#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/model_file.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "nurbsreg/io/point_cloud_memory.hpp"
#include "nurbsreg/io/projected_cloud.hpp"
#include "nurbsreg/registration/scan_size.hpp"
#include "nurbsreg/service/request_options.hpp"
#include "sessions.hpp"

namespace nurbsreg::service {
namespace {

using detail::Endpoint;
using detail::HttpError;
using Json = nlohmann::json;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// Points projected between two checks of a /v1/project request's time limit: few enough that a
// request stops soon after its limit, enough that a check (a clock read) costs nothing per block.
constexpr std::size_t kProjectCheckBlock = 16384;

// A /v1/project request stopped by its time limit: the 504 answer's JSON body.
struct TimeLimitAnswer {
  std::string body;
};

std::string fmt_seconds(double seconds) {
  std::ostringstream out;
  out << seconds;
  return out.str();
}

std::string error_json(const std::string& message) {
  return Json{{"error", message}}.dump() + "\n";
}

void set_error(httplib::Response& res, int status, const std::string& message,
               int retry_after = 0) {
  res.status = status;
  res.body = error_json(message);
  res.set_header("Content-Type", "application/json");
  if (retry_after > 0) res.set_header("Retry-After", std::to_string(retry_after));
}

std::optional<std::string> param(const httplib::Request& req, const char* name) {
  if (!req.has_param(name)) return std::nullopt;
  return req.get_param_value(name);
}

// The whole file behind an already opened descriptor.
std::string read_descriptor(int fd, const std::string& label) {
  std::string text;
  char buffer[1 << 16];
  while (true) {
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw io::InputError(label, "read error");
    }
    if (n == 0) return text;
    text.append(buffer, static_cast<std::size_t>(n));
  }
}

class Descriptor {
 public:
  explicit Descriptor(int fd) : fd_(fd) {}
  ~Descriptor() {
    if (fd_ >= 0) ::close(fd_);
  }
  Descriptor(const Descriptor&) = delete;
  Descriptor& operator=(const Descriptor&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

// Reads a model that resolve_under_root has placed inside the root. The file is opened without
// following a final symbolic link (O_NOFOLLOW) and must still be a regular file, and the bytes
// parsed are those of that open file (JSON from the descriptor, CAD through /proc/self/fd), so
// a link swapped in after the check reads nothing outside the root.
engine::Model read_model_under_root(const std::filesystem::path& real, const std::string& label) {
  const Descriptor fd(::open(real.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC));
  if (fd.get() < 0) throw io::InputError(label, "cannot open the file (or it became a link)");
  struct stat info {};
  if (::fstat(fd.get(), &info) != 0 || !S_ISREG(info.st_mode)) {
    throw io::InputError(label, "not a regular file");
  }
  std::string ext = real.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".json") return io::parse_model(read_descriptor(fd.get(), label), label);
  const std::string via = "/proc/self/fd/" + std::to_string(fd.get());
  try {
    if (ext == ".step" || ext == ".stp") return io::read_step(via);
    if (ext == ".iges" || ext == ".igs") return io::read_iges(via);
  } catch (const io::InputError& e) {
    std::string what = e.what();
    if (what.starts_with(via)) what = what.substr(via.size() + 2);
    throw io::InputError(label, what);
  }
  throw io::InputError(label,
                       "unsupported model format (supported: .json, .step, .stp, .iges, .igs)");
}

Json model_json(const detail::ServedModel& m) {
  return Json{{"id", m.id},
              {"file", m.file},
              {"faces", m.surfaces},
              {"curves", m.curves},
              {"skipped_faces", m.skipped_faces},
              {"patches", m.patches},
              {"prepared", true},
              {"prepare_seconds", m.prepare_seconds},
              {"features", m.features != nullptr},
              {"features_seconds", m.features_seconds}};
}

}  // namespace

std::optional<std::string> ServiceOptions::validate() const {
  if (port < 0 || port > 65535) return "--port: must be in 0..65535";
  if (connections < 1) return "--connections: must be >= 1";
  if (max_inflight < 0) return "--max-inflight: must be >= 0 (0: the hardware threads)";
  if (max_body == 0) return "--max-body: must be > 0";
  if (!(time_limit_seconds > 0)) return "--time-limit: must be > 0";
  if (!(session_idle_seconds > 0)) return "--session-timeout: must be > 0";
  if (max_sessions == 0) return "--max-sessions: must be > 0";
  if (keep_alive_seconds < 0) return "--keep-alive: must be >= 0";
  if (keep_alive_requests < 1) return "keep-alive requests: must be >= 1";
  return icp.validate();
}

struct Service::Impl {
  explicit Impl(ServiceOptions o)
      : options(std::move(o)),
        gate(options.max_inflight > 0
                 ? options.max_inflight
                 : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()))),
        sessions(options.max_sessions, options.session_idle_seconds) {
    if (!options.model_root.empty()) {
      std::error_code ec;
      model_root = std::filesystem::canonical(options.model_root, ec);
      if (ec || !std::filesystem::is_directory(model_root)) {
        throw std::invalid_argument("--model-root: " + options.model_root + ": not a directory");
      }
    }
    set_up_routes();
  }

  ServiceOptions options;
  httplib::Server server;
  detail::ModelRegistry models;
  detail::InflightGate gate;
  detail::SessionStore sessions;
  detail::Metrics metrics;
  detail::BoundedTaskQueue::Counters queue_counters;
  std::filesystem::path model_root;
  std::atomic<bool> stopping{false};
  std::atomic<int> port{0};  // bound (bind())
  // The requests being handled, by peer, so that stop() closes only idle connections.
  detail::ConnectionTracker connections;
  std::atomic<bool> running{false};

  void set_up_routes();
  void close_idle_connections();
  bool authorised(const httplib::Request& req) const;
  void check_common(const httplib::Request& req, Endpoint endpoint) const;
  std::shared_ptr<detail::ServedModel> model_of(const httplib::Request& req) const;
  std::string read_body(const httplib::Request& req, const httplib::ContentReader& reader,
                        Clock::time_point deadline, bool& consumed) const;
  void drain(const httplib::ContentReader& reader) const;
  detail::Metrics::Gauges gauges() const;
  Clock::time_point deadline_from(Clock::time_point start) const;
  // The bound on a frame's computation: the server's `deadline` (from the request's start), or
  // the request's own `time_limit` from now (its body is in) when that comes first.
  static Clock::time_point work_deadline(Clock::time_point deadline,
                                         const std::optional<double>& frame_limit);
  // The request's `time_limit` (at most --time-limit), if it gives one.
  std::optional<double> frame_limit_of(const httplib::Request& req) const;
  // The 504 error's text: what `what` says, and the limit that stopped it.
  std::string time_limit_error(const std::string& what,
                               const std::optional<double>& frame_limit) const;

  // A frame admitted to computation: its in-flight slot (held until the answer is built) and
  // the point cloud of its body.
  struct AdmittedFrame {
    detail::InflightSlot slot;
    io::PointCloud cloud;
  };
  // The admission align and project share, after their own options are checked and before
  // any work: a point-cloud content type (400, before any body byte), a free in-flight slot
  // (503 with Retry-After beyond --max-inflight), the body (413 over --max-body, 408 past
  // `deadline`) and its parsed cloud (400 naming the problem).
  AdmittedFrame admit_frame(const httplib::Request& req, const httplib::ContentReader& reader,
                            Clock::time_point deadline, bool& consumed);

  // A request with a body (align, project, model loading): `work` reads it (through
  // read_body) and answers; any exception becomes an error answer; the body is drained when
  // `work` did not read it, so the connection stays usable.
  template <class Work>
  void with_body(Endpoint endpoint, const httplib::Request& req, httplib::Response& res,
                 const httplib::ContentReader& reader, Work&& work);

  void align(const httplib::Request& req, httplib::Response& res,
             const httplib::ContentReader& reader, bool& consumed, std::size_t& points);
  void project(const httplib::Request& req, httplib::Response& res,
               const httplib::ContentReader& reader, bool& consumed, std::size_t& points);
  void load_model(const httplib::Request& req, httplib::Response& res,
                  const httplib::ContentReader& reader, bool& consumed);
};

bool Service::Impl::authorised(const httplib::Request& req) const {
  if (options.token.empty()) return true;
  const std::string header = req.get_header_value("Authorization");
  const std::string expected = "Bearer " + options.token;
  // Constant time in the token's length, so the comparison does not tell how much matched.
  if (header.size() != expected.size()) return false;
  unsigned char diff = 0;
  for (std::size_t i = 0; i < header.size(); ++i)
    diff |= static_cast<unsigned char>(header[i] ^ expected[i]);
  return diff == 0;
}

// The checks every endpoint but /healthz shares, done before any body byte is read.
void Service::Impl::check_common(const httplib::Request& req, Endpoint endpoint) const {
  if (detail::BoundedTaskQueue::overflowing()) {
    throw HttpError(503, "the service is at its connection limit; retry later", 1);
  }
  if (endpoint != Endpoint::healthz && !authorised(req)) {
    throw HttpError(401, "missing or wrong bearer token (Authorization: Bearer <token>)");
  }
}

std::shared_ptr<detail::ServedModel> Service::Impl::model_of(const httplib::Request& req) const {
  const auto id = param(req, "model");
  if (!id) throw HttpError(400, "model: missing query parameter (GET /v1/models lists the ids)");
  auto model = models.find(*id);
  if (!model) throw HttpError(404, "model \"" + *id + "\" is not loaded (GET /v1/models)");
  return model;
}

std::string Service::Impl::read_body(const httplib::Request& req,
                                     const httplib::ContentReader& reader,
                                     Clock::time_point deadline, bool& consumed) const {
  if (req.has_header("Content-Length")) {
    const auto length = req.get_header_value<std::uint64_t>("Content-Length");
    if (length > options.max_body) {
      throw HttpError(413, "body of " + std::to_string(length) + " bytes is over the limit of " +
                               std::to_string(options.max_body) + " (--max-body)");
    }
  }
  std::string body;
  if (req.has_header("Content-Length")) {
    body.reserve(req.get_header_value<std::uint64_t>("Content-Length"));
  }
  bool too_large = false;
  bool too_slow = false;
  consumed = true;
  const bool ok = reader([&](const char* data, std::size_t size) {
    if (size > options.max_body - body.size()) {
      too_large = true;
      return false;
    }
    if (Clock::now() > deadline) {
      too_slow = true;
      return false;
    }
    body.append(data, size);
    return true;
  });
  if (too_large) {
    throw HttpError(413, "body is over the limit of " + std::to_string(options.max_body) +
                             " bytes (--max-body)");
  }
  if (too_slow) throw HttpError(408, "the body did not arrive within the time limit");
  if (!ok) throw HttpError(400, "the body could not be read (connection closed early?)");
  return body;
}

void Service::Impl::drain(const httplib::ContentReader& reader) const {
  std::size_t seen = 0;
  const std::size_t limit = options.max_body;
  reader([&](const char*, std::size_t size) {
    seen += size;
    return seen <= limit;
  });
}

detail::Metrics::Gauges Service::Impl::gauges() const {
  detail::Metrics::Gauges g;
  g.in_flight = gate.count();
  g.max_inflight = gate.limit();
  g.waiting_connections = queue_counters.waiting.load();
  g.refused_connections = queue_counters.overflowed.load();
  g.sessions = sessions.size();
  g.models = models.size();
  return g;
}

Clock::time_point Service::Impl::deadline_from(Clock::time_point start) const {
  return start + std::chrono::duration_cast<Clock::duration>(
                     std::chrono::duration<double>(options.time_limit_seconds));
}

Clock::time_point Service::Impl::work_deadline(Clock::time_point deadline,
                                               const std::optional<double>& frame_limit) {
  if (!frame_limit) return deadline;
  return std::min(deadline, Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                               std::chrono::duration<double>(*frame_limit)));
}

std::optional<double> Service::Impl::frame_limit_of(const httplib::Request& req) const {
  const auto text = param(req, "time_limit");
  if (!text) return std::nullopt;
  return parse_time_limit(*text, options.time_limit_seconds);
}

std::string Service::Impl::time_limit_error(const std::string& what,
                                            const std::optional<double>& frame_limit) const {
  const double limit = frame_limit ? *frame_limit : options.time_limit_seconds;
  return what + " (" + (frame_limit ? "time_limit " : "--time-limit ") + fmt_seconds(limit) + " s)";
}

Service::Impl::AdmittedFrame Service::Impl::admit_frame(const httplib::Request& req,
                                                        const httplib::ContentReader& reader,
                                                        Clock::time_point deadline,
                                                        bool& consumed) {
  const std::string content_type = req.get_header_value("Content-Type");
  if (!is_cloud_content_type(content_type)) {
    throw HttpError(400, "Content-Type \"" + content_type +
                             "\": expected application/octet-stream or text/plain (a PCD or "
                             "PLY body), application/x-pcd, application/x-ply or "
                             "application/x-nurbsreg-xyz-float32");
  }
  if (!gate.try_enter()) {
    metrics.count_overload();
    throw HttpError(
        503,
        "busy: " + std::to_string(gate.limit()) + " frames in flight (--max-inflight); retry later",
        1);
  }
  AdmittedFrame frame{detail::InflightSlot(&gate), {}};
  std::string body = read_body(req, reader, deadline, consumed);
  const auto encoding = encoding_for_content_type(content_type, body);
  frame.cloud = io::parse_point_cloud(body, *encoding, "request body");
  return frame;
}

template <class Work>
void Service::Impl::with_body(Endpoint endpoint, const httplib::Request& req,
                              httplib::Response& res, const httplib::ContentReader& reader,
                              Work&& work) {
  const Clock::time_point start = Clock::now();
  bool consumed = false;
  std::size_t points = 0;
  try {
    check_common(req, endpoint);
    work(consumed, points);
  } catch (const HttpError& e) {
    set_error(res, e.status(), e.what(), e.retry_after());
  } catch (const io::InputError& e) {
    set_error(res, 400, e.what());
  } catch (const std::invalid_argument& e) {
    set_error(res, 400, e.what());
  } catch (const std::bad_alloc&) {
    set_error(res, 503, "out of memory for this request; retry later", 1);
  } catch (const std::exception& e) {
    spdlog::error("{} {}: {}", req.method, req.path, e.what());
    set_error(res, 500, e.what());
  } catch (...) {
    set_error(res, 500, "unknown failure");
  }
  if (!consumed && !detail::BoundedTaskQueue::overflowing()) {
    // A refused request's body is read and thrown away (at most --max-body bytes; httplib
    // skips an announced larger one itself), so the next request on the connection parses.
    // Not on an overflow connection: it is served by the accept loop, which must not wait for
    // an upload; its answer says Connection: close.
    try {
      drain(reader);
    } catch (...) {
    }
  }
  // Answers after a fully read body keep the connection; the others may leave bytes of it.
  if (res.status >= 400 && res.status != 422 && res.status != 400 && res.status != 504) {
    res.set_header("Connection", "close");
  }
  metrics.record(endpoint, res.status, seconds_since(start), res.status == 200 ? points : 0);
  spdlog::debug("{} {} -> {} ({:.3f} s)", req.method, req.path, res.status, seconds_since(start));
}

void Service::Impl::align(const httplib::Request& req, httplib::Response& res,
                          const httplib::ContentReader& reader, bool& consumed,
                          std::size_t& points) {
  const Clock::time_point start = Clock::now();
  const Clock::time_point deadline = deadline_from(start);
  // Everything but the body first, so a bad option costs no upload.
  const std::shared_ptr<detail::ServedModel> model = model_of(req);
  if (model->surfaces == 0) {
    throw HttpError(400, "model \"" + model->id + "\" has no surfaces to align to");
  }
  std::optional<Eigen::Isometry3d> init;
  if (const auto text = param(req, "init")) {
    init = Eigen::Isometry3d(parse_init_pose(*text));
  }
  IcpOverrides overrides;
  overrides.method = param(req, "method");
  overrides.max_iterations = param(req, "max_iterations");
  overrides.max_distance = param(req, "max_distance");
  overrides.keep_fraction = param(req, "keep_fraction");
  overrides.kernel = param(req, "kernel");
  overrides.kernel_scale = param(req, "kernel_scale");
  const icp::IcpOptions icp_options = apply_icp_overrides(options.icp, overrides);
  // A frame's work is bounded by the server's iteration limit (and --max-body): a request may
  // lower it, not raise it.
  if (icp_options.max_iterations > options.icp.max_iterations) {
    throw HttpError(400, "max_iterations: at most " + std::to_string(options.icp.max_iterations) +
                             " (the server's --max-iterations)");
  }
  std::optional<std::string> session_id;
  if (const auto text = param(req, "session")) session_id = parse_session_id(*text);
  const bool with_distances = param(req, "distances").value_or("") == "true";
  const std::optional<double> frame_limit = frame_limit_of(req);

  const AdmittedFrame admitted = admit_frame(req, reader, deadline, consumed);
  const io::PointCloud& cloud = admitted.cloud;
  // The frame's own limit counts from here (its body is in); the server's from the start.
  const Clock::time_point work_deadline = Impl::work_deadline(deadline, frame_limit);
  if (cloud.size() == 0) {
    throw HttpError(400, cloud.total == 0
                             ? std::string("request body: the scan has no points")
                             : "request body: the scan has no finite points (all " +
                                   std::to_string(cloud.total) + " are NaN or infinite)");
  }

  // The session's aligner and previous pose, or a pooled aligner.
  std::shared_ptr<detail::Session> session;
  std::unique_lock<detail::FrameLock> session_lock;
  struct SessionUse {
    detail::SessionStore& store;
    std::shared_ptr<detail::Session>& session;
    ~SessionUse() {
      if (session) store.close(session);
    }
  } session_use{sessions, session};
  if (session_id) {
    detail::SessionStore::OpenError error{};
    session = sessions.open(*session_id, model, error);
    if (error == detail::SessionStore::OpenError::other_model) {
      throw HttpError(409, "session \"" + *session_id + "\" belongs to another model");
    }
    if (error == detail::SessionStore::OpenError::full) {
      throw HttpError(503,
                      "all " + std::to_string(options.max_sessions) +
                          " sessions are in use (--max-sessions); retry later",
                      1);
    }
    session_lock = std::unique_lock(session->busy, std::defer_lock);
    if (!session_lock.try_lock_until(work_deadline)) {
      throw HttpError(
          409, "session \"" + *session_id + "\" is busy with another frame beyond the time limit");
    }
  }

  std::unique_ptr<registration::Aligner> pooled;
  registration::Aligner* aligner = nullptr;
  if (session) {
    if (!session->aligner || session->overrides != overrides) {
      session->aligner = model->make_aligner(icp_options);
      // The session's warm state: its frames borrow the certificates of the frames before (exact
      // answers, not bit-identical to `align --init` of the previous pose from a fresh process).
      session->aligner->keep_certificates(true);
      session->overrides = overrides;
    }
    aligner = session->aligner.get();
    if (!init && session->pose) init = session->pose;
  } else if (overrides.empty()) {
    pooled = model->take_aligner(options.icp);
    aligner = pooled.get();
  } else {
    pooled = model->make_aligner(icp_options);
    aligner = pooled.get();
  }
  // As `align` does: from the given (or the session's previous) pose, else from any pose (the
  // global coarse stage, then ICP); the work stops at the request's deadline.
  registration::AlignRequest request;
  request.init = init;
  request.deadline = work_deadline;
  // As `align` without --aligned: only per-point distances need every point's exact projection;
  // the report (pose, deviations, verdict) is the same either way, and with a distance bound (the
  // global path's fine ICP, max_distance) far outliers then cost next to nothing.
  request.all_projections = with_distances;
  const registration::AlignmentResult frame = aligner->align(cloud.points, request);

  const io::AlignmentReport report = io::make_alignment_report(
      frame, icp_options.method, cloud.skipped_nonfinite, seconds_since(start));
  Json answer = Json::parse(io::report_to_json(report));
  answer["model"] = model->id;
  const registration::DeviationSummary& d = frame.deviation;
  answer["deviation"] =
      Json{{"count", d.count}, {"within", d.within}, {"mean", d.mean}, {"rms", d.rms},
           {"p50", d.p50},     {"p95", d.p95},       {"p99", d.p99},   {"max", d.max}};
  answer["init"] = init ? (session && !param(req, "init") ? "session" : "request") : "global";
  if (session) {
    answer["session"] = session->id;
    answer["frame"] = ++session->frames;
    if (frame.ok()) session->pose = frame.icp.T_model_scan;
  }
  if (with_distances) {
    const auto& signed_distance = aligner->last_projections().signed_distance;
    answer["signed_distances"] =
        std::vector<double>(signed_distance.begin(), signed_distance.end());
  }
  if (pooled && overrides.empty()) model->give_back(std::move(pooled));
  if (frame.icp.termination == icp::IcpTermination::time_limit) {
    // The request's time ran out mid-computation: 504, naming the limit (the report says how
    // far the work got); the pose is not a result.
    answer["error"] = time_limit_error(*frame.failure, frame_limit);
    answer["time_limit_seconds"] = frame_limit ? *frame_limit : options.time_limit_seconds;
    res.status = 504;
  } else if (frame.failure) {
    // No pose to use: the report says what happened; the status says it is not a result.
    answer["error"] = *frame.failure;
    res.status = 422;
  } else {
    res.status = 200;
  }
  points = cloud.size();
  res.body = answer.dump(2) + "\n";
  res.set_header("Content-Type", "application/json");
}

void Service::Impl::project(const httplib::Request& req, httplib::Response& res,
                            const httplib::ContentReader& reader, bool& consumed,
                            std::size_t& points) {
  const Clock::time_point deadline = deadline_from(Clock::now());
  const std::shared_ptr<detail::ServedModel> model = model_of(req);
  const engine::ProjectionTarget target =
      parse_projection_target(param(req, "target").value_or("surfaces"));
  if (target == engine::ProjectionTarget::surfaces && model->surfaces == 0) {
    throw HttpError(400, "model \"" + model->id + "\" has no surfaces; use target=curves");
  }
  if (target == engine::ProjectionTarget::curves && model->curves == 0) {
    throw HttpError(400, "model \"" + model->id + "\" has no curves; use target=surfaces");
  }
  const std::optional<double> frame_limit = frame_limit_of(req);
  const AdmittedFrame admitted = admit_frame(req, reader, deadline, consumed);
  const io::PointCloud& cloud = admitted.cloud;
  const Clock::time_point work_deadline = Impl::work_deadline(deadline, frame_limit);

  // The time limit is checked between blocks of kProjectCheckBlock points (the rows do not
  // depend on the block size): past it, the work stops with 504 at the next check.
  struct Pooled {
    detail::ServedModel& model;
    std::unique_ptr<engine::Projector> projector;
    ~Pooled() { model.give_back(std::move(projector)); }
  } pooled{*model, model->take_projector()};
  const auto check_time = [&](std::size_t done, std::size_t total, double) {
    if (done < total && Clock::now() >= work_deadline) {
      Json answer;
      answer["error"] = time_limit_error("time limit exceeded after " + std::to_string(done) +
                                             " of " + std::to_string(total) + " points",
                                         frame_limit);
      answer["time_limit_seconds"] = frame_limit ? *frame_limit : options.time_limit_seconds;
      answer["points"] = total;
      answer["projected_points"] = done;
      throw TimeLimitAnswer{answer.dump(2) + "\n"};
    }
  };
  io::ProjectedCloud projected;
  try {
    // A limit already past (a slow upload) stops before the first block.
    check_time(0, std::max<std::size_t>(1, cloud.size()), 0.0);
    projected = io::project_cloud(*pooled.projector, cloud, target, check_time, kProjectCheckBlock);
  } catch (const TimeLimitAnswer& stopped) {
    res.status = 504;
    res.body = stopped.body;
    res.set_header("Content-Type", "application/json");
    points = cloud.size();
    return;
  }
  std::ostringstream csv;
  io::write_projection_csv(csv, projected.columns(cloud));
  res.status = 200;
  res.body = std::move(csv).str();
  res.set_header("Content-Type", "text/csv");
  res.set_header("X-Skipped-Points", std::to_string(cloud.skipped_nonfinite));
  // `project`'s warnings, one header each (HTTP has no stderr): the scan's size against the
  // model's, and points that mostly lie far from the model.
  const engine::PreparedModel& prepared = pooled.projector->model();
  const registration::ScanSize sizes = registration::scan_size(cloud.points, prepared);
  if (const auto note = sizes.warning()) res.set_header("X-Warning", "points: " + *note);
  if (const auto note =
          registration::far_from_model_note(projected.results.distance, sizes.model, sizes.units)) {
    res.set_header("X-Warning", "points: " + *note);
  }
  points = cloud.size();
}

void Service::Impl::load_model(const httplib::Request& req, httplib::Response& res,
                               const httplib::ContentReader& reader, bool& consumed) {
  if (model_root.empty()) {
    throw HttpError(403, "loading models at run time is off (start with --model-root DIR)");
  }
  std::optional<std::string> path = param(req, "path");
  std::optional<std::string> id = param(req, "id");
  if (!path) {
    // A small JSON body {"path": ..., "id": ...}.
    const std::string body =
        read_body(req, reader, Clock::now() + std::chrono::seconds(10), consumed);
    Json request;
    try {
      request = Json::parse(body);
    } catch (const Json::exception&) {
      throw HttpError(400,
                      "expected a JSON body {\"path\": \"...\", \"id\": \"...\"} or "
                      "?path=...&id=...");
    }
    if (!request.is_object() || !request.contains("path") || !request["path"].is_string()) {
      throw HttpError(400, "body: \"path\" (a string) is required");
    }
    path = request["path"].get<std::string>();
    if (request.contains("id")) {
      if (!request["id"].is_string()) throw HttpError(400, "body: \"id\" must be a string");
      id = request["id"].get<std::string>();
    }
  }
  std::filesystem::path real;
  try {
    real = resolve_under_root(model_root, *path);
  } catch (const RootEscape& e) {
    throw HttpError(403, e.what());
  } catch (const std::invalid_argument& e) {
    throw HttpError(404, e.what());
  }
  const std::string model_id = parse_model_id(id ? *id : real.stem().string());
  if (models.find(model_id)) throw HttpError(409, "a model with id \"" + model_id + "\" is loaded");
  if (!gate.try_enter()) throw HttpError(503, "busy; retry later", 1);
  const detail::InflightSlot slot(&gate);
  const std::string label = *path;
  auto served = detail::serve_model(read_model_under_root(real, label), label, model_id);
  try {
    models.add(served);
  } catch (const std::invalid_argument& e) {
    throw HttpError(409, e.what());
  }
  spdlog::info("loaded model {} from {} ({} faces, {} patches)", served->id, label,
               served->surfaces, served->patches);
  res.status = 201;
  res.body = model_json(*served).dump(2) + "\n";
  res.set_header("Content-Type", "application/json");
}

void Service::Impl::close_idle_connections() {
  if (port <= 0) return;
  const std::size_t closed = connections.close_idle(port);
  if (closed > 0) spdlog::info("closed {} idle connection(s)", closed);
}

void Service::Impl::set_up_routes() {
  httplib::Server& s = server;
  s.set_keep_alive_max_count(static_cast<std::size_t>(options.keep_alive_requests));
  s.set_keep_alive_timeout(options.keep_alive_seconds);
  s.set_payload_max_length(options.max_body);
  // An answer's status line and headers go out in one write and its body in another; with
  // Nagle's algorithm the body then waits for the client's delayed acknowledgement of the
  // first (tens of milliseconds on Linux), which would dominate a warm frame's latency.
  s.set_tcp_nodelay(true);
  // A request is active from routing until its answer is written (the logger runs after the
  // write): stop() closes the other connections at once (ConnectionTracker).
  s.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response&) {
    connections.begin(req.remote_addr, req.remote_port);
    return httplib::Server::HandlerResponse::Unhandled;
  });
  s.set_logger([this](const httplib::Request& req, const httplib::Response&) {
    connections.end(req.remote_addr, req.remote_port);
  });
  const int threads = options.connections;
  const std::size_t waiting =
      options.max_queue > 0 ? options.max_queue : static_cast<std::size_t>(threads);
  // The idle connections are closed when the accept loop has ended (the queue's shutdown, on
  // the accepting thread): every connection is accepted by then, so none is missed, and the
  // scan of this process's sockets follows their accept() on one thread.
  s.new_task_queue = [this, threads, waiting] {
    return new detail::BoundedTaskQueue(static_cast<std::size_t>(threads), waiting, queue_counters,
                                        [this] { close_idle_connections(); });
  };

  // No Expect: 100-continue hook: a request refused from its headers alone still has its body
  // read and dropped (drain), because httplib 0.11 keeps the connection open after any answer,
  // and a body the client sends anyway would be parsed as the next request. httplib's default
  // answers 100 to every Expect.

  s.Get("/healthz", [this](const httplib::Request& req, httplib::Response& res) {
    const Clock::time_point start = Clock::now();
    if (detail::BoundedTaskQueue::overflowing()) {
      set_error(res, 503, "at the connection limit", 1);
    } else {
      res.status = 200;
      res.body = Json{{"status", "ok"}, {"models", models.size()}}.dump() + "\n";
      res.set_header("Content-Type", "application/json");
    }
    (void)req;
    metrics.record(Endpoint::healthz, res.status, seconds_since(start), 0);
  });
  s.Get("/v1/models", [this](const httplib::Request& req, httplib::Response& res) {
    const Clock::time_point start = Clock::now();
    try {
      check_common(req, Endpoint::models);
      Json list = Json::array();
      for (const auto& m : models.list())
        list.push_back(model_json(*m));
      res.status = 200;
      res.body = list.dump(2) + "\n";
      res.set_header("Content-Type", "application/json");
    } catch (const HttpError& e) {
      set_error(res, e.status(), e.what(), e.retry_after());
    }
    metrics.record(Endpoint::models, res.status, seconds_since(start), 0);
  });
  s.Get("/metrics", [this](const httplib::Request& req, httplib::Response& res) {
    const Clock::time_point start = Clock::now();
    try {
      check_common(req, Endpoint::metrics);
      res.status = 200;
      res.body = metrics.prometheus_text(gauges());
      res.set_header("Content-Type", "text/plain; version=0.0.4");
    } catch (const HttpError& e) {
      set_error(res, e.status(), e.what(), e.retry_after());
    }
    metrics.record(Endpoint::metrics, res.status, seconds_since(start), 0);
  });
  s.Post("/v1/align", [this](const httplib::Request& req, httplib::Response& res,
                             const httplib::ContentReader& reader) {
    with_body(Endpoint::align, req, res, reader, [&](bool& consumed, std::size_t& points) {
      align(req, res, reader, consumed, points);
    });
  });
  s.Post("/v1/project", [this](const httplib::Request& req, httplib::Response& res,
                               const httplib::ContentReader& reader) {
    with_body(Endpoint::project, req, res, reader, [&](bool& consumed, std::size_t& points) {
      project(req, res, reader, consumed, points);
    });
  });
  s.Post("/v1/models", [this](const httplib::Request& req, httplib::Response& res,
                              const httplib::ContentReader& reader) {
    with_body(Endpoint::models, req, res, reader,
              [&](bool& consumed, std::size_t&) { load_model(req, res, reader, consumed); });
  });
  // Unknown paths and methods: a JSON error like every other answer.
  s.set_error_handler(
      httplib::Server::HandlerWithResponse([](const httplib::Request& req, httplib::Response& res) {
        if (!res.body.empty()) return httplib::Server::HandlerResponse::Unhandled;
        set_error(res, res.status,
                  res.status == 404 ? "no such endpoint: " + req.method + " " + req.path
                                    : "request failed (" + std::to_string(res.status) + ")");
        return httplib::Server::HandlerResponse::Handled;
      }));
  s.set_exception_handler(
      [](const httplib::Request&, httplib::Response& res, std::exception_ptr error) {
        std::string what = "unknown failure";
        try {
          std::rethrow_exception(error);
        } catch (const std::exception& e) {
          what = e.what();
        } catch (...) {
        }
        set_error(res, 500, what);
      });
}

Service::Service(ServiceOptions options) {
  if (auto error = options.validate()) throw std::invalid_argument(*error);
  impl_ = std::make_unique<Impl>(std::move(options));
}

Service::~Service() = default;

void Service::add_model(const std::string& path, std::string id) {
  if (!id.empty()) id = parse_model_id(id);
  auto served = detail::serve_model(io::read_model_file(path), path, std::move(id));
  if (served->skipped_faces > 0) {
    spdlog::warn("{}: {} faces could not be converted and are not in the model", path,
                 served->skipped_faces);
  }
  parse_model_id(served->id);
  impl_->models.add(served);
  spdlog::info("model {}: {} ({} faces, {} curves, {} patches, prepared in {:.2f} s)", served->id,
               path, served->surfaces, served->curves, served->patches, served->prepare_seconds);
}

int Service::bind() {
  const ServiceOptions& o = impl_->options;
  const int port = o.port == 0 ? impl_->server.bind_to_any_port(o.bind)
                               : (impl_->server.bind_to_port(o.bind, o.port) ? o.port : -1);
  if (port < 0) {
    throw std::runtime_error(o.bind + ":" + std::to_string(o.port) +
                             ": cannot listen (address in use or not available)");
  }
  impl_->port = port;
  return port;
}

void Service::run() {
  impl_->running = true;
  if (!impl_->stopping) impl_->server.listen_after_bind();
  impl_->running = false;
}

void Service::stop() {
  impl_->stopping = true;
  // Ends the accept loop; the idle keep-alive connections, which would hold run() up to
  // --keep-alive, are then closed by the task queue's shutdown (close_idle_connections).
  impl_->server.stop();
}

}  // namespace nurbsreg::service

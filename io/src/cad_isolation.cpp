// The STEP/IGES import in a child process: why and how in cad_isolation.hpp.
#include "cad_isolation.hpp"
#include "occt_module.hpp"

#include <spdlog/spdlog.h>

#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <new>
#include <nlohmann/json.hpp>

#include "nurbsreg/io/errors.hpp"
#include "nurbsreg/io/model_json.hpp"
#include "nurbsreg/io/resource_limits.hpp"
#include "text_io.hpp"

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define NURBSREG_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
#define NURBSREG_SANITIZED 1
#endif
#endif

namespace nurbsreg::io::cad_detail {
namespace {

// The child's message: one tag byte, then the payload.
//   'M' report JSON, '\n', model JSON      the import succeeded
//   'E' message                            InputError (the message without the file name)
//   'O'                                    out of memory (the address-space limit)
//   'F' message                            any other exception
constexpr char kModel = 'M', kInputError = 'E', kOutOfMemory = 'O', kFailure = 'F';

std::string report_to_json(const CadImportReport& r) {
  nlohmann::json j;
  j["format"] = r.format;
  j["file_units"] = r.file_units;
  j["faces"] = r.faces;
  j["trimmed_faces"] = r.trimmed_faces;
  j["analytic_faces"] = r.analytic_faces;
  j["approximations"] = r.approximations;
  j["degenerated_edges"] = r.degenerated_edges;
  j["rebuilt_edges"] = r.rebuilt_edges;
  j["inconsistent_edges"] = r.inconsistent_edges;
  j["uv_outside_domain"] = r.uv_outside_domain;
  j["surface_types"] = r.surface_types;
  j["surface_faces"] = r.surface_faces;
  j["diagonal"] = r.diagonal;  // nlohmann prints doubles with 17 digits: exact
  return j.dump();
}

CadImportReport report_from_json(std::string_view text) {
  const nlohmann::json j = nlohmann::json::parse(text);
  CadImportReport r;
  r.format = j.at("format").get<std::string>();
  r.file_units = j.at("file_units").get<std::string>();
  r.faces = j.at("faces").get<std::size_t>();
  r.trimmed_faces = j.at("trimmed_faces").get<std::size_t>();
  r.analytic_faces = j.at("analytic_faces").get<std::size_t>();
  r.approximations = j.at("approximations").get<std::size_t>();
  r.degenerated_edges = j.at("degenerated_edges").get<std::size_t>();
  r.rebuilt_edges = j.at("rebuilt_edges").get<std::size_t>();
  r.inconsistent_edges = j.at("inconsistent_edges").get<std::size_t>();
  r.uv_outside_domain = j.at("uv_outside_domain").get<std::size_t>();
  r.surface_types = j.at("surface_types").get<std::map<std::string, std::size_t>>();
  r.surface_faces = j.at("surface_faces").get<std::vector<int>>();
  r.diagonal = j.at("diagonal").get<double>();
  return r;
}

void write_all(int fd, std::string_view bytes) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd, bytes.data(), bytes.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;  // the parent is gone or gave up: nothing left to tell
    bytes.remove_prefix(static_cast<std::size_t>(n));
  }
}

// Virtual memory the process already has (the child starts with the parent's): the
// address-space limit is on top of it.
std::uint64_t current_address_space() {
  std::ifstream statm("/proc/self/statm");
  std::uint64_t pages = 0;
  statm >> pages;
  return pages * static_cast<std::uint64_t>(sysconf(_SC_PAGESIZE));
}

[[noreturn]] void run_child(const std::string& path, int fd, const ResourceLimits& limits) {
  const rlimit no_core{0, 0};
  setrlimit(RLIMIT_CORE, &no_core);  // a crash is reported, not dumped
  // CPU time: the wall-clock timeout is the parent's; this one also stops a child whose parent
  // died. SIGXCPU at the soft limit, SIGKILL a second later.
  const rlimit cpu{static_cast<rlim_t>(limits.cad_timeout_seconds),
                   static_cast<rlim_t>(limits.cad_timeout_seconds + 1)};
  setrlimit(RLIMIT_CPU, &cpu);
#ifndef NURBSREG_SANITIZED
  const auto bytes = static_cast<rlim_t>(current_address_space() + (limits.cad_memory_mb << 20));
  const rlimit memory{bytes, bytes};
  setrlimit(RLIMIT_AS, &memory);
#endif
  std::string message;
  try {
    CadImportReport report;
    const engine::Model model = import_in_process(path, &report, /*take_lock=*/false);
    message = kModel + report_to_json(report) + "\n" + model_to_json(model);
  } catch (const InputError& e) {
    std::string what = e.what();
    if (what.starts_with(path + ": ")) what.erase(0, path.size() + 2);
    message = kInputError + what;
  } catch (const std::bad_alloc&) {
    message = std::string(1, kOutOfMemory);
  } catch (const std::exception& e) {
    message = kFailure + std::string(e.what());
  } catch (...) {
    message = kFailure + std::string("unknown exception");
  }
  write_all(fd, message);
  ::close(fd);
  _exit(0);  // no atexit handlers, no flushing of the parent's buffered output
}

std::string signal_name(int signal) {
  const char* name = strsignal(signal);
  return "signal " + std::to_string(signal) + (name != nullptr ? std::string(", ") + name : "");
}

}  // namespace

engine::Model import_isolated(const std::string& path, CadImportReport* report) {
  const ResourceLimits limits = resource_limits();
  const std::string format =
      text_detail::lower_extension(path).starts_with(".st") ? "STEP" : "IGES";
  int fds[2];
  if (::pipe(fds) != 0) {
    throw std::runtime_error(path + ": cannot create a pipe for the " + format +
                             " import: " + std::strerror(errno));
  }
  // Loaded here, before the fork: the child then finds it mapped (and a missing module is said
  // once, by the parent).
  (void)occt_import_function();
  pid_t child = -1;
  {
    // No other thread of this process is inside OCCT while we fork (see the header).
    const std::lock_guard<std::mutex> lock(occt_mutex());
    child = ::fork();
  }
  if (child < 0) {
    const int error = errno;
    ::close(fds[0]);
    ::close(fds[1]);
    throw std::runtime_error(path + ": cannot start the " + format +
                             " import process: " + std::strerror(error));
  }
  if (child == 0) {
    ::close(fds[0]);
    run_child(path, fds[1], limits);
  }
  ::close(fds[1]);

  // Read everything the child says until it closes the pipe, or until the deadline.
  std::string message;
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::seconds(limits.cad_timeout_seconds);
  bool timed_out = false;
  // A conversion past a second is said while it runs (a large part takes seconds; a malformed
  // file's quick failure keeps its error as the only line). From this wait, not from a thread: a
  // thread beside the fork could leave the child holding a lock nobody releases (an ASan build
  // hung so).
  const auto start = std::chrono::steady_clock::now();
  const auto say_at = start + std::chrono::seconds(1);
  bool said = false;
  char buffer[1 << 16];
  while (true) {
    const auto now = std::chrono::steady_clock::now();
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - now).count();
    if (left <= 0) {
      timed_out = true;
      break;
    }
    if (!said && now >= say_at) {
      spdlog::info("{}: converting the {} file with OpenCASCADE", path, format);
      said = true;
    }
    const long long wait =
        said ? left
             : std::chrono::duration_cast<std::chrono::milliseconds>(say_at - now).count() + 1;
    pollfd p{fds[0], POLLIN, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(std::min<long long>({left, wait, 1 << 30})));
    if (ready < 0 && errno == EINTR) continue;
    if (ready == 0) continue;  // the deadline and the line are checked above
    const ssize_t n = ::read(fds[0], buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;  // EOF: the child is done (or dead)
    message.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(fds[0]);
  if (timed_out) ::kill(child, SIGKILL);
  int status = 0;
  while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
  }
  if (timed_out) {
    throw InputError(path,
                     "the " + format + " import did not finish within " +
                         std::to_string(limits.cad_timeout_seconds) +
                         " s and was stopped (raise the limit with NURBSREG_CAD_TIMEOUT=<s>)");
  }
  if (WIFSIGNALED(status)) {
    const int signal = WTERMSIG(status);
    if (signal == SIGXCPU) {
      throw InputError(path, "the " + format + " import used more than " +
                                 std::to_string(limits.cad_timeout_seconds) +
                                 " s of CPU time and was stopped (NURBSREG_CAD_TIMEOUT=<s>)");
    }
    throw InputError(path, "OpenCASCADE's " + format + " reader crashed on this file (" +
                               signal_name(signal) +
                               "): the file is malformed, e.g. an entity that references itself");
  }
  if (message.empty()) {
    throw InputError(path, "the " + format + " import process ended (exit status " +
                               std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) +
                               ") without a result");
  }
  const char tag = message.front();
  const std::string_view payload = std::string_view(message).substr(1);
  switch (tag) {
    case kModel: {
      const std::size_t newline = payload.find('\n');
      if (newline == std::string_view::npos) break;
      if (report != nullptr) *report = report_from_json(payload.substr(0, newline));
      // parse_model: exact (shortest round-trip numbers) and the same checks as a JSON file.
      return parse_model(payload.substr(newline + 1), path);
    }
    case kInputError:
      throw InputError(path, std::string(payload));
    case kOutOfMemory:
      throw InputError(path, "the " + format + " import needed more than " +
                                 std::to_string(limits.cad_memory_mb) +
                                 " MiB and was stopped (raise the limit with "
                                 "NURBSREG_CAD_MEMORY_MB=<MiB>)");
    case kFailure:
      throw std::runtime_error(path + ": " + std::string(payload));
    default:
      break;
  }
  throw InputError(path, "the " + format + " import process returned a malformed result");
}

}  // namespace nurbsreg::io::cad_detail

#pragma once
// `nurbsreg serve`: a long-running HTTP/1.1 service that keeps models prepared and answers
// frames (CONTRACT.md §4; README "Alignment service"). The HTTP layer only parses, admits,
// calls the library and serialises; every number comes from the calls behind the CLI:
// registration::Aligner for POST /v1/align (the report filled by io::make_alignment_report, as
// `align --report`), io::project_cloud and io::write_projection_csv for POST /v1/project (as
// `project --out R.csv`). A frame therefore gets the same answer here as from the CLI, bit for
// bit.
//
// HTTP library: cpp-httplib (Debian's libcpp-httplib-dev 0.11.4), chosen because it is packaged
// by Debian, small, and its model is one we can bound:
//  - threading: a blocking accept loop hands each connection to a TaskQueue that we supply
//    (BoundedTaskQueue: --connections workers and a bounded wait list; a connection beyond it is
//    answered 503 at once), and a worker serves that connection's requests one after the other
//    (keep-alive); the frame's own work is parallel inside the library (TBB), so a handful of
//    connection threads keep every core busy;
//  - keep-alive with a count and an idle timeout per connection; read and write timeouts per
//    socket operation;
//  - limits: the body length is checked from Content-Length before a byte is read (payload
//    limit, 413) and a handler that reads the body itself (content-reader handlers, used here)
//    counts it while reading (chunked bodies, decompressed bodies); an Expect: 100-continue
//    hook refuses a request before the client sends its body.
// Boost.Beast (asynchronous, more control) would need far more code for the same guarantees;
// civetweb and libmicrohttpd are C APIs with their own thread pools that we could not bound in
// the same way.
//
// Threads: add_model() before bind(); run() blocks and serves until stop(), which any thread
// may call (not a signal handler: the caller's signal thread does). run() returns once the
// requests already read are answered. Service objects are independent.

#include <cstddef>
#include <memory>
#include <optional>
#include <string>

#include "nurbsreg/icp/icp.hpp"

namespace nurbsreg::service {

struct ServiceOptions {
  std::string bind = "127.0.0.1";  // loopback unless told otherwise
  int port = 0;                    // 0: an ephemeral port (bind() returns it)
  int connections = 16;            // connection workers (each serves one connection at a time)
  // Frames (align, project) computed at once; beyond it, 503 with Retry-After. 0: the
  // hardware threads.
  int max_inflight = 0;
  // Connections waiting for a free worker; beyond it a connection is answered 503 at once.
  // 0: as many as --connections.
  std::size_t max_queue = 0;
  std::size_t max_body = std::size_t{256} << 20;  // bytes; larger bodies: 413
  std::string token;  // bearer token required on every request but /healthz; empty: none
  // Models may be loaded at run time (POST /v1/models) from below this directory only; empty:
  // POST /v1/models is refused.
  std::string model_root;
  // Per request, from its start: the body must arrive (408), a busy session free up (409) and
  // the alignment or projection finish (504: registration::AlignRequest::deadline stops the
  // coarse stage and ICP, a projection stops between blocks) within this. A request's
  // `time_limit` may tighten it for its computation.
  double time_limit_seconds = 30.0;
  double session_idle_seconds = 300.0;  // sessions unused this long expire
  std::size_t max_sessions = 64;
  int keep_alive_seconds = 5;
  int keep_alive_requests = 10000;
  icp::IcpOptions icp;  // every frame's ICP options; requests may override some (README)

  // An error naming the option, or nothing.
  std::optional<std::string> validate() const;
};

class Service {
 public:
  explicit Service(ServiceOptions options);
  ~Service();
  Service(const Service&) = delete;
  Service& operator=(const Service&) = delete;

  // Loads and prepares a model file (any format io::read_model_file reads). `id` empty: the
  // file's stem. Throws io::InputError naming the file, std::invalid_argument for a duplicate
  // or malformed id.
  void add_model(const std::string& path, std::string id = {});

  // Binds the listening socket; returns the port. Throws std::runtime_error naming the address.
  int bind();
  // Serves until stop(); returns after in-flight requests are answered.
  void run();
  // Stops accepting and closes the idle keep-alive connections at once (the requests being
  // handled are answered, then their connections closed); idempotent, thread-safe. Before run()
  // it makes run() return at once.
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace nurbsreg::service

#include "metrics.hpp"

#include <unistd.h>

#include <charconv>
#include <fstream>
#include <sstream>

namespace nurbsreg::service::detail {
namespace {

// Shortest exact form ("0.005", not "0.0050000000000000001").
std::string number(double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  return std::string(buffer, result.ptr);
}

}  // namespace

const char* endpoint_name(Endpoint e) {
  switch (e) {
    case Endpoint::healthz:
      return "healthz";
    case Endpoint::models:
      return "models";
    case Endpoint::align:
      return "align";
    case Endpoint::project:
      return "project";
    case Endpoint::metrics:
      return "metrics";
    case Endpoint::other:
      break;
  }
  return "other";
}

void Metrics::record(Endpoint endpoint, int status, double seconds, std::size_t points) {
  const auto e = static_cast<std::size_t>(endpoint);
  std::lock_guard lock(mutex_);
  ++requests_[{endpoint, status}];
  Histogram& h = latency_[e];
  std::size_t bucket = 0;
  while (bucket < kBuckets.size() && seconds > kBuckets[bucket])
    ++bucket;
  ++h.counts[bucket];
  h.sum += seconds;
  ++h.count;
  points_[e] += points;
}

std::string Metrics::prometheus_text(const Gauges& g) const {
  std::ostringstream out;
  std::lock_guard lock(mutex_);
  out << "# HELP nurbsreg_requests_total HTTP requests answered, by endpoint and status.\n"
         "# TYPE nurbsreg_requests_total counter\n";
  for (const auto& [key, count] : requests_) {
    out << "nurbsreg_requests_total{endpoint=\"" << endpoint_name(key.first) << "\",status=\""
        << key.second << "\"} " << count << "\n";
  }
  out << "# HELP nurbsreg_request_duration_seconds Time from the request line to the answer.\n"
         "# TYPE nurbsreg_request_duration_seconds histogram\n";
  for (std::size_t e = 0; e < kEndpoints; ++e) {
    const Histogram& h = latency_[e];
    if (h.count == 0) continue;
    const char* name = endpoint_name(static_cast<Endpoint>(e));
    std::uint64_t cumulative = 0;
    for (std::size_t b = 0; b <= kBuckets.size(); ++b) {
      cumulative += h.counts[b];
      out << "nurbsreg_request_duration_seconds_bucket{endpoint=\"" << name << "\",le=\"";
      if (b < kBuckets.size()) {
        out << number(kBuckets[b]);
      } else {
        out << "+Inf";
      }
      out << "\"} " << cumulative << "\n";
    }
    out << "nurbsreg_request_duration_seconds_sum{endpoint=\"" << name << "\"} " << number(h.sum)
        << "\n"
        << "nurbsreg_request_duration_seconds_count{endpoint=\"" << name << "\"} " << h.count
        << "\n";
  }
  out << "# HELP nurbsreg_points_total Scan points aligned or projected (rate() gives points/s).\n"
         "# TYPE nurbsreg_points_total counter\n";
  for (const Endpoint e : {Endpoint::align, Endpoint::project}) {
    out << "nurbsreg_points_total{endpoint=\"" << endpoint_name(e) << "\"} "
        << points_[static_cast<std::size_t>(e)] << "\n";
  }
  out << "# HELP nurbsreg_in_flight Frames being computed now.\n"
         "# TYPE nurbsreg_in_flight gauge\n"
      << "nurbsreg_in_flight " << g.in_flight << "\n"
      << "# HELP nurbsreg_max_in_flight The admission limit (--max-inflight).\n"
         "# TYPE nurbsreg_max_in_flight gauge\n"
      << "nurbsreg_max_in_flight " << g.max_inflight << "\n"
      << "# HELP nurbsreg_queue_length Accepted connections waiting for a worker.\n"
         "# TYPE nurbsreg_queue_length gauge\n"
      << "nurbsreg_queue_length " << g.waiting_connections << "\n"
      << "# HELP nurbsreg_refused_connections_total Connections answered 503 because the wait "
         "list was full.\n"
         "# TYPE nurbsreg_refused_connections_total counter\n"
      << "nurbsreg_refused_connections_total " << g.refused_connections << "\n"
      << "# HELP nurbsreg_overloaded_total Frames refused with 503 (--max-inflight reached).\n"
         "# TYPE nurbsreg_overloaded_total counter\n"
      << "nurbsreg_overloaded_total " << overloads_.load() << "\n"
      << "# HELP nurbsreg_sessions Live sessions.\n"
         "# TYPE nurbsreg_sessions gauge\n"
      << "nurbsreg_sessions " << g.sessions << "\n"
      << "# HELP nurbsreg_models Prepared models.\n"
         "# TYPE nurbsreg_models gauge\n"
      << "nurbsreg_models " << g.models << "\n"
      << "# HELP nurbsreg_resident_memory_bytes Resident set size of the process.\n"
         "# TYPE nurbsreg_resident_memory_bytes gauge\n"
      << "nurbsreg_resident_memory_bytes " << resident_bytes() << "\n";
  return out.str();
}

std::size_t resident_bytes() {
  std::ifstream statm("/proc/self/statm");
  std::size_t pages_total = 0, pages_resident = 0;
  if (!(statm >> pages_total >> pages_resident)) return 0;
  return pages_resident * static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
}

}  // namespace nurbsreg::service::detail

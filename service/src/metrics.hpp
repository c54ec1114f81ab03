#pragma once
// The service's counters and their Prometheus text exposition (GET /metrics, text format
// 0.0.4): requests by endpoint and status, a latency histogram per endpoint, points processed
// per endpoint (points/s is rate() of the counter), frames in flight, connections waiting,
// connections and frames refused, sessions, models and the resident memory. Thread-safe: one
// mutex around the maps (a few updates per frame, nothing per point). Private to service/.

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <utility>

namespace nurbsreg::service::detail {

enum class Endpoint { healthz, models, align, project, metrics, other };
inline constexpr std::size_t kEndpoints = 6;
const char* endpoint_name(Endpoint e);

class Metrics {
 public:
  // Upper bounds of the latency buckets, seconds (+Inf implied).
  static constexpr std::array<double, 13> kBuckets = {0.005, 0.01, 0.025, 0.05, 0.075, 0.1, 0.15,
                                                      0.25,  0.5,  1.0,   2.5,  5.0,   10.0};

  void record(Endpoint endpoint, int status, double seconds, std::size_t points);
  void count_overload() { overloads_.fetch_add(1); }

  // Gauges sampled when the text is produced.
  struct Gauges {
    int in_flight = 0;
    int max_inflight = 0;
    std::size_t waiting_connections = 0;
    std::size_t refused_connections = 0;
    std::size_t sessions = 0;
    std::size_t models = 0;
  };
  std::string prometheus_text(const Gauges& gauges) const;

 private:
  struct Histogram {
    std::array<std::uint64_t, kBuckets.size() + 1> counts{};  // last: +Inf
    double sum = 0.0;
    std::uint64_t count = 0;
  };
  mutable std::mutex mutex_;
  std::map<std::pair<Endpoint, int>, std::uint64_t> requests_;
  std::array<Histogram, kEndpoints> latency_{};
  std::array<std::uint64_t, kEndpoints> points_{};
  std::atomic<std::uint64_t> overloads_{0};
};

// The process's resident set size in bytes (/proc/self/statm), 0 when unknown.
std::size_t resident_bytes();

}  // namespace nurbsreg::service::detail

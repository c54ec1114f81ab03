#pragma once
// Admission control of the service (private to service/).
//
// BoundedTaskQueue: httplib's TaskQueue with a fixed set of workers and a bounded wait list of
// accepted connections. A connection that finds the list full is served on the accepting
// thread with `overflowing()` true, so every request on it is answered 503 at once (the
// response says Connection: close); the accept loop is held up for that one short answer only.
// httplib's own ThreadPool queues without bound, which lets a crowd of clients hold memory and
// wait forever. httplib calls shutdown() on the accepting thread once its accept loop has ended:
// `before_join` runs there, when no connection can be added any more.
//
// InflightGate: at most `limit` frames computed at once; try_enter() never waits.

#include <httplib.h>

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace nurbsreg::service::detail {

class BoundedTaskQueue final : public httplib::TaskQueue {
 public:
  // `counters` (owned by the caller, outliving the queue) receive the wait-list length and the
  // connections refused.
  struct Counters {
    std::atomic<std::size_t> waiting{0};
    std::atomic<std::size_t> overflowed{0};
  };
  BoundedTaskQueue(std::size_t workers, std::size_t max_waiting, Counters& counters,
                   std::function<void()> before_join = {});
  ~BoundedTaskQueue() override;

  void enqueue(std::function<void()> fn) override;
  // Runs `before_join` (once), lets the workers finish every connection handed over, then joins
  // them.
  void shutdown() override;

  // True on a thread serving an overflow connection.
  static bool overflowing();

 private:
  void work();

  std::size_t max_waiting_;
  Counters& counters_;
  std::function<void()> before_join_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::function<void()>> jobs_;
  bool shutdown_ = false;
  std::vector<std::thread> threads_;
};

class InflightGate {
 public:
  explicit InflightGate(int limit) : limit_(limit) {}
  bool try_enter() {
    int now = count_.load();
    while (now < limit_) {
      if (count_.compare_exchange_weak(now, now + 1)) return true;
    }
    return false;
  }
  void leave() { count_.fetch_sub(1); }
  bool has_room() const { return count_.load() < limit_; }
  int count() const { return count_.load(); }
  int limit() const { return limit_; }

 private:
  const int limit_;
  std::atomic<int> count_{0};
};

// One admitted frame: leaves the gate when destroyed.
class InflightSlot {
 public:
  InflightSlot() = default;
  explicit InflightSlot(InflightGate* gate) : gate_(gate) {}
  InflightSlot(InflightSlot&& other) noexcept : gate_(std::exchange(other.gate_, nullptr)) {}
  InflightSlot(const InflightSlot&) = delete;
  InflightSlot& operator=(const InflightSlot&) = delete;
  InflightSlot& operator=(InflightSlot&&) = delete;
  ~InflightSlot() {
    if (gate_) gate_->leave();
  }

 private:
  InflightGate* gate_ = nullptr;
};

}  // namespace nurbsreg::service::detail

#include "admission.hpp"

namespace nurbsreg::service::detail {
namespace {
thread_local bool t_overflowing = false;
}

BoundedTaskQueue::BoundedTaskQueue(std::size_t workers, std::size_t max_waiting, Counters& counters,
                                   std::function<void()> before_join)
    : max_waiting_(max_waiting), counters_(counters), before_join_(std::move(before_join)) {
  threads_.reserve(workers);
  for (std::size_t i = 0; i < workers; ++i)
    threads_.emplace_back([this] { work(); });
}

BoundedTaskQueue::~BoundedTaskQueue() {
  shutdown();
}

bool BoundedTaskQueue::overflowing() {
  return t_overflowing;
}

void BoundedTaskQueue::enqueue(std::function<void()> fn) {
  {
    std::lock_guard lock(mutex_);
    if (!shutdown_ && jobs_.size() < max_waiting_) {
      jobs_.push_back(std::move(fn));
      counters_.waiting.store(jobs_.size());
      wake_.notify_one();
      return;
    }
  }
  // Full: answer this connection here, every request on it with 503.
  counters_.overflowed.fetch_add(1);
  t_overflowing = true;
  fn();
  t_overflowing = false;
}

void BoundedTaskQueue::work() {
  while (true) {
    std::function<void()> job;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return shutdown_ || !jobs_.empty(); });
      if (jobs_.empty()) return;  // shut down and nothing left
      job = std::move(jobs_.front());
      jobs_.pop_front();
      counters_.waiting.store(jobs_.size());
    }
    job();
  }
}

void BoundedTaskQueue::shutdown() {
  if (before_join_) std::exchange(before_join_, {})();
  {
    std::lock_guard lock(mutex_);
    shutdown_ = true;
  }
  wake_.notify_all();
  for (std::thread& t : threads_) {
    if (t.joinable()) t.join();
  }
  threads_.clear();
}

}  // namespace nurbsreg::service::detail

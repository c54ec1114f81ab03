#pragma once
// FrameLock (private to service/): the lock a session's frames take in turn, with a deadline.
// A std::timed_mutex would do, but its try_lock_until on the steady clock calls
// pthread_mutex_clocklock, which ThreadSanitizer (LLVM 14, Debian's clang) does not intercept:
// it then sees every unlock as one of an unlocked mutex, and the tsan stage fails on a correct
// program. A flag under a std::mutex with a condition variable, whose waits it sees, has the
// same meaning.

#include <chrono>
#include <condition_variable>
#include <mutex>

namespace nurbsreg::service::detail {

class FrameLock {
 public:
  void lock() {
    std::unique_lock lock(mutex_);
    released_.wait(lock, [this] { return !held_; });
    held_ = true;
  }
  bool try_lock() {
    std::lock_guard lock(mutex_);
    if (held_) return false;
    held_ = true;
    return true;
  }
  template <class Clock, class Duration>
  bool try_lock_until(const std::chrono::time_point<Clock, Duration>& deadline) {
    std::unique_lock lock(mutex_);
    if (!released_.wait_until(lock, deadline, [this] { return !held_; })) return false;
    held_ = true;
    return true;
  }
  void unlock() {
    {
      std::lock_guard lock(mutex_);
      held_ = false;
    }
    released_.notify_one();
  }

 private:
  std::mutex mutex_;
  std::condition_variable released_;
  bool held_ = false;
};

}  // namespace nurbsreg::service::detail

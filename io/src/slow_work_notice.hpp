#pragma once
// Internal to io: a line for a person waiting on work that is usually quick but can take seconds
// (a STEP part's conversion, a model's features): logged at info only once the work has run for
// `after`, from a thread that waits for it. Quick work, and quick failures (a malformed file whose
// error is then the only line), say nothing.

#include <spdlog/spdlog.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>

namespace nurbsreg::io::detail {

class SlowWorkNotice {
 public:
  explicit SlowWorkNotice(std::string line,
                          std::chrono::milliseconds after = std::chrono::milliseconds(1000))
      : waiter_([this, line = std::move(line), after] {
          std::unique_lock lock(mutex_);
          if (!done_signal_.wait_for(lock, after, [this] { return done_; })) {
            spdlog::info("{}", line);
          }
        }) {}
  ~SlowWorkNotice() {
    {
      std::lock_guard lock(mutex_);
      done_ = true;
    }
    done_signal_.notify_one();
    waiter_.join();
  }
  SlowWorkNotice(const SlowWorkNotice&) = delete;
  SlowWorkNotice& operator=(const SlowWorkNotice&) = delete;

 private:
  std::mutex mutex_;
  std::condition_variable done_signal_;
  bool done_ = false;
  std::thread waiter_;  // last: starts once the members it reads exist
};

}  // namespace nurbsreg::io::detail

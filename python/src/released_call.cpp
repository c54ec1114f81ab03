#include "released_call.hpp"

#include <pybind11/pybind11.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <thread>

namespace nurbsreg::python {
namespace py = pybind11;
namespace {

// Python's main thread (threading.main_thread().ident): PyErr_CheckSignals runs handlers only
// there.
unsigned long main_thread_ident = 0;

struct Job {
  const std::function<void()>* work = nullptr;
  int threads = 0;
  tbb::task_group_context context;
  std::exception_ptr error;
  std::mutex mutex;
  std::condition_variable changed;
  bool done = false;
};

// work() as a task of the job's group, so that cancelling job.context stops it.
void execute(Job& job) {
  const auto body = [&job] {
    tbb::task_group group(job.context);
    group.run_and_wait([&job] { (*job.work)(); });
  };
  try {
    if (job.threads > 0) {
      tbb::task_arena arena(job.threads);
      arena.execute(body);
    } else {
      body();
    }
  } catch (...) {
    job.error = std::current_exception();
  }
}

// Threads that run watched jobs; never destroyed (they may still wait at interpreter exit, and
// they touch nothing of Python).
class Helpers {
 public:
  static Helpers& instance() {
    static Helpers* helpers = new Helpers;
    return *helpers;
  }

  void submit(Job& job) {
    std::lock_guard lock(mutex_);
    queue_.push_back(&job);
    if (idle_ < queue_.size()) std::thread([this] { loop(); }).detach();
    ready_.notify_one();
  }

 private:
  void loop() {
    for (;;) {
      Job* job = nullptr;
      {
        std::unique_lock lock(mutex_);
        ++idle_;
        ready_.wait(lock, [this] { return !queue_.empty(); });
        --idle_;
        job = queue_.front();
        queue_.pop_front();
      }
      execute(*job);
      // Notified under the lock: the caller may destroy the job as soon as it sees done.
      std::lock_guard lock(job->mutex);
      job->done = true;
      job->changed.notify_all();
    }
  }

  std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<Job*> queue_;
  std::size_t idle_ = 0;
};

bool on_main_thread() {
  return PyThread_get_thread_ident() == main_thread_ident;
}

}  // namespace

void init_released_calls() {
  main_thread_ident =
      py::module_::import("threading").attr("main_thread")().attr("ident").cast<unsigned long>();
}

void run_released(int threads, bool watch, const std::function<void()>& work) {
  Job job;
  job.work = &work;
  job.threads = threads;
  if (!watch || !on_main_thread()) {
    {
      py::gil_scoped_release release;
      execute(job);
    }
    if (job.error) std::rethrow_exception(job.error);
    return;
  }
  // The handler's exception, kept aside while the GIL is released and the work winds down.
  PyObject *type = nullptr, *value = nullptr, *traceback = nullptr;
  {
    py::gil_scoped_release release;
    Helpers::instance().submit(job);
    std::unique_lock lock(job.mutex);
    while (!job.changed.wait_for(lock, std::chrono::milliseconds(20), [&] { return job.done; })) {
      if (type != nullptr) continue;  // cancelled: waiting for the tasks to stop
      lock.unlock();
      {
        py::gil_scoped_acquire gil;
        if (PyErr_CheckSignals() != 0) PyErr_Fetch(&type, &value, &traceback);
      }
      if (type != nullptr) job.context.cancel_group_execution();
      lock.lock();
    }
  }
  if (type != nullptr) {
    PyErr_Restore(type, value, traceback);
    throw py::error_already_set();
  }
  if (job.error) std::rethrow_exception(job.error);
}

}  // namespace nurbsreg::python

// The tsan stage's proof that it can see a race inside a TBB task (scripts/test.sh, tests
// TsanTbb.*). With an uninstrumented libtbb TSan cannot order a task's accesses against the
// caller's, so the stage's suppressions once had to hide everything inside tasks: a real race
// there went unseen. Run with no argument: a correct parallel_for (results written in tasks,
// read after the join; per-thread sums through enumerable_thread_specific), which must get no
// report. With `race`: every task also adds to one plain integer, which must be reported.
// Either way two threads must run the tasks: on a loaded machine TBB's worker could arrive after
// the caller had run every task (CI: no report, the canary failed), so each thread's first task
// waits, up to 30 s, until a second thread has one too; a run that never got two says so.
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <thread>
#include <vector>

int main(int argc, char** argv) {
  const bool race = argc > 1 && std::strcmp(argv[1], "race") == 0;
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 2);
  std::vector<double> values(200000);
  tbb::enumerable_thread_specific<long> per_thread(0);
  long shared = 0;
  std::atomic<int> threads_in{0};
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, values.size(), 1000),
                    [&](const tbb::blocked_range<std::size_t>& r) {
                      thread_local bool entered = false;
                      if (!entered) {
                        entered = true;
                        threads_in.fetch_add(1);
                        while (threads_in.load() < 2 && std::chrono::steady_clock::now() < deadline)
                          std::this_thread::yield();
                      }
                      for (std::size_t i = r.begin(); i != r.end(); ++i)
                        values[i] = 0.5 * i;
                      per_thread.local() += static_cast<long>(r.size());
                      if (race) shared += static_cast<long>(r.size());
                    });
  double sum = 0;
  for (const double v : values)
    sum += v;
  long counted = 0;
  for (const long n : per_thread)
    counted += n;
  std::printf("sum %.1f, %ld values counted, shared %ld, %d threads ran tasks\n", sum, counted,
              shared, threads_in.load());
  if (threads_in.load() < 2) {
    std::printf("only one thread ran the tasks in 30 s: this run shows nothing\n");
    return 2;
  }
  return counted == static_cast<long>(values.size()) ? 0 : 1;
}

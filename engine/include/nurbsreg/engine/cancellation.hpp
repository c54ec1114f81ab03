#pragma once
// Cancellation of a computation from outside (Python's Ctrl-C cancels the TBB task group its
// released call runs in). A cancelled parallel loop returns normally with part of its work not
// done; the serial code after it must not go on with those partial results (a feature matching
// over descriptors never computed read garbage indices and crashed). Every parallel loop of the
// library is therefore followed by stop_if_cancelled(), which turns the cancellation into an
// exception that unwinds the whole call.
#include <tbb/task_group.h>

#include <stdexcept>

namespace nurbsreg::engine {

struct Cancelled : std::runtime_error {
  Cancelled() : std::runtime_error("the computation was cancelled") {}
};

inline void stop_if_cancelled() {
  if (tbb::is_current_task_group_canceling()) throw Cancelled();
}

}  // namespace nurbsreg::engine

#pragma once
// Long calls without the GIL that Ctrl-C can stop.
//
// run_released(threads, watch, work) runs work() with the GIL released, inside a TBB task arena
// of `threads` threads (0: the default arena, all hardware threads; as the CLI's --threads, but
// for this call only, so concurrent calls from several Python threads may each choose). With
// `watch` set and called from Python's main thread (the only one signals reach), work() runs on
// a helper thread while the caller checks Python's signal handlers every 20 ms: an exception
// from a handler (KeyboardInterrupt for Ctrl-C) cancels work()'s TBB tasks (task_group_context
// cancellation reaches every nested parallel loop), waits until work() has returned, and is
// raised (py::error_already_set). work()'s results are then incomplete: the caller discards
// them. Exceptions thrown by work() propagate unchanged. The caller holds the GIL.
//
// Helper threads are kept for later calls (one per concurrent watched call), so the per-thread
// scratch of a Projector they use is made once, not per call.

#include <functional>

namespace nurbsreg::python {

void run_released(int threads, bool watch, const std::function<void()>& work);

// Remembers the main thread (call once at import, from any thread).
void init_released_calls();

}  // namespace nurbsreg::python

// One way to stop a computation early: its caller's std::atomic<bool> flag (a cancelled job, a
// service shutting down, Ctrl-C). Functions that take a flag (RunSweep, SweepRow, ParallelFor) run
// under a CancelScope of it, and code whose signature carries none (the engines' loops, the fit's
// and the diagnosis's ParallelFor calls and Ceres solves) polls the scope's flag of the thread it
// runs on; ParallelFor hands the flag on to the threads it starts. So one flag reaches every loop of
// a computation, at least once per ~1e5 engine steps (a few ms), and the computation ends with
// Cancelled. Threads a library starts on its own (Ceres' pool) see no flag and are never stopped
// mid-evaluation: their solve is aborted between iterations instead.
#pragma once

#include <atomic>

namespace strokelab {

// Runs the calling thread under `flag` (nullptr: no flag) until destroyed; scopes nest.
class CancelScope {
 public:
  explicit CancelScope(const std::atomic<bool>* flag);
  ~CancelScope();
  CancelScope(const CancelScope&) = delete;
  CancelScope& operator=(const CancelScope&) = delete;

 private:
  const std::atomic<bool>* previous_;
};

// The flag of the calling thread's innermost CancelScope (nullptr outside any).
const std::atomic<bool>* CurrentCancelFlag();

// Whether the calling thread's flag is raised.
bool CancelRequested();

// Throws Cancelled (errors.h) when the calling thread's flag is raised.
void ThrowIfCancelled();

}  // namespace strokelab

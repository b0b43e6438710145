// Cooperative interruption of long C++ loops (Ctrl-C in an interactive session).
//
// The core does not depend on Python: a front end installs a process-wide hook that says
// whether the user asked to stop (the Python module's hook runs PyErr_CheckSignals), and
// long loops call checkInterrupt() between units of work -- once per ICP iteration, per
// batch of RANSAC hypotheses, per chunk of points. It is called only from the thread that
// owns the call, never inside an OpenMP parallel region (an exception must not leave one),
// so a loop stops at the next such point and unwinds normally: no partial result is
// returned and objects it was updating keep a valid state (the ICP engine's target tree,
// for example, is untouched by align()).
#pragma once

#include <atomic>
#include <stdexcept>

namespace scanalign {

/// Thrown by checkInterrupt() when the installed hook asks to stop. The Python module
/// turns it into KeyboardInterrupt (or whatever the signal handler raised).
class Interrupted : public std::runtime_error {
 public:
  Interrupted() : std::runtime_error("interrupted") {}
};

/// The hook: returns true when the running call should stop. nullptr (the default, and
/// in pure C++ programs) means never. Set once at start-up by a front end.
using InterruptHook = bool (*)();
inline std::atomic<InterruptHook> interrupt_hook{nullptr};

/// True when a hook is installed and returns true. For the one thread that owns a
/// parallel region (e.g. OpenMP thread 0): it sets a flag the others read, and the owner
/// throws Interrupted after the region. One atomic load when no hook is installed; the
/// Python hook itself rate-limits its work to one signal check per 20 ms.
inline bool interruptRequested() {
  const InterruptHook hook = interrupt_hook.load(std::memory_order_acquire);
  return hook != nullptr && hook();
}

/// Throws Interrupted when interruptRequested(). Call it between units of work, outside
/// parallel regions.
inline void checkInterrupt() {
  if (interruptRequested()) throw Interrupted();
}

}  // namespace scanalign

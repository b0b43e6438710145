// How many OpenMP threads a call uses. Every parallel region of the library asks here, so
// one rule holds everywhere: 0 (or less) means all cores, and a request above the machine's
// processors is clamped to them. More threads than cores only add overhead, and thousands
// of them exhaust the process's stack space: a crash, not an error the caller could catch.
#pragma once

#include <algorithm>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace scanalign {

inline int resolveThreads(int requested) {
#ifdef _OPENMP
  const int all = std::max(1, std::max(omp_get_max_threads(), omp_get_num_procs()));
  return requested <= 0 ? std::max(1, omp_get_max_threads()) : std::min(requested, all);
#else
  (void)requested;
  return 1;
#endif
}

}  // namespace scanalign

// Deterministic parallel reduction: the "summing tree" of the eye-in-hand paper
// (Comput. Electron. Agric. 180 (2021) 105929), §3.2, on CPU cores.
//
// The index range is cut into fixed blocks; each block is summed sequentially into its
// own partial (a thread-local value, so threads never share cache lines while adding),
// and the partials are merged pairwise in a fixed order. The sum therefore does not
// depend on the number of threads or on scheduling, and a GPU backend can reproduce it.
#pragma once

#include "scanalign/common/threads.hpp"

#include <algorithm>
#include <cstddef>
#include <vector>

#include <omp.h>

namespace scanalign {

inline constexpr std::size_t kReduceBlock = 1024;  ///< indices per leaf of the summing tree

/// Pairwise merge of parts[0..n) in a fixed order; returns the total (parts is clobbered).
template <typename Partial>
Partial treeReduce(std::vector<Partial>& parts) {
  const std::size_t n = parts.size();
  if (n == 0) return Partial{};
  for (std::size_t stride = 1; stride < n; stride *= 2)
    for (std::size_t i = 0; i + stride < n; i += 2 * stride) parts[i].merge(parts[i + stride]);
  return parts[0];
}

/// Sums fn(i, partial) over i in [0, n) with `threads` OpenMP threads (0: OpenMP default).
/// `scratch` is resized to the block count (reuse it across calls to avoid allocation).
template <typename Partial, typename Fn>
Partial blockReduce(std::size_t n, int threads, std::vector<Partial>& scratch, Fn&& fn) {
  const std::size_t nblocks = (n + kReduceBlock - 1) / kReduceBlock;
  scratch.resize(nblocks);
#pragma omp parallel for schedule(dynamic, 1) num_threads(resolveThreads(threads))
  for (std::ptrdiff_t b = 0; b < static_cast<std::ptrdiff_t>(nblocks); ++b) {
    Partial part{};
    const std::size_t begin = static_cast<std::size_t>(b) * kReduceBlock;
    const std::size_t end = std::min(n, begin + kReduceBlock);
    for (std::size_t i = begin; i < end; ++i) fn(i, part);
    scratch[b] = part;
  }
  return treeReduce(scratch);
}

}  // namespace scanalign

// The pose pairs (i, j) a relative pose error is measured over, chosen as evo's
// metrics.RPE chooses them (evo: Grupp, "evo: Python package for the evaluation of
// odometry and SLAM", 2017). Header-only: one short function.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

namespace scanalign {

/// Pairs over a non-decreasing sequence `s` (frame indices, path length in metres or
/// timestamps in seconds):
/// - consecutive (all_pairs false): the chain 0 = i_0 < i_1 < ..., i_{k+1} the first index
///   with s[i_{k+1}] - s[i_k] >= delta;
/// - all pairs: for every i, the first j > i minimising |(s[j] - s[i]) - delta|, kept when
///   that is <= tol.
inline std::vector<std::pair<std::int64_t, std::int64_t>> relativePosePairs(const std::vector<double>& s,
                                                                            double delta, bool all_pairs,
                                                                            double tol) {
  std::vector<std::pair<std::int64_t, std::int64_t>> pairs;
  const auto n = static_cast<std::int64_t>(s.size());
  if (!all_pairs) {
    for (std::int64_t i = 0, j = 1; j < n; ++j)
      if (s[j] - s[i] >= delta) pairs.emplace_back(i, j), i = j;
    return pairs;
  }
  for (std::int64_t i = 0; i + 1 < n; ++i) {
    const auto first = s.begin() + i + 1;
    const auto err = [&](std::int64_t j) { return std::abs((s[j] - s[i]) - delta); };
    // s[k] is the first value >= s[i] + delta; only k and its predecessor can be closest,
    // and of equal values the first index counts.
    std::int64_t j = std::lower_bound(first, s.end(), s[i] + delta) - s.begin();
    if (j == n || (j > i + 1 && err(j - 1) <= err(j))) j = std::lower_bound(first, s.end(), s[j - 1]) - s.begin();
    if (err(j) <= tol) pairs.emplace_back(i, j);
  }
  return pairs;
}

}  // namespace scanalign

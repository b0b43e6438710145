// Nearest-timestamp matching as evo's sync.associate_trajectories does it (Grupp, "evo:
// Python package for the evaluation of odometry and SLAM", 2017). Header-only: one short
// function.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace scanalign {

/// For every time of `shorter`, the nearest time of `longer` (sorted ascending) within
/// `max_difference` (s, inclusive; ties to the earlier one): pairs (i_shorter, i_longer)
/// in the order of `shorter`. An index of `longer` may be used more than once. Throws
/// std::invalid_argument for a NaN, infinite or negative max_difference and for non-finite
/// timestamps (a NaN compares false both ways: it would be skipped or break the sort check).
inline std::vector<std::pair<std::int64_t, std::int64_t>> associateNearest(const std::vector<double>& shorter,
                                                                           const std::vector<double>& longer,
                                                                           double max_difference) {
  if (!(max_difference >= 0 && std::isfinite(max_difference)))
    throw std::invalid_argument("max_difference must be a finite number >= 0 (s), got " +
                                std::to_string(max_difference));
  for (const auto* t : {&shorter, &longer})
    if (!std::all_of(t->begin(), t->end(), [](double v) { return std::isfinite(v); }))
      throw std::invalid_argument(std::string("associate_nearest: ") + (t == &shorter ? "shorter" : "longer") +
                                  " has non-finite timestamps");
  if (!std::is_sorted(longer.begin(), longer.end()))
    throw std::invalid_argument("method='nearest' needs the longer trajectory's timestamps sorted");
  std::vector<std::pair<std::int64_t, std::int64_t>> pairs;
  if (longer.empty()) return pairs;
  const double inf = std::numeric_limits<double>::infinity();
  const auto n = static_cast<std::int64_t>(longer.size());
  for (std::size_t i = 0; i < shorter.size(); ++i) {
    const double t = shorter[i];
    if (t < longer.front() - max_difference || t > longer.back() + max_difference) continue;
    const std::int64_t k = std::min<std::int64_t>(std::upper_bound(longer.begin(), longer.end(), t) - longer.begin(),
                                                  n - 1);
    const double above = longer[k] - t, below = k > 0 ? t - longer[k - 1] : inf;
    if (above <= max_difference && above < below) pairs.emplace_back(i, k);
    else if (below <= max_difference && below <= above) pairs.emplace_back(i, k - 1);
  }
  return pairs;
}

}  // namespace scanalign

// Pairing two timestamp streams one-to-one, closest pairs first: the package's one rule
// (the TUM RGB-D benchmark's associate.py, Sturm et al., IROS 2012, with evo's inclusive
// bound). Header-only: one short function.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace scanalign {

/// Index pairs (i, j), sorted by i: every pair with |first[i] - second[j]| <= max_difference
/// is a candidate; candidates are taken by increasing |dt| (ties: smaller i, then smaller
/// j), skipping those whose i or j is already taken. Both streams must be sorted
/// ascending and finite; max_difference (s) finite and >= 0.
inline std::vector<std::pair<std::int64_t, std::int64_t>> associateTimestamps(const std::vector<double>& first,
                                                                              const std::vector<double>& second,
                                                                              double max_difference) {
  if (!(max_difference >= 0 && std::isfinite(max_difference)))
    throw std::invalid_argument("max_difference must be a finite number >= 0 (s), got " +
                                std::to_string(max_difference));
  double largest = 0;
  for (const auto* t : {&first, &second}) {
    const char* name = t == &first ? "first" : "second";
    for (std::size_t k = 0; k < t->size(); ++k) {
      if (!std::isfinite((*t)[k]))
        throw std::invalid_argument(std::string("associate_timestamps: ") + name + " has non-finite timestamps");
      if (k && (*t)[k] < (*t)[k - 1])
        throw std::invalid_argument(std::string("associate_timestamps: ") + name +
                                    " timestamps must be sorted ascending");
      largest = std::max(largest, std::abs((*t)[k]));
    }
  }
  // Windows are widened so that rounding in t +- max_difference never loses a pair; the
  // exact criterion is applied to each candidate.
  const double margin = max_difference * (1 + 1e-9) + 1e-9 * largest;
  std::vector<std::tuple<double, std::int64_t, std::int64_t>> candidates;
  for (std::size_t i = 0; i < first.size(); ++i) {
    auto j = std::lower_bound(second.begin(), second.end(), first[i] - margin);
    for (; j != second.end() && *j <= first[i] + margin; ++j) {
      const double d = std::abs(first[i] - *j);
      if (d <= max_difference) candidates.emplace_back(d, i, j - second.begin());
    }
  }
  std::sort(candidates.begin(), candidates.end());
  std::vector<bool> used_first(first.size()), used_second(second.size());
  std::vector<std::pair<std::int64_t, std::int64_t>> pairs;
  for (const auto& [d, i, j] : candidates) {
    if (used_first[i] || used_second[j]) continue;
    used_first[i] = used_second[j] = true;
    pairs.emplace_back(i, j);
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

}  // namespace scanalign

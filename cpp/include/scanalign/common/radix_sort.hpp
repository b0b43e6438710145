// Stable sort of (key, value) pairs by an integer key, by least-significant-digit radix
// passes: the grids (voxel grid, the normals' cells) sort tens of thousands of cell keys per
// frame, and std::sort's comparisons were a visible part of their time.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace scanalign {

/// Sorts `items` by key; items with equal keys keep their order (as std::stable_sort by
/// key, so items given in increasing value order come out as std::sort of the pairs). Passes
/// of 11 bits cover the bits up to the largest key's highest set bit: O(n) per pass, so
/// compact keys (a few tens of bits) sort in two or three passes.
template <typename Value>
void radixSortByKey(std::vector<std::pair<std::uint64_t, Value>>& items) {
  const std::size_t n = items.size();
  if (n < 2) return;
  std::uint64_t all = 0;
  for (const auto& it : items) all |= it.first;
  int bits = 0;
  while (bits < 64 && (all >> bits) != 0) ++bits;
  constexpr int kDigit = 11;
  constexpr std::size_t kBuckets = std::size_t{1} << kDigit;
  std::vector<std::pair<std::uint64_t, Value>> scratch(n);
  std::vector<std::size_t> start(kBuckets);
  for (int shift = 0; shift < bits; shift += kDigit) {
    std::fill(start.begin(), start.end(), 0);
    for (const auto& it : items) ++start[(it.first >> shift) & (kBuckets - 1)];
    if (std::find(start.begin(), start.end(), n) != start.end()) continue;  // one digit value: order kept
    std::size_t sum = 0;
    for (std::size_t& s : start) {
      const std::size_t c = s;
      s = sum;
      sum += c;
    }
    for (const auto& it : items) scratch[start[(it.first >> shift) & (kBuckets - 1)]++] = it;
    items.swap(scratch);
  }
}

}  // namespace scanalign

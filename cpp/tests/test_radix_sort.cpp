// radixSortByKey against std::stable_sort by key.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include "scanalign/common/radix_sort.hpp"

TEST(RadixSort, EqualsStableSortByKey) {
  std::mt19937_64 rng(3);
  for (const int bits : {1, 7, 11, 12, 23, 40, 64})
    for (const std::size_t n : {0, 1, 2, 100, 50000}) {
      std::vector<std::pair<std::uint64_t, std::uint32_t>> items(n);
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint64_t k = bits == 64 ? rng() : rng() & ((std::uint64_t{1} << bits) - 1);
        items[i] = {k % (n / 4 + 1) == 0 ? 0 : k, static_cast<std::uint32_t>(i)};  // many duplicates
      }
      auto want = items;
      std::stable_sort(want.begin(), want.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
      scanalign::radixSortByKey(items);
      ASSERT_EQ(items, want) << bits << " bits, " << n << " items";
    }
}

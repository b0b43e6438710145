// Morton (Z-curve) order of points: points close in space end up close in the order. The
// ICP engine processes its source in this order (consecutive queries touch the same part of
// the tree, and each one's neighbour is a good search hint for the next); the synthetic
// scene lays out a mesh's faces in it for the renderer's caches.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/common/radix_sort.hpp"

namespace scanalign {

/// Spreads the low 21 bits of v to every third bit (for a 63-bit Morton code).
inline std::uint64_t spreadBits(std::uint64_t v) {
  v &= 0x1fffff;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

/// The permutation sorting `cloud` along a Morton curve of the bounding box of its finite
/// points, quantised to 21 bits per axis; non-finite points come last and equal codes keep
/// their input order. `keyed` is scratch, kept by callers that order clouds repeatedly.
template <typename Scalar, typename Index>
void mortonOrder(const CloudView<Scalar>& cloud, std::vector<Index>& order,
                 std::vector<std::pair<std::uint64_t, Index>>& keyed) {
  Eigen::Array3d lo = Eigen::Array3d::Constant(std::numeric_limits<double>::max());
  Eigen::Array3d hi = Eigen::Array3d::Constant(std::numeric_limits<double>::lowest());
  for (std::size_t i = 0; i < cloud.size; ++i)
    if (cloud.isFinite(i)) {
      const Eigen::Array3d p = cloud[i].template cast<double>().array();
      lo = lo.min(p);
      hi = hi.max(p);
    }
  const double top = double((1 << 21) - 1), scale = top / std::max((hi - lo).maxCoeff(), 1e-12);
  keyed.resize(cloud.size);
  for (std::size_t i = 0; i < cloud.size; ++i) {
    std::uint64_t key = std::numeric_limits<std::uint64_t>::max();
    if (cloud.isFinite(i)) {
      const Eigen::Array3d c = ((cloud[i].template cast<double>().array() - lo) * scale).min(top);
      key = spreadBits(std::uint64_t(c[0])) | spreadBits(std::uint64_t(c[1])) << 1 |
            spreadBits(std::uint64_t(c[2])) << 2;
    }
    keyed[i] = {key, static_cast<Index>(i)};
  }
  radixSortByKey(keyed);
  order.resize(cloud.size);
  for (std::size_t i = 0; i < cloud.size; ++i) order[i] = keyed[i].second;
}

}  // namespace scanalign

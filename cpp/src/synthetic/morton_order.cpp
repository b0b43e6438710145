#include "scanalign/synthetic/morton_order.hpp"

#include <algorithm>
#include <limits>
#include <utility>

#include "scanalign/common/radix_sort.hpp"

namespace scanalign {

namespace {

/// Spreads the low 21 bits of v to every third bit (for a 63-bit Morton code).
std::uint64_t spreadBits(std::uint64_t v) {
  v &= 0x1fffff;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

}  // namespace

std::vector<std::int64_t> mortonOrder(const CloudView<double>& points) {
  Eigen::Array3d lo = Eigen::Array3d::Constant(std::numeric_limits<double>::max());
  Eigen::Array3d hi = Eigen::Array3d::Constant(std::numeric_limits<double>::lowest());
  for (std::size_t i = 0; i < points.size; ++i)
    if (points.isFinite(i)) {
      lo = lo.min(points[i].array());
      hi = hi.max(points[i].array());
    }
  const double scale = double((1 << 21) - 1) / std::max((hi - lo).maxCoeff(), 1e-12);
  std::vector<std::pair<std::uint64_t, std::int64_t>> keyed(points.size);
  for (std::size_t i = 0; i < points.size; ++i) {
    std::uint64_t key = std::numeric_limits<std::uint64_t>::max();
    if (points.isFinite(i)) {
      const Eigen::Array3d c = ((points[i].array() - lo) * scale).min(double((1 << 21) - 1));
      key = spreadBits(std::uint64_t(c[0])) | spreadBits(std::uint64_t(c[1])) << 1 |
            spreadBits(std::uint64_t(c[2])) << 2;
    }
    keyed[i] = {key, static_cast<std::int64_t>(i)};
  }
  radixSortByKey(keyed);
  std::vector<std::int64_t> order(points.size);
  for (std::size_t i = 0; i < points.size; ++i) order[i] = keyed[i].second;
  return order;
}

}  // namespace scanalign

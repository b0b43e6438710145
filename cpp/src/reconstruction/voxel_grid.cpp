#include "scanalign/reconstruction/voxel_grid.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "scanalign/common/radix_sort.hpp"

namespace scanalign {

template <typename Scalar>
VoxelGridResult voxelGrid(const CloudView<Scalar>& points, double leaf_size, const double* attributes,
                          std::size_t attribute_dim, std::uint32_t min_points_per_voxel) {
  if (!(leaf_size > 0.0) || !std::isfinite(leaf_size))
    throw std::invalid_argument("voxel grid: leaf_size must be a finite positive length in metres");
  if (attribute_dim > 0 && attributes == nullptr) throw std::invalid_argument("voxel grid: null attributes");
  VoxelGridResult out;
  // Index arithmetic in the cloud's own precision, as PCL does, so voxel boundaries agree.
  const Scalar inv = Scalar(1) / static_cast<Scalar>(leaf_size);
  std::int64_t lo[3] = {std::numeric_limits<std::int64_t>::max(), std::numeric_limits<std::int64_t>::max(),
                        std::numeric_limits<std::int64_t>::max()};
  std::int64_t hi[3] = {std::numeric_limits<std::int64_t>::min(), std::numeric_limits<std::int64_t>::min(),
                        std::numeric_limits<std::int64_t>::min()};
  auto cell = [&](const Scalar* p, int k) { return voxelCoordinate(p[k], inv); };
  std::size_t finite = 0;
  for (std::size_t i = 0; i < points.size; ++i) {
    if (!points.isFinite(i)) continue;
    ++finite;
    for (int k = 0; k < 3; ++k) {
      const Scalar v = points.ptr(i)[k] * inv;
      if (!(std::abs(double(v)) < 9e18)) throw std::invalid_argument("voxel grid: leaf_size too small for the coordinates");
      lo[k] = std::min(lo[k], cell(points.ptr(i), k));
      hi[k] = std::max(hi[k], cell(points.ptr(i), k));
    }
  }
  if (finite == 0) return out;
  constexpr std::int64_t kAxis = std::int64_t{1} << 21;
  for (int k = 0; k < 3; ++k)
    if (hi[k] - lo[k] >= kAxis)
      throw std::invalid_argument("voxel grid: leaf_size " + std::to_string(leaf_size) +
                                  " m is too small for the cloud's extent (more than 2^21 voxels along an axis)");
  // Compact voxel keys (< 2^63: at most 2^21 voxels per axis) sort in a few radix passes.
  const auto nx = static_cast<std::uint64_t>(hi[0] - lo[0] + 1);
  const auto ny = static_cast<std::uint64_t>(hi[1] - lo[1] + 1);
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed;
  keyed.reserve(finite);
  for (std::size_t i = 0; i < points.size; ++i) {
    if (!points.isFinite(i)) continue;
    const Scalar* p = points.ptr(i);
    const auto x = static_cast<std::uint64_t>(cell(p, 0) - lo[0]);
    const auto y = static_cast<std::uint64_t>(cell(p, 1) - lo[1]);
    const auto z = static_cast<std::uint64_t>(cell(p, 2) - lo[2]);
    keyed.emplace_back((z * ny + y) * nx + x, static_cast<std::uint32_t>(i));  // PCL's z-y-x order
  }
  radixSortByKey(keyed);  // stable: within a voxel, input order
  for (std::size_t a = 0; a < keyed.size();) {
    std::size_t b = a;
    while (b < keyed.size() && keyed[b].first == keyed[a].first) ++b;
    const std::size_t count = b - a;
    if (count >= min_points_per_voxel) {
      double c[3] = {0.0, 0.0, 0.0};
      const std::size_t attr_base = out.attributes.size();
      out.attributes.resize(attr_base + attribute_dim, 0.0);
      for (std::size_t j = a; j < b; ++j) {
        const Scalar* p = points.ptr(keyed[j].second);
        for (int k = 0; k < 3; ++k) c[k] += p[k];
        for (std::size_t d = 0; d < attribute_dim; ++d)
          out.attributes[attr_base + d] += attributes[keyed[j].second * attribute_dim + d];
      }
      for (int k = 0; k < 3; ++k) out.points.push_back(c[k] / double(count));
      for (std::size_t d = 0; d < attribute_dim; ++d) out.attributes[attr_base + d] /= double(count);
      out.counts.push_back(static_cast<std::uint32_t>(count));
    }
    a = b;
  }
  return out;
}

template VoxelGridResult voxelGrid<float>(const CloudView<float>&, double, const double*, std::size_t, std::uint32_t);
template VoxelGridResult voxelGrid<double>(const CloudView<double>&, double, const double*, std::size_t,
                                           std::uint32_t);

}  // namespace scanalign

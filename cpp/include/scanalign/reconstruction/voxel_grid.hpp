// Voxel-grid downsampling (the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929),
// §3.6): one point per occupied voxel, the centroid of
// the points inside it, with optional per-point attributes (normals, colours) averaged.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "scanalign/common/cloud_view.hpp"

namespace scanalign {

/// The voxel coordinate of v along one axis, floor(v * inv_leaf) with the product in the
/// cloud's own precision and inv_leaf = Scalar(1) / Scalar(leaf), as pcl::VoxelGrid
/// computes it. voxelGrid and the reconstruction's incremental merge both use it, so they
/// put every point into the same voxel.
template <typename Scalar>
inline std::int64_t voxelCoordinate(Scalar v, Scalar inv_leaf) {
  return static_cast<std::int64_t>(std::floor(v * inv_leaf));
}

struct VoxelGridResult {
  std::vector<double> points;           ///< 3 per voxel (m): the centroid
  std::vector<double> attributes;       ///< attribute_dim per voxel: the mean
  std::vector<std::uint32_t> counts;    ///< input points per voxel
  std::size_t size() const { return counts.size(); }
};

/// Voxel grid with cubic voxels of edge `leaf_size` (m), aligned to the cloud's minimum
/// corner exactly as pcl::VoxelGrid (voxel index floor(p / leaf) - floor(min / leaf)),
/// and output in PCL's order (z-major, then y, then x). Non-finite points are skipped.
/// `attributes` (may be null) holds attribute_dim doubles per input point. Voxels with
/// fewer than min_points_per_voxel points are dropped. Throws std::invalid_argument when
/// the leaf is not positive or too small for the cloud's extent (over 2^21 voxels per axis).
template <typename Scalar>
VoxelGridResult voxelGrid(const CloudView<Scalar>& points, double leaf_size, const double* attributes = nullptr,
                          std::size_t attribute_dim = 0, std::uint32_t min_points_per_voxel = 1);

}  // namespace scanalign

// Surface normals by PCA over a radius neighbourhood (the eye-in-hand paper
// (Comput. Electron. Agric. 180 (2021) 105929), §3.5, after Rusu 2009).
#pragma once

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/registration/kdtree.hpp"

namespace scanalign {

struct NormalEstimationSettings {
  /// Neighbourhood radius (m). Eye-in-hand paper §3.5: 5 mm.
  double radius = 0.005;
  /// Normals are flipped to point towards this point (m, in the cloud's frame), as
  /// pcl::flipNormalTowardsViewpoint; the camera centre for a camera-frame cloud.
  Eigen::Vector3d viewpoint = Eigen::Vector3d::Zero();
  /// Fewer neighbours than this (the point itself included) give a NaN normal.
  int min_neighbors = 3;
  /// OpenMP threads; 0 = all cores.
  int num_threads = 0;
  /// Cells per radius of the grid neighbourhood search used by estimateNormals without a
  /// tree (1..16; 0 = chosen from the cloud's density). Only the speed depends on it: the
  /// normals are the same up to rounding.
  int grid_subdivisions = 0;
};

/// Throws std::invalid_argument naming the field: a radius that is not finite and > 0, a
/// non-finite viewpoint, min_neighbors < 3, num_threads < 0, grid_subdivisions outside [0, 16].
void validate(const NormalEstimationSettings& settings);

/// Estimates a unit normal per point: the eigenvector of the smallest eigenvalue of the
/// neighbourhood covariance, oriented towards the viewpoint. `normals` receives 3*N values
/// (row-major); `curvature` (may be null) N values of the surface variation
/// lambda_0 / (lambda_0 + lambda_1 + lambda_2) in [0, 1/3]. Points that are not finite
/// or have too few neighbours get NaN. Throws std::invalid_argument on bad settings, and
/// Interrupted (common/interrupt.hpp; KeyboardInterrupt in Python) when the interrupt hook
/// asks to stop (the outputs are then partly written). Cost: a cell grid sums whole cells
/// inside or outside every query's sphere at once, so a radius beyond the cloud's extent
/// costs O(N) (far outliers included: empty stretches of the grid are closed); only the
/// points in cells the sphere boundary crosses are tested one by one, so the worst case is a
/// radius comparable to the cloud's extent (200k points in a 2 m cube, radius 2 m: ~12 s).
template <typename Scalar>
void estimateNormals(const CloudView<Scalar>& points, const NormalEstimationSettings& settings, Scalar* normals,
                     Scalar* curvature = nullptr);

/// The same over an existing tree built on `points` (e.g. the ICP target's). Visits every
/// neighbour of every point: O(N^2) when the radius spans the cloud (checked for an
/// interrupt between chunks of 16384 points).
template <typename Scalar>
void estimateNormals(const CloudView<Scalar>& points, const LeftBalancedKdTree<Scalar>& tree,
                     const NormalEstimationSettings& settings, Scalar* normals, Scalar* curvature = nullptr);

}  // namespace scanalign

// RANSAC cylinders from two oriented points, and their least-squares refit, beside the CGA
// planes and spheres of ransac.hpp (same loop, result type and statuses).
//
// A cylinder is not a blade of conformal geometric algebra (Kleppe, PhD thesis, NTNU 2018,
// §4.3 lists points, spheres, planes, circles and lines), so its minimal sample is the classic
// one: two points with surface normals (Schnabel, Wahl and Klein, "Efficient RANSAC for
// point-cloud shape detection", Computer Graphics Forum 26(2), 2007, §4.3; PCL's
// SampleConsensusModelCylinder). On a cylinder every normal line meets the axis at right
// angles, so the axis direction is n1 x n2, and the axis passes through the closest points of
// the two normal lines.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/segmentation/ransac.hpp"

namespace scanalign {

/// The cylinder |(p - point) x axis| = radius; PCL's coefficient order is (point, axis, radius).
struct CylinderModel {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  ///< metres: a point of the axis
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  ///< unit axis direction (its sign is arbitrary)
  double radius = 0.0;                              ///< metres
  /// Distance of p from the axis, metres.
  double axisDistance(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d d = p - point;
    return (d - d.dot(axis) * axis).norm();
  }
  /// Distance of p from the surface, | |(p - point) x axis| - radius |, metres.
  double surfaceDistance(const Eigen::Vector3d& p) const { return std::abs(axisDistance(p) - radius); }
};

struct CylinderSettings {
  /// threshold: inlier distance from the surface (metres); seed, iterations, refit as for planes.
  RansacSettings ransac;
  double min_radius = 0.0;                                       ///< metres: samples outside the limits are degenerate
  double max_radius = std::numeric_limits<double>::infinity();  ///< metres
  /// radians: an inlier's normal must lie within this angle of the direction from the axis
  /// to the point (PCL weighs the same angle into its error with setNormalDistanceWeight).
  double max_normal_angle = 0.35;
  /// metres: radius of the PCA normals (features/normals.hpp) when the caller gives none.
  double normal_radius = 0.01;
};

/// Throws std::invalid_argument naming the field: the RansacSettings, not 0 <= min_radius <
/// max_radius, max_normal_angle outside (0, pi/2], normal_radius not finite and > 0.
void validate(const CylinderSettings& settings);

/// The cylinder through two oriented points (normals need not be unit or oriented): axis
/// n1 x n2 through the midpoint of the closest points of the normal lines, radius the mean
/// distance of the two points from it. False when the normals are within about 1 degree of
/// parallel (no unique axis) or the two points' distances from the axis differ by more than
/// `tolerance` (metres: no cylinder fits both).
bool cylinderFromOrientedPoints(const Eigen::Vector3d& p1, const Eigen::Vector3d& n1, const Eigen::Vector3d& p2,
                                const Eigen::Vector3d& n2, double tolerance, CylinderModel& out);

/// Geometric least squares: minimise sum_i (|(p_i - point) x axis| - radius)^2 over the 5
/// degrees of freedom (axis 2, point 2, radius), Levenberg-Marquardt from `model` (updated in
/// place, with `point` moved to the foot of the indexed points' centroid on the axis). False
/// (model unchanged) for fewer than 5 points, a non-finite solution or no decrease of the cost.
template <typename Scalar>
bool fitCylinderLeastSquares(const CloudView<Scalar>& points, const std::vector<std::uint32_t>& indices,
                             CylinderModel& model, int max_iterations = 50);

/// RANSAC cylinder over the points with finite coordinates and normals (the others are never
/// sampled nor inliers). Error: the surface distance, and no inlier whose normal is more than
/// max_normal_angle from the radial direction. Refit (fitCylinderLeastSquares) kept when its
/// radius is within the limits; inliers re-selected against the returned model. Fewer than 2
/// usable points: kTooFewPoints; only degenerate samples: kDegenerate. `normals`: 3 per point.
template <typename Scalar>
RansacResult<CylinderModel> ransacCylinder(const CloudView<Scalar>& points, const CloudView<Scalar>& normals,
                                           const CylinderSettings& settings);

/// The same with PCA normals of radius settings.normal_radius (features/normals.hpp).
template <typename Scalar>
RansacResult<CylinderModel> ransacCylinder(const CloudView<Scalar>& points, const CylinderSettings& settings);

}  // namespace scanalign

// Table segmentation (Kleppe, PhD thesis, NTNU 2018, paper 3 §3.1.2-3.1.3, thesis §5.2):
// crop, the table plane by CGA RANSAC, removal of the table and everything below it,
// Euclidean clusters of what is left, cluster size limits.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/segmentation/ransac.hpp"

namespace scanalign {

struct TableSegmentationSettings {
  /// (1) pass-through crop: keep points with crop_min <= p <= crop_max (metres) if crop.
  bool crop = false;
  Eigen::Vector3d crop_min = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());
  Eigen::Vector3d crop_max = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  /// (2) the table plane: RANSAC settings (threshold = Delta, metres).
  RansacSettings plane;
  /// (3) orientation of the table normal: towards `up` when it is non-zero, else towards
  /// the viewpoint. Plane inliers and every point with signed distance < threshold are removed.
  /// `viewpoint`: the sensor's centre in the cloud's frame (metres); unset, the origin, which
  /// is the camera centre of a cloud in its camera frame. A sensor sees the table from above,
  /// so an `up` that leaves the viewpoint below the table (by more than plane.threshold; the
  /// origin taken for an unset viewpoint, by more than 5 cm, since a base frame's origin often
  /// lies on the table top) contradicts it: the result's `warning` says so (the objects would
  /// be removed as "below the table").
  std::optional<Eigen::Vector3d> viewpoint;
  Eigen::Vector3d up = Eigen::Vector3d::Zero();  ///< zero: orient towards the viewpoint
  /// (4) Euclidean clustering: points closer than cluster_tolerance (metres) are linked.
  double cluster_tolerance = 0.02;
  /// (5) clusters with fewer than min / more than max points are dropped.
  std::size_t min_cluster_size = 100;
  std::size_t max_cluster_size = std::numeric_limits<std::size_t>::max();
};

/// Throws std::invalid_argument naming the field: the plane's RansacSettings, a crop box with
/// NaN bounds (infinite ones are open sides), a non-finite viewpoint or up, a cluster_tolerance
/// that is not finite and > 0, or not 1 <= min_cluster_size <= max_cluster_size.
void validate(const TableSegmentationSettings& settings);

/// The table settings of a pose search in a table scene (findObjects, findParts): a 5 mm
/// plane threshold (the thesis's Delta for depth-camera scans of a table), 10 mm between
/// points of one object, at least 200 points per object (smaller clusters are noise or
/// fragments too small for a descriptor match).
inline TableSegmentationSettings objectTableSettings() {
  TableSegmentationSettings s;
  s.plane.threshold = 0.005;
  s.cluster_tolerance = 0.01;
  s.min_cluster_size = 200;
  return s;
}

struct TableSegmentationResult {
  RansacStatus status = RansacStatus::kTooFewPoints;  ///< of the plane RANSAC
  RansacResult<PlaneModel> plane;  ///< normal oriented up / towards the viewpoint; inliers index the input
  /// One cluster per object: ascending input indices; clusters by decreasing size.
  std::vector<std::vector<std::uint32_t>> objects;
  std::size_t cropped_points = 0;  ///< finite points inside the crop box
  std::size_t above_points = 0;    ///< points left after step (3)
  /// Empty, or why the result is suspect: an `up` that puts the viewpoint below the table.
  std::string warning;
  bool success() const { return status == RansacStatus::kSuccess; }
};

template <typename Scalar>
TableSegmentationResult segmentTable(const CloudView<Scalar>& points, const TableSegmentationSettings& settings);

}  // namespace scanalign

// A camera pose from where it is and what it looks at: the virtual cameras of a CAD
// model's views (Kleppe, PhD thesis, NTNU 2018, §7.3) and of the synthetic scan paths.
#pragma once

#include <Eigen/Core>

namespace scanalign {

/// Camera pose looking from `eye` at `target` (both in one frame W, m), OpenCV camera axes:
/// the camera's z axis points at the target, its y axis down (against `up`). Returns
/// T_W_camera (camera -> W).
/// @throws std::invalid_argument for non-finite input, eye == target, or `up` parallel to the
///         view direction.
Eigen::Matrix4d lookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target,
                       const Eigen::Vector3d& up = Eigen::Vector3d::UnitZ());

}  // namespace scanalign

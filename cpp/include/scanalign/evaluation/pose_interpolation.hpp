// Unit quaternions and pose interpolation for camera trajectories (the TUM RGB-D format
// stores orientations as quaternions (qx, qy, qz, qw), Hamilton convention, scalar last).
//
// Eigen does the work: Quaterniond from a rotation matrix (Shepperd's largest-pivot
// method, accurate over the whole rotation group) and Quaterniond::slerp (shortest arc).
#pragma once

#include <Eigen/Core>

namespace scanalign {

/// Unit quaternion (qx, qy, qz, qw) with qw >= 0 of a rotation matrix.
Eigen::Vector4d quaternionFromRotation(const Eigen::Matrix3d& R);

/// Rotation matrix of the quaternion (qx, qy, qz, qw), normalised first.
/// Throws std::invalid_argument for a zero or non-finite quaternion.
Eigen::Matrix3d rotationFromQuaternion(const Eigen::Vector4d& xyzw);

/// The pose a fraction `a` in [0, 1] of the way from T0 to T1 (4x4 rigid transforms, metres):
/// translation linear, rotation spherical-linear along the shorter arc. a = 0 gives T0's
/// rotation, a = 1 T1's (up to rounding).
Eigen::Matrix4d interpolatePose(const Eigen::Matrix4d& T0, const Eigen::Matrix4d& T1, double a);

}  // namespace scanalign

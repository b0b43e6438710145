// Quaternions and pose interpolation; see pose_interpolation.hpp.
#include "scanalign/evaluation/pose_interpolation.hpp"

#include <cmath>
#include <stdexcept>

#include <Eigen/Geometry>

namespace scanalign {

Eigen::Vector4d quaternionFromRotation(const Eigen::Matrix3d& R) {
  Eigen::Quaterniond q(R);
  q.normalize();  // a rounded rotation matrix gives a slightly non-unit quaternion
  // q and -q are the same rotation; qw >= 0 makes the stored value unique (but for qw = 0).
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  return q.coeffs();  // Eigen stores (x, y, z, w)
}

Eigen::Matrix3d rotationFromQuaternion(const Eigen::Vector4d& xyzw) {
  const double n = xyzw.norm();
  if (!xyzw.allFinite() || !(n > 1e-12)) throw std::invalid_argument("quaternions must be finite and non-zero");
  return Eigen::Quaterniond(xyzw / n).toRotationMatrix();
}

Eigen::Matrix4d interpolatePose(const Eigen::Matrix4d& T0, const Eigen::Matrix4d& T1, double a) {
  const Eigen::Quaterniond q0(quaternionFromRotation(T0.topLeftCorner<3, 3>()));
  const Eigen::Quaterniond q1(quaternionFromRotation(T1.topLeftCorner<3, 3>()));
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = q0.slerp(a, q1).normalized().toRotationMatrix();
  T.topRightCorner<3, 1>() = (1.0 - a) * T0.topRightCorner<3, 1>() + a * T1.topRightCorner<3, 1>();
  return T;
}

}  // namespace scanalign

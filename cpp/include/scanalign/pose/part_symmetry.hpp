// The rotational symmetry of a part: a part that looks the same after a rotation about an
// axis has several equally correct poses, and each grasp defined on it has equivalent grasps.
// Pose scoring (ambiguity between candidates) and grasp planning (equivalent grasps) both
// use it, so it lives here once.
//
// Frames and units: the axis and the point are in the part's model (CAD) frame, metres;
// angles in radians.
#pragma once

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace scanalign {

struct PartSymmetry {
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();   ///< symmetry axis direction, model frame (normalised on use)
  Eigen::Vector3d point = Eigen::Vector3d::Zero();   ///< a point on the axis, model frame, m
  /// 1: no symmetry; n >= 2: the part looks the same after a rotation by 2π/n about the
  /// axis; 0: after any rotation (a body of revolution).
  int order = 1;

  /// Throws std::invalid_argument naming the field: a non-finite or zero axis, a non-finite
  /// point, an order below 0 or above 360.
  void validate() const {
    if (!axis.allFinite() || !(axis.norm() > 1e-12))
      throw std::invalid_argument("symmetry axis must be a finite non-zero 3-vector");
    if (!point.allFinite()) throw std::invalid_argument("symmetry point must be finite (m)");
    if (order < 0 || order > 360)
      throw std::invalid_argument("symmetry order must be 0 (continuous), 1 (none) or 2..360, got " +
                                  std::to_string(order));
  }

  /// The rotation by `angle` rad about the axis, as a model -> model transform.
  Eigen::Isometry3d rotation(double angle) const {
    const Eigen::Vector3d u = axis.normalized();
    Eigen::Isometry3d S = Eigen::Isometry3d::Identity();
    S.linear() = Eigen::AngleAxisd(angle, u).toRotationMatrix();
    S.translation() = point - S.linear() * point;
    return S;
  }

  /// The transforms S_k (model -> model) that map the part onto itself: k * 2π/order for
  /// k = 0..order-1; for a continuous symmetry `continuous_steps` evenly spaced angles.
  /// S_0 is the identity. If T_scene_model is a pose of the part, so is T_scene_model * S_k.
  std::vector<Eigen::Isometry3d> transforms(int continuous_steps = 72) const {
    validate();
    const int n = order == 0 ? std::max(1, continuous_steps) : order;
    std::vector<Eigen::Isometry3d> out;
    out.reserve(static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k) out.push_back(rotation(2 * M_PI * k / n));
    return out;
  }
};

/// Pose error between two poses of a symmetric part, minimised over its symmetry:
/// (rotation angle rad, translation m). Translation is measured at the symmetry point, which
/// every symmetry rotation keeps fixed. For a continuous symmetry only the tilt of the axis
/// counts (the twist about it is free), solved in closed form.
inline std::pair<double, double> symmetricPoseError(const Eigen::Isometry3d& T_a, const Eigen::Isometry3d& T_b,
                                                    const PartSymmetry& sym) {
  const Eigen::Vector3d u = sym.axis.normalized();
  const double dt = (T_a * sym.point - T_b * sym.point).norm();
  const Eigen::Matrix3d R = T_a.linear().transpose() * T_b.linear();  // model-frame relative rotation
  if (sym.order == 0) {
    const double c = std::clamp(u.dot(R * u), -1.0, 1.0);
    return {std::acos(c), dt};
  }
  double best = M_PI;
  const int n = std::max(1, sym.order);
  for (int k = 0; k < n; ++k) {
    const Eigen::Matrix3d D = R * Eigen::AngleAxisd(2 * M_PI * k / n, u).toRotationMatrix();
    best = std::min(best, std::acos(std::clamp((D.trace() - 1) / 2, -1.0, 1.0)));
  }
  return {best, dt};
}

}  // namespace scanalign

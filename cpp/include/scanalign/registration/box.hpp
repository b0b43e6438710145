// Axis-aligned box in the source camera frame for correspondence rejection (the
// eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929), §3.4).
#pragma once

#include <Eigen/Core>

#include "scanalign/registration/correspondence_terms.hpp"

namespace scanalign {

/// Box (x_min, x_max, y_min, y_max, z_min, z_max) in metres, in the source camera frame
/// (x right, y down, z towards the object). A correspondence is kept only when its source
/// point lies inside (bounds inclusive). Because the box is attached to the source frame,
/// it moves with the transform ICP applies to the source, as in the eye-in-hand paper.
struct Box {
  Eigen::Vector3d min = Eigen::Vector3d::Constant(-1e30);
  Eigen::Vector3d max = Eigen::Vector3d::Constant(1e30);

  Box() = default;
  Box(double x_min, double x_max, double y_min, double y_max, double z_min, double z_max)
      : min(x_min, y_min, z_min), max(x_max, y_max, z_max) {}

  template <typename Scalar>
  bool contains(const Scalar* p) const {
    return detail::insideBox(min.data(), max.data(), p);
  }
  bool valid() const { return (min.array() <= max.array()).all() && min.allFinite() && max.allFinite(); }

  /// Eye-in-hand paper §3.4 preset for the free-hand scans: +-0.20 m laterally, 0.1 mm to 10 m deep.
  static Box freeHandPreset() { return Box(-0.20, 0.20, -0.20, 0.20, 0.0001, 10.0); }
  /// Eye-in-hand paper §3.4 preset for the banana scan (the printed y bounds are partly garbled; +-0.1 m).
  static Box bananaPreset() { return Box(-0.05, 0.05, -0.10, 0.10, 0.0001, 10.0); }
};

}  // namespace scanalign

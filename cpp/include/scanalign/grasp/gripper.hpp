// The tool on the flange: where its tool centre point is (T_flange_tcp) and a simple collision
// body, a capsule or a box, that the grasp planner keeps above the table.
//
// Frames and units: metres; every geometric field is in the flange frame (DH frame 6: origin
// at the flange centre, z along the tool axis, away from the arm).
#pragma once

#include <cstdint>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace scanalign {

enum class GripperShape : std::uint8_t {
  Capsule = 0,  ///< the points within `radius` of the segment capsule_a - capsule_b
  Box = 1,      ///< an axis-aligned box of the flange frame: box_centre ± box_half_extents
};
const char* toString(GripperShape s);

struct Gripper {
  Eigen::Isometry3d T_flange_tcp = Eigen::Isometry3d::Identity();  ///< TCP -> flange, m
  GripperShape shape = GripperShape::Box;                           ///< which of the bodies below is used
  Eigen::Vector3d capsule_a = Eigen::Vector3d::Zero();               ///< capsule axis end, flange frame, m
  Eigen::Vector3d capsule_b = Eigen::Vector3d::Zero();               ///< capsule axis end, flange frame, m
  double capsule_radius = 0;                                         ///< m (>= 0)
  Eigen::Vector3d box_centre = Eigen::Vector3d::Zero();              ///< flange frame, m
  Eigen::Vector3d box_half_extents = Eigen::Vector3d::Zero();        ///< along flange x, y, z, m (>= 0)
  /// Radius of the flange disc (in the flange xy plane, centred on its origin), m (>= 0);
  /// the disc is kept above the table too (a gripper body may not cover the flange's rim).
  double flange_radius = 0.0315;

  /// Throws std::invalid_argument naming the field: non-rigid T_flange_tcp, non-finite
  /// geometry, negative radii or half extents.
  void validate() const;

  /// Signed height above the plane n·p + d = 0 (n unit, base frame) of the lowest point of the
  /// collision body when the flange is at T_base_flange, m (negative: below the plane).
  double bodyHeight(const Eigen::Isometry3d& T_base_flange, const Eigen::Vector3d& n, double d) const;
  /// The same for the flange disc.
  double flangeHeight(const Eigen::Isometry3d& T_base_flange, const Eigen::Vector3d& n, double d) const;

  /// A parallel-jaw gripper like the Robotiq 2F-85 on its coupling: TCP between the finger
  /// pads 0.15 m along the flange z axis; body a box 0.08 x 0.14 x 0.15 m (flange x, y, z)
  /// from the flange face to the TCP; flange radius 0.0315 m (ISO 9409-1-50-4-M6, as UR5).
  static Gripper parallelJaw();
};

}  // namespace scanalign

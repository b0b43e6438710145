// A Robot from a serial chain of joint axes, as a URDF describes an arm (Robot::fromJointChain).
//
// A URDF places each joint by an arbitrary <origin> (its frame in the parent link's frame)
// and turns it about an arbitrary <axis> (in the joint's own frame); the chain's forward
// kinematics is the product T_base_tip(q) = O_1 Rot(u_1, q_1) O_2 Rot(u_2, q_2) ... O_6
// Rot(u_6, q_6) T_joint6_tip (JointChain::forward). The analytic inverse kinematics (ik.hpp)
// needs the arm as a standard DH table (robot.hpp, P1 (1)) in one of two layouts
// (ArmGeometry). fromJointChain places the six joint axes in the base frame at q = 0 and
// derives the DH frames from these lines (Denavit and Hartenberg 1955, "A kinematic notation
// for lower-pair mechanisms based on matrices", J. Appl. Mech. 22: frame i on the common
// normal of axes i and i+1, where it meets axis i+1, x_i along it), plus T_base_dh0 (DH frame
// 0 in the base) and T_flange_tool (the tip in the flange frame), so that Robot::forward(q)
// equals JointChain::forward(joint_signs * q), limits included.
//
// Free choices and how they are made:
//  - each DH x axis has a free sign (flipping it flips alpha_i and a_i and moves theta
//    offsets by pi): of the 32 choices for frames 1..5, the one that makes the table one of
//    the analytic layouts is taken, with the smallest sum of |theta offsets|;
//  - parallel axes (angle below `tolerance`) have no unique common normal: the one through
//    the previous origin is taken (d_i = 0, as both layouts need), its sign following
//    x_{i-1}; collinear axes keep the previous x;
//  - frame 0 lies on axis 1 at the foot of the base origin with x_0 = x_1 (theta_offset_1 =
//    0); the flange, frame 6, lies on axis 6 at the foot of the tip's origin with x_6 = x_5;
//  - DH values within `tolerance` of what the layouts test exactly (alpha a multiple of pi/2,
//    a and d zero) are set to them when that makes the table analytic: URDFs write pi/2 with
//    10-12 digits (1.57079632679 is 4.9e-12 short of it), and an axis turned by such an angle
//    misses the layout's twist by as much, which the layout test (1e-12) refuses; forward
//    kinematics then departs from the chain by about tolerance x reach.
//  - the DH z axes follow the chain's axes, so q maps 1:1 onto the chain's joints unless
//    joint_signs reverses some (limits mirrored): a chain whose axes point against the layouts
//    (KUKA's own descriptions turn A1, A4, A6 about -z / -x) is analytic only so.
//
// Metres and radians throughout.
#pragma once

#include <array>
#include <optional>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "scanalign/kinematics/robot.hpp"

namespace scanalign {

/// A serial chain of 6 revolute joints, each placed by a fixed transform and turning about an
/// axis of its own frame (a URDF's revolute / continuous joints, the fixed joints between
/// them folded into the next origin).
struct JointChain {
  /// origins[i]: the frame of joint i+1 in the frame of joint i (its child link) at q = 0;
  /// origins[0] in the base frame. m.
  std::array<Eigen::Isometry3d, 6> origins{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity(),
                                           Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity(),
                                           Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()};
  /// axes[i]: the rotation axis of joint i+1 in its own frame, any length > 0 (normalised on use).
  std::array<Eigen::Vector3d, 6> axes{Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ(),
                                      Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ()};
  /// [q_min, q_max] of each joint, rad; -inf / +inf for an unlimited (continuous) joint.
  std::array<Eigen::Vector2d, 6> limits{Eigen::Vector2d(-M_PI, M_PI), Eigen::Vector2d(-M_PI, M_PI),
                                        Eigen::Vector2d(-M_PI, M_PI), Eigen::Vector2d(-M_PI, M_PI),
                                        Eigen::Vector2d(-M_PI, M_PI), Eigen::Vector2d(-M_PI, M_PI)};
  /// The tip (tool) frame in the frame of joint 6, m.
  Eigen::Isometry3d T_joint6_tip = Eigen::Isometry3d::Identity();

  /// Throws std::invalid_argument naming the field: a non-rigid origin or tip, a non-finite or
  /// zero axis, NaN limits or q_min > q_max.
  void validate() const;
  /// T_base_tip(q) by the chain itself: origins[0] Rot(axes[0], q_1) ... origins[5]
  /// Rot(axes[5], q_6) T_joint6_tip (Rodrigues' rotation about each unit axis).
  Eigen::Isometry3d forward(const Vector6d& q) const;
};

/// Settings of Robot::fromJointChain.
struct JointChainSettings {
  std::string name = "custom";  ///< the Robot's name
  /// The Robot's joint i turns q_i = joint_signs[i] * q_chain_i (each +1 or -1; limits
  /// mirrored). Unset: all +1, and the error for a chain no analytic layout fits names the
  /// signs (fewest reversed joints) that would make it one.
  std::optional<Vector6d> joint_signs;
  /// Return the Robot even when no analytic layout fits (geometry Unsupported: forward
  /// kinematics only) instead of throwing.
  bool fk_only = false;
  /// rad (and m): axes within this angle count as parallel, DH values within it of 0 or a
  /// multiple of pi/2 are set to them; in [0, 1e-3).
  double tolerance = 1e-9;
  /// How error messages name the chain (e.g. "arm.urdf: the chain base -> tool0 (joints a1,
  /// ..., a6)").
  std::string what = "the joint chain";

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

}  // namespace scanalign

// Grasp planning with the analytic inverse kinematics: given a part's pose in the cell, its
// grasps, the gripper and the robot, the joint targets to pick it, and for every rejected
// candidate the reason (issue 17 §3 step 3).
//
// Frames (metres, radians; T_a_b maps b into a):
//
//   base --T_base_model--> model --T_model_grasp--> grasp (= TCP at the grasp)
//   base --Robot::T_base_dh0--> DH 0 --FK(q)--> flange --Gripper::T_flange_tcp--> tcp
//
//   T_base_tcp    = T_base_model * T_model_grasp
//   T_base_flange = T_base_tcp * inv(T_flange_tcp)
//
// The robot's own T_flange_tool is not used: the gripper's T_flange_tcp is the tool.
//
// Candidates: every grasp x every symmetry copy (PartSymmetry::transforms) x every IK
// configuration (ik.hpp, configIndex 0..7), solved at the pre-grasp. Each candidate is checked
// in this order, and the first failure is its reason:
//   1. the IK of the pre-grasp flange pose (Unreachable, OutsideLimits); its angles are then
//      moved by multiples of 2π to those nearest q_current within the limits;
//   2. gripper body, flange disc and arm joint points above the table at the pre-grasp
//      (BelowTable), singularity margins at the pre-grasp (NearSingularity);
//   3. the straight TCP line from the pre-grasp to the grasp in n = max(1, ceil(distance /
//      approach_step)) equal steps, followed with ikClosest from sample to sample: a sample
//      without an Ok solution (Unreachable / OutsideLimits), or one in another configuration
//      or with a joint step above max_joint_step (ApproachBranchChange);
//   4. forward kinematics of every sample's joints equals its flange pose to 1e-9 (else
//      Unreachable), then the table and the singularity margins at every approach sample
//      (BelowTable, NearSingularity).
// A path through a singularity is reported as ApproachBranchChange when the IK labels change
// there, before its samples' margins are looked at: it cannot be followed at all.
// The cost of an Ok candidate is the weighted joint motion sum_i w_i |Δq_i| (rad) from
// q_current to q_pregrasp plus along the approach samples; the plan chooses the least.
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "scanalign/grasp/grasp.hpp"
#include "scanalign/grasp/gripper.hpp"
#include "scanalign/kinematics/ik.hpp"
#include "scanalign/kinematics/robot.hpp"
#include "scanalign/pose/part_symmetry.hpp"

namespace scanalign {

/// Why a candidate was rejected (Ok: it was not).
enum class GraspReason : std::uint8_t {
  Ok = 0,
  Unreachable = 1,           ///< no IK solution in this configuration (pre-grasp, or a sample of the approach)
  OutsideLimits = 2,         ///< reachable, but some joint has no 2π multiple within its limits
  NearSingularity = 3,       ///< a singularity margin below its setting (the detail names which and its value)
  BelowTable = 4,            ///< gripper body, flange or an arm joint point closer to the table than the clearance
  ApproachBranchChange = 5,  ///< the straight approach leaves the IK configuration or jumps in joint space
};
const char* toString(GraspReason r);

struct GraspPlannerSettings {
  double table_clearance = 0.005;  ///< m, least height of the gripper body and flange above the table plane
  /// Also keep the arm's joint points (DH frame origins 2..5: elbow and wrist) above the table
  /// plane + clearance. Off for an arm mounted below the table top beside it (the plane is
  /// unbounded).
  bool check_arm_points = true;
  /// Wrist: least |θ5| distance from 0 or π, i.e. asin|sin θ5| (θ5 = q5 + offset5, the DH wrist
  /// angle; the wrist is singular when the tool axis lines up with the forearm axis z3 (KUKA)
  /// or with the parallel axes z1 (UR)), rad.
  double min_wrist_angle = 0.05;
  /// Shoulder: least distance of the wrist centre from the first joint axis, m (KUKA: the
  /// wrist centre P_w; UR: P_c, the projection of the wrist point P5 onto the arm plane, which
  /// is on the first axis when P5 lies d4 from it).
  double min_shoulder_distance = 0.02;
  /// Elbow: least angle between the upper arm (P1 -> P2) and the forearm (P2 -> wrist point:
  /// KUKA P_w, UR P3) away from straight (0) or folded (π), rad.
  double min_elbow_angle = 0.05;
  double approach_step = 0.005;    ///< m, spacing of the samples of the straight approach (> 0)
  double max_joint_step = 0.1;     ///< rad, largest joint change between two approach samples that counts as continuous (> 0)
  Vector6d joint_weights = Vector6d::Ones();  ///< weights w_i of the cost sum_i w_i |Δq_i|, each in [0, 1e6]
  bool respect_limits = true;      ///< reject solutions outside the joint limits (false: ignore the limits)
  int continuous_symmetry_steps = 36;  ///< symmetry copies of a part with a continuous symmetry (order 0), 1..3600

  /// Throws std::invalid_argument naming the field for a negative, non-finite or zero value
  /// where it must be positive.
  void validate() const;
};

struct GraspCandidate {
  int grasp_index = -1;      ///< into the grasp list
  int symmetry_index = 0;    ///< symmetry copy k (S_k of PartSymmetry::transforms)
  int config_index = 0;      ///< IK configuration, configIndex() (ik.hpp)
  Eigen::Isometry3d T_base_tcp_pregrasp = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_base_tcp_grasp = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_base_flange_pregrasp = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_base_flange_grasp = Eigen::Isometry3d::Identity();
  /// Joint targets, rad; NaN where not reached (q_grasp: unless the approach was followed).
  Vector6d q_pregrasp = Vector6d::Constant(std::numeric_limits<double>::quiet_NaN());
  Vector6d q_grasp = Vector6d::Constant(std::numeric_limits<double>::quiet_NaN());
  GraspReason reason = GraspReason::Unreachable;
  std::string detail;  ///< human-readable reason, with the measured value where there is one
  double cost = std::numeric_limits<double>::infinity();  ///< rad (weighted), finite for Ok only
};

struct GraspPlanResult {
  bool found = false;
  std::string message;  ///< the choice, or why nothing was found (the reasons summarised)
  int chosen = -1;      ///< index into candidates, -1 when none
  std::vector<GraspCandidate> candidates;
  /// Joints at every approach sample of the chosen candidate, pre-grasp first, grasp last, rad.
  std::vector<Vector6d> approach_q;
};

/// Plans a pick (see the file comment). table_plane = (n, d): n·p + d = 0 in the base frame
/// with n the unit normal pointing up (away from the table, towards the robot's free space).
/// q_current: the robot's joints now, rad.
/// Throws std::invalid_argument naming the argument or field: non-rigid T_base_model, an
/// empty grasp list or a bad grasp (Grasp::validate), a bad symmetry, gripper or setting, a
/// non-finite or non-unit table normal, non-finite q_current, a robot the analytic IK does not
/// cover, an approach of more than 100000 samples, or more than 10000 grasps x symmetry copies.
GraspPlanResult planGrasp(const Robot& robot, const Eigen::Isometry3d& T_base_model,
                          const std::vector<Grasp>& grasps, const PartSymmetry& symmetry, const Gripper& gripper,
                          const Eigen::Vector4d& table_plane, const Vector6d& q_current,
                          const GraspPlannerSettings& settings = {});

}  // namespace scanalign

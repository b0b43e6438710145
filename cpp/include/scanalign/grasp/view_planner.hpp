// Where to put a hand camera to look at a part: the view step of the two-step pose of Kleppe
// et al., "Automated assembly using 3D and 2D cameras", Robotics 6 (2017) 14 (the thesis's
// Paper 3), §3.3: the robot carrying the 2D camera moves it above the rough 3D estimate, the
// camera looking straight down.
//
// The view is planned as a grasp whose tool is the camera: the camera poses above the part at
// `yaw_steps` turns about the vertical (the image's in-plane rotation is free for SIFT) are
// the candidates, and every analytic IK configuration of each is judged by the grasp planner
// (grasp_planner.hpp: reachability, joint limits, table clearance of the camera body, flange
// and arm, singularity margins), with no approach motion. The plan with the least joint
// motion from q_current wins.
//
// Frames (T_a_b maps b into a; metres, radians): base (z up), part, camera (x right, y down,
// z along the optical axis), flange; the camera mount's T_flange_tcp is the hand-eye
// calibration T_flange_camera.
#pragma once

#include <limits>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "scanalign/grasp/grasp_planner.hpp"
#include "scanalign/grasp/gripper.hpp"
#include "scanalign/kinematics/robot.hpp"

namespace scanalign {

struct ViewPlannerSettings {
  /// m, from the part's top face up to the camera centre: 18 cm puts a 6 cm label across about
  /// 300 of a 1280-pixel webcam's columns and keeps 2 cm of rough error well inside the view.
  double height = 0.18;
  int yaw_steps = 4;      ///< camera turns about the vertical tried, 2π / yaw_steps apart (1..360)
  GraspPlannerSettings planner;  ///< how each IK configuration is judged (approach_step unused)

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

struct ViewPlan {
  bool found = false;
  std::string message;  ///< the choice, or why no view was reachable
  Eigen::Isometry3d T_base_camera = Eigen::Isometry3d::Identity();  ///< the chosen camera pose
  Vector6d q = Vector6d::Constant(std::numeric_limits<double>::quiet_NaN());  ///< its joints, rad
  GraspPlanResult plan;  ///< every candidate with its reason (grasp_index: the yaw step)
};

/// The camera pose looking straight down at the part from `height` above its top face
/// (T_base_part's origin raised by top_height along base z), turned by `yaw` about the
/// vertical (camera x along base x at yaw 0, so the image's u runs along base x).
Eigen::Isometry3d cameraAbove(const Eigen::Isometry3d& T_base_part, double top_height, double height, double yaw);

/// Plans the view (see the file comment). camera_mount.T_flange_tcp = T_flange_camera.
/// table_plane = (n, d), n·p + d = 0, n the unit normal pointing up. Throws
/// std::invalid_argument as planGrasp, and for bad settings or a non-finite top_height.
ViewPlan planCameraView(const Robot& robot, const Eigen::Isometry3d& T_base_part, double top_height,
                        const Gripper& camera_mount, const Eigen::Vector4d& table_plane, const Vector6d& q_current,
                        const ViewPlannerSettings& settings = {});

}  // namespace scanalign

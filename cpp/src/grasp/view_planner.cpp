// The hand camera's view above a part, planned as a grasp with the camera as its tool
// (grasp/view_planner.hpp; Kleppe et al., Robotics 6 (2017) 14, §3.3).
#include "scanalign/grasp/view_planner.hpp"

#include <cmath>
#include <stdexcept>
#include <vector>

#include "scanalign/common/rigid.hpp"
#include "scanalign/grasp/grasp.hpp"
#include "scanalign/pose/part_symmetry.hpp"

namespace scanalign {

void ViewPlannerSettings::validate() const {
  if (!(height > 0.0) || !std::isfinite(height))
    throw std::invalid_argument("ViewPlannerSettings.height must be a finite positive distance (m)");
  if (yaw_steps < 1 || yaw_steps > 360) throw std::invalid_argument("ViewPlannerSettings.yaw_steps must be in 1..360");
  planner.validate();
}

Eigen::Isometry3d cameraAbove(const Eigen::Isometry3d& T_base_part, double top_height, double height, double yaw) {
  const Eigen::Vector3d top = T_base_part * Eigen::Vector3d(0.0, 0.0, top_height);
  // Looking down: camera z = -base z; camera x = (cos yaw, sin yaw, 0); y = z x x.
  const Eigen::Vector3d x(std::cos(yaw), std::sin(yaw), 0.0), z(0.0, 0.0, -1.0);
  Eigen::Matrix3d R;
  R.col(0) = x;
  R.col(1) = z.cross(x);
  R.col(2) = z;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = top + Eigen::Vector3d(0.0, 0.0, height);
  return T;
}

ViewPlan planCameraView(const Robot& robot, const Eigen::Isometry3d& T_base_part, double top_height,
                        const Gripper& camera_mount, const Eigen::Vector4d& table_plane, const Vector6d& q_current,
                        const ViewPlannerSettings& settings) {
  settings.validate();
  requireRigid(T_base_part.matrix(), "T_base_part");
  if (!std::isfinite(top_height)) throw std::invalid_argument("top_height must be finite (m)");
  std::vector<Grasp> views;
  constexpr double kTwoPi = 6.283185307179586;
  for (int k = 0; k < settings.yaw_steps; ++k) {
    Grasp g;
    g.name = "view, yaw " + std::to_string(k * 360 / settings.yaw_steps) + " deg";
    g.T_model_grasp = T_base_part.inverse() * cameraAbove(T_base_part, top_height, settings.height,
                                                          kTwoPi * k / settings.yaw_steps);
    g.pre_grasp_distance = 0.0;  // a view has no approach
    views.push_back(g);
  }
  ViewPlan out;
  out.plan = planGrasp(robot, T_base_part, views, PartSymmetry{}, camera_mount, table_plane, q_current,
                       settings.planner);
  out.found = out.plan.found;
  out.message = out.plan.message;
  if (out.found) {
    const GraspCandidate& c = out.plan.candidates[static_cast<std::size_t>(out.plan.chosen)];
    out.T_base_camera = c.T_base_tcp_grasp;
    out.q = c.q_pregrasp;
  }
  return out;
}

}  // namespace scanalign

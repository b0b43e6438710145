// A grasp defined on a CAD part: the tool centre point (TCP) pose at the grasp, in the part's
// model frame, and the straight approach the TCP takes to reach it.
//
// Frames and units (metres, radians; T_a_b maps b-coordinates into frame a):
//   model  the part's CAD frame;
//   grasp  the TCP frame at the grasp, T_model_grasp;
//   pre-grasp  the grasp frame moved back by pre_grasp_distance against the approach
//          direction: T_model_pregrasp = T_model_grasp * Trans(-pre_grasp_distance * approach).
// A part with a rotational symmetry S_k (pose/part_symmetry.hpp) has the equivalent grasps
// S_k * T_model_grasp: the part looks the same after S_k, so the hand can take it either way.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "scanalign/pose/part_symmetry.hpp"

namespace scanalign {

struct Grasp {
  std::string name;                                                 ///< for messages and files
  Eigen::Isometry3d T_model_grasp = Eigen::Isometry3d::Identity();  ///< TCP pose at the grasp, model frame, m
  /// Unit direction, in the grasp (TCP) frame, in which the TCP moves to reach the grasp;
  /// default +z, the tool axis (a gripper closing in along its own axis).
  Eigen::Vector3d approach = Eigen::Vector3d::UnitZ();
  double pre_grasp_distance = 0.08;  ///< m, from the pre-grasp to the grasp along `approach` (>= 0)

  /// Throws std::invalid_argument naming the field: a non-rigid T_model_grasp (rigidProblem,
  /// common/rigid.hpp), a non-finite or non-unit approach (|1 - norm| > 1e-6), a negative or
  /// non-finite pre_grasp_distance. `what` prefixes the message (e.g. "grasps[2]").
  void validate(const std::string& what = "grasp") const;

  /// T_model_pregrasp: the grasp pose moved back by pre_grasp_distance against `approach`.
  Eigen::Isometry3d preGrasp() const;
};

/// The grasps equivalent to `grasp` under the part's symmetry: for each S_k in
/// symmetry.transforms(continuous_steps), the grasp with T_model_grasp' = S_k T_model_grasp
/// (same name, approach and distance: both are in the grasp frame, which moves with it).
/// Index k of the result is symmetry copy k; copy 0 is the grasp itself. A continuous
/// symmetry (order 0) is sampled every 2π / continuous_steps rad.
std::vector<Grasp> equivalentGrasps(const Grasp& grasp, const PartSymmetry& symmetry, int continuous_steps = 36);

}  // namespace scanalign

// Hand-eye calibration of an eye-in-hand camera: AX = ZB (Zhuang, Roth and Sudhakar 1994,
// "Simultaneous robot/world and tool/flange calibration by solving homogeneous transformation
// equations of the form AX = YB", IEEE T-RA 10(4)), solved for both unknowns:
//
//   T_base_flange_i · X = Z · T_world_camera_i,   X = T_flange_camera,  Z = T_base_world,
//
// A_i = T_base_flange_i (robot forward kinematics, accurate) and B_i = T_world_camera_i, the
// camera pose in a frame "world" that is fixed but unknown relative to the robot base: a
// calibration target (B_i = inv(T_camera_target_i), e.g. a checkerboard pose from PnP), or,
// without any target, the first camera frame of a frame-to-model ICP scan (the scan's
// trajectory T_model_camera_i). Metres and radians throughout.
//
// 1. Closed form (Daniilidis 1999, "Hand-eye calibration using dual quaternions", IJRR
//    18(3) 286-298): the relative motions A_ij = inv(A_i) A_j and B_ij = inv(B_i) B_j satisfy
//    A_ij X = X B_ij (Z cancels). As unit dual quaternions (CGA motors: Kleppe, PhD thesis,
//    NTNU 2018, Ch. 4, the motor of a screw motion; the screw axes of A_ij and B_ij are lines
//    that X maps onto each other) each pair gives 6 linear equations in the 8 coefficients of
//    X (Daniilidis eq. (31)); the stacked system's 2-dimensional null space (its two smallest
//    right singular vectors) and the two unit-dual-quaternion constraints give X (eqs.
//    (34)-(35)). Z is the chordal mean of A_i X inv(B_i).
// 2. Refinement: Levenberg-Marquardt on SE(3) x SE(3) (12 local parameters, right
//    perturbations X exp(xi_x), Z exp(xi_z)) of the camera-pose residuals
//    E_i = B_i inv(X) inv(A_i) Z (identity when consistent): the translation of E_i (metres;
//    equal in norm to the error of the target's position in camera i) and its rotation
//    vector times rotation_weight (metres per radian), optionally with a Huber loss per pose.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace scanalign {

/// Why a calibration has no answer (HandEyeResult::status).
enum class HandEyeStatus {
  Ok = 0,
  TooFewPoses,       ///< fewer than 3 poses (2 relative motions with non-parallel axes need 3)
  InvalidInput,      ///< sizes differ, or a pose is non-finite / not rigid (the message names it)
  DegenerateMotion,  ///< rotations too small, or all relative rotation axes (nearly) parallel
  /// The answer leaves an RMS residual above max_rms_translation / max_rotation: the poses do
  /// not fit one X and Z (robot and camera poses paired wrongly, a failed target detection, a
  /// lost ICP track). The transforms and residuals are still filled in, to look at.
  InconsistentPoses,
};

/// "ok", "too_few_poses", "invalid_input", "degenerate_motion", "inconsistent_poses".
const char* toString(HandEyeStatus status);

/// Settings of calibrateHandEye (units beside each field).
struct HandEyeSettings {
  /// Relative motions A_ij whose rotation is below this angle do not count for the
  /// degeneracy check (their axis is ill-defined); fewer than 2 above it: DegenerateMotion.
  /// rad; default 5 deg.
  double min_relative_rotation = 0.0872664626;
  /// Least spread of the relative rotation axes: the largest angle between the rotation axis of
  /// the largest relative rotation and that of any other counted motion (axes as lines, in
  /// [0, pi/2]). Below it the rotation about that axis is not determined: DegenerateMotion.
  /// rad; default 2 deg.
  double min_axis_angle = 0.0349065850;
  bool refine = true;             ///< Levenberg-Marquardt refinement of the closed form
  /// Weight of rotation residuals against translation ones, m/rad: a rotation error of 1 rad
  /// costs as much as a translation error of this many metres. The maximum-likelihood choice
  /// is sigma_translation / sigma_rotation of the camera poses (0.3 m/rad for the noise of a
  /// PnP target pose at 0.4 m: 0.05 mm / 0.01 deg).
  double rotation_weight = 0.3;
  /// Huber threshold on the weighted 6-vector residual of a pose, m (0: least squares). Poses
  /// beyond it count linearly, so one bad target detection does not pull the answer.
  double huber_delta = 0.0;
  /// Largest RMS translation residual of an answer, m (default 2 cm: twenty times a drifting
  /// ICP scan's); above it: InconsistentPoses.
  double max_rms_translation = 0.02;
  /// Largest RMS rotation residual of an answer, rad (default 5 deg); above it: InconsistentPoses.
  double max_rms_rotation = 0.0872664626;
  int max_iterations = 50;        ///< Levenberg-Marquardt iterations, >= 1
  /// Stop when the step's largest component is below this (m and rad).
  double step_tolerance = 1e-12;
};

/// Throws std::invalid_argument naming the field: angles finite and in [0, pi/2],
/// rotation_weight, max_rms_translation and max_rms_rotation finite and > 0, huber_delta
/// finite and >= 0, max_iterations >= 1,
/// step_tolerance finite and >= 0.
void validate(const HandEyeSettings& settings);

/// Outcome of calibrateHandEye. Transforms are 4x4, metres.
struct HandEyeResult {
  HandEyeStatus status = HandEyeStatus::InvalidInput;
  std::string message;  ///< empty when Ok, else why (naming the pose index when one is bad)
  /// T_flange_camera (camera -> flange), refined when settings.refine, else the closed form.
  Eigen::Matrix4d T_flange_camera = Eigen::Matrix4d::Identity();
  /// T_base_world (the target / scan's world frame -> robot base).
  Eigen::Matrix4d T_base_world = Eigen::Matrix4d::Identity();
  Eigen::Matrix4d T_flange_camera_closed_form = Eigen::Matrix4d::Identity();  ///< Daniilidis 1999
  Eigen::Matrix4d T_base_world_closed_form = Eigen::Matrix4d::Identity();     ///< chordal mean
  /// Per pose i: |rotation| of E_i = B_i inv(X) inv(A_i) Z at the answer, rad.
  Eigen::VectorXd residual_rotation;
  /// Per pose i: |translation| of E_i at the answer, m.
  Eigen::VectorXd residual_translation;
  double rms_rotation = 0.0;                  ///< rad, over poses, at the answer
  double rms_translation = 0.0;               ///< m, over poses, at the answer
  double rms_rotation_closed_form = 0.0;      ///< rad, at the closed form
  double rms_translation_closed_form = 0.0;   ///< m, at the closed form
  int iterations = 0;                         ///< Levenberg-Marquardt iterations (0: no refinement)
  bool converged = false;                     ///< the refinement met step_tolerance (true without refinement)
  int pairs = 0;                              ///< relative motions (pose pairs) in the closed form
  double axis_spread = 0.0;                   ///< rad, see HandEyeSettings::min_axis_angle
  double max_relative_rotation = 0.0;         ///< rad, largest rotation of a relative motion
  bool ok() const { return status == HandEyeStatus::Ok; }
};

/// Solves T_base_flange[i] X = Z T_world_camera[i] for X = T_flange_camera and
/// Z = T_base_world (see the file comment). The closed form uses all relative motions (pairs
/// i < j) up to 64 poses, beyond that the pairs with j - i = 1, 2, 4, 8, ... (about N log2 N),
/// so time and memory stay near linear in N. Never throws for bad poses: the result says why (a status and a message
/// naming the index); throws std::invalid_argument for invalid settings (validate).
HandEyeResult calibrateHandEye(const std::vector<Eigen::Matrix4d>& T_base_flange,
                               const std::vector<Eigen::Matrix4d>& T_world_camera,
                               const HandEyeSettings& settings = {});

/// The same from views of a fixed target: T_camera_target[i] (target -> camera i), so
/// T_world_camera = inv(T_camera_target) and the result's T_base_world is T_base_target.
HandEyeResult calibrateHandEyeFromTarget(const std::vector<Eigen::Matrix4d>& T_base_flange,
                                         const std::vector<Eigen::Matrix4d>& T_camera_target,
                                         const HandEyeSettings& settings = {});

}  // namespace scanalign

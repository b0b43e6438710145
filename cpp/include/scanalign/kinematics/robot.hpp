// Serial 6R robots in standard Denavit-Hartenberg form, forward kinematics and the
// built-in arm models (Kleppe, PhD thesis, NTNU 2018, Paper 1 eqs. (1)-(3)).
//
// Frames and units:
//  - metres and radians;
//  - DH frame i is attached to link i; frame 0 is the DH base frame, frame 6 the flange;
//  - T_{i-1,i} = Rot_z(theta_i) Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i)      (P1 (1))
//    with theta_i = q_i + theta_offset_i, where q_i is the joint value the controller
//    reports;
//  - Robot::T_base_dh0 places DH frame 0 in the user's robot base frame ("base"), and
//    Robot::T_flange_tool places the tool centre point in the flange frame, so
//        T_base_tool = T_base_dh0 * T_{0,1} ... T_{5,6} * T_flange_tool        (P1 (3)).
//
// This header is PCL-free and allocation-free; a robot controller can use it without Python.
// A robot from a serial chain of joint axes (a URDF's joints): kinematics/joint_chain.hpp.
#pragma once

#include <array>
#include <cstddef>
#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace scanalign {

using Vector6d = Eigen::Matrix<double, 6, 1>;

struct JointChain;          // kinematics/joint_chain.hpp
struct JointChainSettings;  // kinematics/joint_chain.hpp

/// One revolute joint in standard DH form.
struct DHJoint {
  double a = 0;             ///< link length along x_i, m (may be negative, as in UR's tables)
  double alpha = 0;         ///< link twist about x_i, rad
  double d = 0;             ///< link offset along z_{i-1}, m
  double theta_offset = 0;  ///< DH theta_i = q_i + theta_offset, rad
  double q_min = -M_PI;     ///< lower joint limit of q_i, rad
  double q_max = M_PI;      ///< upper joint limit of q_i, rad
};

/// Which analytic solver applies to a DH table (Robot::geometry()).
enum class ArmGeometry {
  /// Not one of the two families below: forward kinematics only.
  Unsupported = 0,
  /// KUKA-type 6R with a shoulder offset a1, an elbow offset a3 and a spherical wrist
  /// (KUKA KR6 R900 sixx "Agilus", and KUKA/ABB/Fanuc arms of the same layout):
  /// alpha = (-pi/2, 0, -pi/2, pi/2, -pi/2, 0), d2 = d3 = d5 = 0, a4 = a5 = a6 = 0,
  /// a2 > 0, d4 > 0 (thesis P1 §4).
  SphericalWrist = 1,
  /// Universal Robots layout: three parallel axes (2, 3, 4) and an offset wrist:
  /// alpha = (pi/2, 0, 0, pi/2, -pi/2, 0), a1 = a4 = a5 = a6 = 0, d2 = d3 = 0,
  /// a2, a3 != 0, d4, d5 > 0 (thesis P1 §5).
  UniversalRobots = 2,
};

const char* toString(ArmGeometry g);
/// The two analytic layouts in words ("'spherical_wrist' (KUKA type: alpha = ...) and
/// 'universal_robots' (...)"), for messages about a DH table that is neither.
const char* analyticLayoutsText();

/// A serial 6R arm: DH table, joint limits, base and tool transforms. A value type.
struct Robot {
  std::string name;
  std::array<DHJoint, 6> joints{};
  /// DH frame 0 -> the user's robot base frame. Identity for the built-in models except
  /// where stated.
  Eigen::Isometry3d T_base_dh0 = Eigen::Isometry3d::Identity();
  /// Tool centre point -> flange (DH frame 6). Identity: the tool is the flange.
  Eigen::Isometry3d T_flange_tool = Eigen::Isometry3d::Identity();

  /// Classifies the DH table (tolerance 1e-12 on zeros and twists).
  ArmGeometry geometry() const;

  /// DH transform T_{i-1,i}(q_i), i = 1..6 (P1 (1)).
  Eigen::Isometry3d link(int i, double q) const;
  /// T_base_tool(q) (P1 (3)).
  Eigen::Isometry3d forward(const Vector6d& q) const;
  /// T_base_flange(q): without the tool transform.
  Eigen::Isometry3d forwardFlange(const Vector6d& q) const;
  /// T_dh0_i for i = 0..6 (frames[0] = identity, frames[6] = flange), in DH frame 0.
  std::array<Eigen::Isometry3d, 7> jointFrames(const Vector6d& q) const;
  /// The joint points of the arm: the origins of DH frames 0..6 in the robot base frame
  /// (T_base_dh0 applied), base to flange, m: the arm's stick figure (P1 (3) truncated after
  /// each link).
  std::array<Eigen::Vector3d, 7> jointPositions(const Vector6d& q) const;
  /// jointPositions for n configurations: q is n x 6 row-major (rad), out receives n x 7 x 3
  /// values (m), or n x 8 x 3 with tcp, the tool centre point (the origin of forward(q))
  /// appended to each. Parallel over configurations as forwardBatch.
  void jointPositionsBatch(const double* q, std::size_t n, double* out, bool tcp = false, int num_threads = 0) const;
  /// Forward kinematics for n configurations: q is n x 6 row-major (rad), out is n 4x4
  /// row-major T_base_tool matrices (metres). Parallel over configurations (OpenMP) when
  /// num_threads != 1 (0 = all cores).
  void forwardBatch(const double* q, std::size_t n, double* out, int num_threads = 0) const;

  /// True when every q_i is in [q_min - tol, q_max + tol].
  bool withinLimits(const Vector6d& q, double tol = 0) const;

  // ----- built-in models (values and sources documented in robot.cpp) -----
  /// KUKA KR6 R900 sixx (Agilus): DH of the thesis authors' CluCalc code (thesis Table 1 is garbled in print), verified by
  /// the home pose q = (0, -pi/2, pi/2, 0, 0, 0) -> p = (0.525, 0, 0.890) m; limits from
  /// KUKA's data sheet (A1 ±170°, A2 -190°..+45°, A3 -120°..+156°, A4 ±185°, A5 ±120°,
  /// A6 ±350°).
  static Robot kukaKR6R900sixx();
  /// UR5 (CB-series) with Universal Robots' published DH table.
  static Robot ur5();
  /// UR5 with the numbers printed in the thesis (Table 2: d1 = 89.2, a2 = -425,
  /// a3 = -392.43, d4 = 109.15, d5 = 94.65, d6 = 82.3 mm), for reproducing thesis Table 2.
  static Robot ur5Thesis();
  static Robot ur3();
  static Robot ur10();
  static Robot ur3e();
  static Robot ur5e();
  static Robot ur10e();
  /// By name: "kr6_r900_sixx" (alias "agilus"), "ur3", "ur5", "ur10", "ur3e", "ur5e",
  /// "ur10e", "ur5_thesis". Throws std::invalid_argument for an unknown name.
  static Robot byName(const std::string& name);

  /// The robot of a serial chain of 6 revolute joints given by their axes (a URDF's joints,
  /// kinematics/joint_chain.hpp): the DH table, T_base_dh0, T_flange_tool and limits whose
  /// forward kinematics equals the chain's, in one of the analytic layouts where possible.
  /// Throws std::invalid_argument (a bad chain or setting, or a chain no analytic layout fits
  /// unless settings.fk_only) and std::runtime_error (the DH model departs from the chain).
  static Robot fromJointChain(const JointChain& chain, const JointChainSettings& settings);
};

}  // namespace scanalign

// Analytic inverse kinematics with conformal geometric algebra (thesis Paper 1, Ch. 5.3;
// Kleppe, PhD thesis, NTNU 2018, Paper 1 §4-5, with the corrections noted below).
//
// The solver builds the joint points of the arm as intersections of CGA spheres and planes,
// exactly as Paper 1 does:
//   KUKA KR6 R900 sixx (Paper 1 §4): P_w = p_e - d6 a_e; P1 from S0* ^ Pi1* ^ Pi_c (29);
//     P2 from S1* ^ S_w* ^ Pi_c (32)-(34); P_wx by the horizon of P_w on S2 (35)-(37).
//   UR (Paper 1 §5): P5 = p_e - d6 a_e; P_c by the horizon of the origin on S_c in the
//     horizontal plane through P5 (43)-(45); P4 from L45* ^ S5* (49); P3 on L34 (50);
//     P2 from (P1 - a2²/2 e∞) ^ (P3 - a3²/2 e∞) ^ Pi_c (52)-(53).
// Conformal objects are 5-vectors on (e1, e2, e3, e∞, e0) with the metric of (5.32), as in
// fitting/sphere_fit.hpp. Every point pair is tested for reality: Q² < 0 (no real
// intersection) reports the configuration as unreachable, never as wrong angles (thesis (4.70)-(4.73), Paper 1 §3.4).
// Joint angles then come from the joint points by a recursive DH extraction that applies
// Paper 1's rule N* = z_{i-1} (eq. (22)) directly, so it does not depend on the blade sign
// conventions.
//
// Configuration labels are geometric, not the CGA point-pair signs (whose meaning depends on
// object orientation, Paper 1 eqs. (26)-(28), (40)-(42)):
//   shoulder +1 ("front"): the wrist centre (KUKA P_w; UR: P_c, the projection of P5 onto
//            the arm plane) lies on the side of the first joint axis that the upper arm
//            points to at θ2 = 0, i.e. along f = sign(a2)·x1, x1 being the DH x axis of
//            link 1; -1 ("back"): on the other side. For the KUKA (a2 > 0), +1 puts P1
//            between the base axis and the wrist; for UR arms (a2 < 0) it is the -x1 side.
//   elbow    +1 ("up"): the elbow joint point P2 lies above the line from the shoulder
//            point P1 to the wrist point (KUKA P_w, UR P3), seen in the arm plane with the arm
//            reaching forward: sign(shoulder · ((wrist − P1) × (P2 − P1)) · (f × e3));
//            -1 ("down"): below it.
//   wrist    +1 ("no flip"): sin(theta5) > 0 for the DH angle theta5 = q5 + offset5;
//            -1 ("flip"): sin(theta5) < 0.
// Solutions are stored at a fixed index, configIndex() = 4*(shoulder<0) + 2*(elbow<0) +
// (wrist<0), so solution k always has the same configuration.
//
// Singularities (Paper 1 §4-5, singular configurations) are detected and solved with a documented free angle:
//   shoulder (KUKA: P_w on the first axis, the arm plane Pi_c undefined): q1 = q_free[0]
//            (the "back" solutions use q1 + pi);
//   wrist    (KUKA: a_e parallel to z3, theta5 = 0 or pi; UR: a_e parallel to z1): KUKA
//            q4 = q_free[3] (flip: q4 + pi); UR q6 = q_free[5] (flip: q6 + pi), or, when the
//            elbow cannot reach with that q6, the nearest q6 for which it can (q6 moves the
//            wrist points P4 and P3 on circles);
//   elbow    (the point pair of P2 is tangent, Q² = 0: arm stretched or folded): no free
//            angle, the two elbow labels give the same joint angles (up to the rounding of
//            a nearly tangent pair);
//   UR shoulder (P_c on the first axis: the horizon pair is tangent): no free angle; the
//            solutions whose shoulder AND elbow labels are both flipped coincide (the elbow
//            label is measured relative to the shoulder side).
// A point pair counts as tangent when |h²/r²| <= IKSettings::reach_tolerance; a pose that
// is singular for one arm configuration (e.g. θ5 = 0 for the elbow-up solution) is usually
// regular for the others, so the bits are per solution.
// The solution's `singular` bit mask says which applied.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "scanalign/kinematics/robot.hpp"

namespace scanalign {

enum class IKStatus : std::uint8_t {
  Ok = 0,             ///< q reaches the pose and lies inside the joint limits
  OutsideLimits = 1,  ///< q reaches the pose but some joint has no 2π-multiple inside its limits
  Unreachable = 2,    ///< a point pair of the construction is imaginary (Q² < 0)
  InvalidInput = 3,   ///< non-finite or non-rigid pose, or a robot the solver does not cover
};
const char* toString(IKStatus s);

/// Bits of IKSolution::singular.
enum SingularBits : std::uint8_t {
  kSingularShoulder = 1,
  kSingularElbow = 2,
  kSingularWrist = 4,
};

/// Which step of the construction failed (IKSolution::unreachable_step).
enum class IKStep : std::uint8_t {
  None = 0,
  Shoulder = 1,  ///< UR: the horizon point pair Q_c (P5 within d4 of the first axis)
  Elbow = 2,     ///< the elbow point pair Q2 (wrist too far from / too close to the shoulder)
  /// The construction gave angles whose forward kinematics misses the target by more than
  /// kIKPositionTolerance / kIKRotationTolerance (rounding that the construction could not
  /// absorb): reported as Unreachable rather than as a wrong answer.
  FkCheck = 3,
};
/// "" (None), "shoulder", "elbow", "fk_check".
const char* toString(IKStep s);

/// Every solution reported Ok or OutsideLimits satisfies |FK(q) - T| <= these, on top of the
/// target's own departure from a rotation (e = max |R^T R - I|, at most kRigidTolerance): position
/// within kIKPositionTolerance + e * (sum of |a_i| + |d_i|) metres, every rotation-matrix entry
/// within kIKRotationTolerance + 2 e. A solution that misses is demoted to Unreachable with
/// unreachable_step FkCheck.
inline constexpr double kIKPositionTolerance = 1e-6;  ///< m
inline constexpr double kIKRotationTolerance = 1e-6;  ///< rotation-matrix entries (~rad)

struct IKConfig {
  std::int8_t shoulder = 1;  ///< +1 front / -1 back (see the file comment)
  std::int8_t elbow = 1;     ///< +1 up / -1 down
  std::int8_t wrist = 1;     ///< +1 no flip / -1 flip
};
/// 4*(shoulder<0) + 2*(elbow<0) + (wrist<0).
inline int configIndex(const IKConfig& c) { return 4 * (c.shoulder < 0) + 2 * (c.elbow < 0) + (c.wrist < 0); }
inline IKConfig configFromIndex(int k) {
  return {static_cast<std::int8_t>(k & 4 ? -1 : 1), static_cast<std::int8_t>(k & 2 ? -1 : 1),
          static_cast<std::int8_t>(k & 1 ? -1 : 1)};
}

struct IKSolution {
  /// Joint values q (rad), each wrapped to the 2π-multiple inside its limits that is closest
  /// to 0; NaN when status is Unreachable or InvalidInput.
  Vector6d q = Vector6d::Constant(std::numeric_limits<double>::quiet_NaN());
  IKConfig config;
  IKStatus status = IKStatus::Unreachable;
  std::uint8_t singular = 0;            ///< SingularBits
  IKStep unreachable_step = IKStep::None;
  bool ok() const { return status == IKStatus::Ok; }
};

struct IKResult {
  std::array<IKSolution, 8> solutions{};  ///< solutions[configIndex(c)] has configuration c
  IKStatus status = IKStatus::Unreachable;  ///< Ok if any solution is Ok, else the "best" status
  int count(IKStatus s = IKStatus::Ok) const {
    int n = 0;
    for (const auto& x : solutions) n += x.status == s;
    return n;
  }
};

/// The Ok solutions of r without duplicates, in index order: a solution repeats an earlier one
/// when every joint differs from it by a multiple of 2π within tol rad (e.g. the two elbow
/// labels at the elbow singularity give the same angles). The first of each group is kept.
inline std::vector<Vector6d> distinctSolutions(const IKResult& r, double tol = 1e-9) {
  std::vector<Vector6d> out;
  for (const IKSolution& s : r.solutions) {
    if (!s.ok()) continue;
    const auto repeats = [&](const Vector6d& q) {
      for (int j = 0; j < 6; ++j)
        if (!(std::abs(std::remainder(s.q[j] - q[j], 2 * M_PI)) <= tol)) return false;
      return true;
    };
    if (std::none_of(out.begin(), out.end(), repeats)) out.push_back(s.q);
  }
  return out;
}

struct IKSettings {
  /// Free angles used at singularities (rad): q_free[0] for the KUKA shoulder, q_free[3] for
  /// the KUKA wrist, q_free[5] for the UR wrist. ikClosest passes the current joints.
  Vector6d q_free = Vector6d::Zero();
  /// A point pair whose normalised discriminant h²/r² (h = half chord, r = sphere radius)
  /// is >= -reach_tolerance counts as real (tangent when <= reach_tolerance): poses on the
  /// workspace boundary, computed in floating point, stay reachable. Dimensionless.
  double reach_tolerance = 1e-12;
  /// sin of the angle between the two axes below which a wrist (or KUKA shoulder: distance
  /// of P_w from the first axis over the sum of the link lengths) is solved as exactly
  /// singular, with the free angle. Dimensionless. Poses nearer than this to a singularity
  /// are solved by the regular construction, which stays exact (FK(IK(T)) = T to ~1e-14) down
  /// to about 1e-10; solving a pose at distance s as singular misses it by about s metres.
  /// 2e-11 balances the two: every pose is reached to better than 1e-10 (see
  /// test_kinematics.cpp, NearSingularAndBoundaryPosesStayExact).
  double singular_tolerance = 2e-11;
  /// Report solutions whose joints cannot be wrapped into the limits as OutsideLimits
  /// (true), or ignore the limits (false: q wrapped to (-π, π]).
  bool respect_limits = true;
};

/// All (up to 8) solutions for a target tool pose T_base_tool (tool -> robot base, metres).
/// Never throws for bad poses: a non-finite or non-rigid pose (rigidProblem(), common/rigid.hpp)
/// gives IKStatus::InvalidInput (the Python bindings raise ValueError naming the argument
/// instead). Every Ok / OutsideLimits solution has been checked by forward kinematics
/// (kIKPositionTolerance, kIKRotationTolerance). An elbow point pair that is imaginary only by
/// rounding (normalised discriminant in [-1e-6, 0), as a stretched arm with a nearly singular
/// wrist gives: the wrist point P4 then carries an error ~1e-16 / sin(theta5) m) is solved as
/// tangent and kept only when that FK check passes.
IKResult ik(const Robot& robot, const Eigen::Isometry3d& T_base_tool, const IKSettings& options = {});

struct ClosestSettings {
  /// Weight of each joint in the distance sum_i w_i (q_i - q_current_i)².
  Vector6d weights = Vector6d::Ones();
};

/// The solution nearest to q_current (rad) in the weighted joint distance, over every Ok
/// solution and every 2π multiple of each joint that lies inside the limits. The returned
/// solution has status Unreachable / OutsideLimits / InvalidInput when no Ok solution
/// exists. Singular free angles are taken from q_current.
IKSolution ikClosest(const Robot& robot, const Eigen::Isometry3d& T_base_tool, const Vector6d& q_current,
                     const IKSettings& options = {}, const ClosestSettings& closest = {});

/// Batch IK: poses are n 4x4 row-major T_base_tool matrices; out[n] receives the results.
/// Parallel over poses (OpenMP; 0 = all cores, 1 = serial).
void ikBatch(const Robot& robot, const double* poses, std::size_t n, IKResult* out, const IKSettings& options = {},
             int num_threads = 0);

/// A joint trajectory through a sequence of poses: each step takes the solution closest to
/// the previous step's joints (the first to q_start). out_q receives n x 6 values (NaN rows
/// where no Ok solution exists; the next step then starts again from the last good q) and
/// out_status n statuses. Returns the number of Ok steps.
std::size_t ikTrajectory(const Robot& robot, const double* poses, std::size_t n, const Vector6d& q_start,
                         double* out_q, IKStatus* out_status, const IKSettings& options = {},
                         const ClosestSettings& closest = {});

/// The intermediate CGA construction of one configuration, in DH frame 0 (metres): for
/// inspection, plots and tests against an independent CGA implementation.
struct IKConstruction {
  ArmGeometry geometry = ArmGeometry::Unsupported;
  IKSolution solution;
  /// Named points (KUKA: p_e, P_w, P1, P2, P_wx; UR: p_e, P5, P_c, P4, P3, P2, P1), NaN when
  /// not reached.
  std::array<std::string, 8> names{};
  std::array<Eigen::Vector3d, 8> points{};
  int num_points = 0;
  /// Normalised discriminants h²/r² of the shoulder (UR horizon) and elbow point pairs:
  /// the sign of Q² (thesis (4.70)-(4.73)).
  double shoulder_discriminant = std::numeric_limits<double>::quiet_NaN();
  double elbow_discriminant = std::numeric_limits<double>::quiet_NaN();
};
IKConstruction ikConstruction(const Robot& robot, const Eigen::Isometry3d& T_base_tool, const IKConfig& config,
                              const IKSettings& options = {});

}  // namespace scanalign

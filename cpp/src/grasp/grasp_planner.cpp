// Grasps, the gripper body and the grasp planner (grasp/grasp.hpp, gripper.hpp,
// grasp_planner.hpp). The planner is a filter over IK candidates: the analytic IK (Kleppe,
// PhD thesis, NTNU 2018, Paper 1 §4-5) gives all eight arm configurations of each pre-grasp,
// so every candidate can be rejected with a measured reason instead of being missed by a
// local solver.
#include "scanalign/grasp/grasp_planner.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <Eigen/Geometry>  // cross()

#include "scanalign/common/rigid.hpp"

namespace scanalign {

namespace {

constexpr double kUnitTolerance = 1e-6;   // |1 - |v|| accepted for a unit vector
constexpr double kFkTolerance = 1e-9;     // FK(q) vs the commanded flange pose, m and matrix entries
constexpr long kMaxApproachSamples = 100000;
constexpr std::size_t kMaxGraspCopies = 10000;  // grasps x symmetry copies per call

std::string num(double v, const char* fmt = "%.4g") {
  char buf[64];
  std::snprintf(buf, sizeof buf, fmt, v);
  return buf;
}

void requireFinite(double v, const std::string& what, bool positive = false) {
  if (!std::isfinite(v) || v < 0 || (positive && v == 0))
    throw std::invalid_argument(what + " must be a finite number " + (positive ? "> 0" : ">= 0") + ", got " +
                                num(v));
}

void requireFiniteVector(const Eigen::Vector3d& v, const std::string& what) {
  if (!v.allFinite()) throw std::invalid_argument(what + " must be finite (m)");
}

}  // namespace

// ----------------------------------------------------------------------------- Grasp

void Grasp::validate(const std::string& what) const {
  requireRigid(T_model_grasp.matrix(), what + ".T_model_grasp");
  if (!approach.allFinite() || std::abs(approach.norm() - 1) > kUnitTolerance)
    throw std::invalid_argument(what + ".approach must be a finite unit 3-vector (grasp frame), got norm " +
                                num(approach.norm()));
  requireFinite(pre_grasp_distance, what + ".pre_grasp_distance (m)");
}

Eigen::Isometry3d Grasp::preGrasp() const {
  return T_model_grasp * Eigen::Translation3d(-pre_grasp_distance * approach);
}

std::vector<Grasp> equivalentGrasps(const Grasp& grasp, const PartSymmetry& symmetry, int continuous_steps) {
  std::vector<Grasp> out;
  for (const Eigen::Isometry3d& S : symmetry.transforms(continuous_steps)) {
    Grasp g = grasp;
    g.T_model_grasp = S * grasp.T_model_grasp;  // S_k maps the part onto itself (model -> model)
    out.push_back(g);
  }
  return out;
}

// ----------------------------------------------------------------------------- Gripper

const char* toString(GripperShape s) { return s == GripperShape::Capsule ? "capsule" : "box"; }

void Gripper::validate() const {
  requireRigid(T_flange_tcp.matrix(), "gripper.T_flange_tcp");
  requireFiniteVector(capsule_a, "gripper.capsule_a");
  requireFiniteVector(capsule_b, "gripper.capsule_b");
  requireFinite(capsule_radius, "gripper.capsule_radius (m)");
  requireFiniteVector(box_centre, "gripper.box_centre");
  if (!box_half_extents.allFinite() || (box_half_extents.array() < 0).any())
    throw std::invalid_argument("gripper.box_half_extents must be finite and >= 0 (m)");
  requireFinite(flange_radius, "gripper.flange_radius (m)");
  if (shape != GripperShape::Capsule && shape != GripperShape::Box)
    throw std::invalid_argument("gripper.shape must be capsule or box");
}

double Gripper::bodyHeight(const Eigen::Isometry3d& T_base_flange, const Eigen::Vector3d& n, double d) const {
  const Eigen::Vector3d nf = T_base_flange.linear().transpose() * n;  // the normal in the flange frame
  const double h0 = n.dot(T_base_flange.translation()) + d;           // height of the flange origin
  if (shape == GripperShape::Capsule)
    return h0 + std::min(nf.dot(capsule_a), nf.dot(capsule_b)) - capsule_radius;
  // The lowest box corner: centre minus the half extents projected on the normal.
  return h0 + nf.dot(box_centre) - nf.cwiseAbs().dot(box_half_extents);
}

double Gripper::flangeHeight(const Eigen::Isometry3d& T_base_flange, const Eigen::Vector3d& n, double d) const {
  // The lowest point of a disc of radius r with axis z: r times the normal's share in the disc plane.
  const Eigen::Vector3d z = T_base_flange.linear().col(2);
  const double in_plane = std::sqrt(std::max(0.0, 1 - z.dot(n) * z.dot(n)));
  return n.dot(T_base_flange.translation()) + d - flange_radius * in_plane;
}

Gripper Gripper::parallelJaw() {
  Gripper g;
  g.T_flange_tcp = Eigen::Translation3d(0, 0, 0.15) * Eigen::Isometry3d::Identity();
  g.shape = GripperShape::Box;
  g.box_centre = {0, 0, 0.075};
  g.box_half_extents = {0.04, 0.07, 0.075};
  g.capsule_a = {0, 0, 0.04};
  g.capsule_b = {0, 0, 0.11};
  g.capsule_radius = 0.04;
  g.flange_radius = 0.0315;
  return g;
}

// ----------------------------------------------------------------------------- settings

const char* toString(GraspReason r) {
  switch (r) {
    case GraspReason::Ok: return "ok";
    case GraspReason::Unreachable: return "unreachable";
    case GraspReason::OutsideLimits: return "outside_limits";
    case GraspReason::NearSingularity: return "near_singularity";
    case GraspReason::BelowTable: return "below_table";
    case GraspReason::ApproachBranchChange: return "approach_branch_change";
  }
  return "?";
}

void GraspPlannerSettings::validate() const {
  requireFinite(table_clearance, "settings.table_clearance (m)");
  requireFinite(min_wrist_angle, "settings.min_wrist_angle (rad)");
  requireFinite(min_shoulder_distance, "settings.min_shoulder_distance (m)");
  requireFinite(min_elbow_angle, "settings.min_elbow_angle (rad)");
  requireFinite(approach_step, "settings.approach_step (m)", true);
  requireFinite(max_joint_step, "settings.max_joint_step (rad)", true);
  // Bounded so that a cost (weights times at most a few hundred rad) stays finite and comparable.
  if (!joint_weights.allFinite() || (joint_weights.array() < 0).any() || (joint_weights.array() > 1e6).any())
    throw std::invalid_argument("settings.joint_weights must be 6 values in [0, 1e6]");
  if (continuous_symmetry_steps < 1 || continuous_symmetry_steps > 3600)
    throw std::invalid_argument("settings.continuous_symmetry_steps must be in 1..3600, got " +
                                std::to_string(continuous_symmetry_steps));
}

// ----------------------------------------------------------------------------- planner

namespace {

/// Everything a candidate check needs, fixed for one planGrasp call.
struct Cell {
  Robot arm;  // the robot with the flange as its tool: IK and FK of flange poses
  ArmGeometry geometry = ArmGeometry::Unsupported;
  Gripper gripper;
  Eigen::Vector3d n;
  double d = 0;
  Vector6d q_current;
  GraspPlannerSettings settings;
  IKSettings ik;
};

/// The joint values nearest q_ref, each moved by a multiple of 2π and kept within the limits
/// when the settings respect them (ik() returns those nearest 0).
Vector6d nearestMultiple(const Cell& c, const Vector6d& q) {
  Vector6d out = q;
  for (int j = 0; j < 6; ++j) {
    const DHJoint& J = c.arm.joints[static_cast<std::size_t>(j)];
    const double k0 = std::round((c.q_current[j] - q[j]) / (2 * M_PI));
    double best = std::numeric_limits<double>::infinity();
    for (double k = k0 - 1; k <= k0 + 1; ++k) {
      const double v = q[j] + 2 * M_PI * k;
      if (c.settings.respect_limits && (v < J.q_min || v > J.q_max)) continue;
      if (std::abs(v - c.q_current[j]) < best) best = std::abs(v - c.q_current[j]), out[j] = v;
    }
  }
  return out;
}

double weightedMotion(const Cell& c, const Vector6d& a, const Vector6d& b) {
  return c.settings.joint_weights.dot((b - a).cwiseAbs());
}

double fkError(const Cell& c, const Vector6d& q, const Eigen::Isometry3d& T_base_flange) {
  return (c.arm.forwardFlange(q).matrix() - T_base_flange.matrix()).cwiseAbs().maxCoeff();
}

/// "" when no margin is violated, else which singularity and its measured value. The margins
/// are measured on the solution's joint points, in the terms of the IK construction (ik.hpp).
std::string singularity(const Cell& c, const Vector6d& q) {
  const GraspPlannerSettings& s = c.settings;
  const auto F = c.arm.jointFrames(q);
  const double wrist = std::asin(std::min(1.0, std::abs(std::sin(q[4] + c.arm.joints[4].theta_offset))));
  if (wrist < s.min_wrist_angle)
    return "wrist: theta5 is " + num(wrist) + " rad from 0 or pi (min_wrist_angle " + num(s.min_wrist_angle) + ")";
  const bool kuka = c.geometry == ArmGeometry::SphericalWrist;
  const Eigen::Vector3d W = kuka ? F[4].translation() : F[5].translation();  // KUKA P_w, UR P5
  const double r2 = W.head<2>().squaredNorm();
  const double d4 = c.arm.joints[3].d;
  const double shoulder = std::sqrt(std::max(0.0, kuka ? r2 : r2 - d4 * d4));
  if (shoulder < s.min_shoulder_distance)
    return "shoulder: wrist centre " + num(shoulder) + " m from the first axis (min_shoulder_distance " +
           num(s.min_shoulder_distance) + ")";
  const Eigen::Vector3d u = F[2].translation() - F[1].translation();
  const Eigen::Vector3d v = (kuka ? F[4] : F[3]).translation() - F[2].translation();
  const double phi = std::atan2(u.cross(v).norm(), u.dot(v));
  const double elbow = std::min(phi, M_PI - phi);
  if (elbow < s.min_elbow_angle)
    return "elbow: " + num(elbow) + " rad from " + (phi < M_PI / 2 ? "stretched" : "folded") +
           " (min_elbow_angle " + num(s.min_elbow_angle) + ")";
  return "";
}

/// "" when the gripper body, the flange and (optionally) the arm's joint points clear the table.
std::string tableProblem(const Cell& c, const Vector6d& q, const Eigen::Isometry3d& T_base_flange) {
  const double clearance = c.settings.table_clearance;
  const auto report = [&](const std::string& what, double h) {
    return what + " " + num(h) + " m above the table (table_clearance " + num(clearance) + ")";
  };
  const double body = c.gripper.bodyHeight(T_base_flange, c.n, c.d);
  if (body < clearance) return report(std::string("gripper ") + toString(c.gripper.shape), body);
  const double flange = c.gripper.flangeHeight(T_base_flange, c.n, c.d);
  if (flange < clearance) return report("flange", flange);
  if (!c.settings.check_arm_points) return "";
  const auto F = c.arm.jointFrames(q);
  for (int i = 2; i <= 5; ++i) {
    const double h = c.n.dot(c.arm.T_base_dh0 * F[static_cast<std::size_t>(i)].translation()) + c.d;
    if (h < clearance) return report("arm joint point (DH frame " + std::to_string(i) + " origin)", h);
  }
  return "";
}

/// Which joints of a reachable pose have no 2π multiple within the limits (for the detail).
std::string jointsOutside(const Cell& c, const Eigen::Isometry3d& T_base_flange, int config) {
  IKSettings free = c.ik;
  free.respect_limits = false;
  const IKSolution s = ik(c.arm, T_base_flange, free).solutions[static_cast<std::size_t>(config)];
  std::string out;
  for (int j = 0; j < 6 && s.q.allFinite(); ++j) {
    const DHJoint& J = c.arm.joints[static_cast<std::size_t>(j)];
    const double v = J.q_min + std::remainder(s.q[j] - J.q_min - M_PI, 2 * M_PI) + M_PI;  // lowest multiple >= q_min
    if (v > J.q_max) out += (out.empty() ? "" : ", ") + std::to_string(j + 1);
  }
  return out.empty() ? "" : "joint(s) " + out + " ";
}

std::string sampleName(int k, int n) {
  if (k == 0) return "the pre-grasp";
  if (k == n) return "the grasp";
  return "approach sample " + std::to_string(k) + " of " + std::to_string(n);
}

void reject(GraspCandidate& cand, GraspReason r, const std::string& detail) {
  cand.reason = r;
  cand.detail = detail;
}

/// TCP pose at approach sample k of n (k = 0: pre-grasp, k = n: grasp): a pure translation
/// along the approach, so the orientation stays that of the grasp.
Eigen::Isometry3d approachPose(const Eigen::Isometry3d& T_base_tcp_grasp, const Grasp& g, int k, int n) {
  const double back = g.pre_grasp_distance * (1.0 - double(k) / n);
  return T_base_tcp_grasp * Eigen::Translation3d(-back * g.approach);
}

/// Follows the approach from q0 with ikClosest; fills path, or rejects the candidate.
bool followApproach(const Cell& c, const Grasp& g, GraspCandidate& cand, int n, std::vector<Vector6d>& path,
                    std::vector<Eigen::Isometry3d>& flange) {
  const Eigen::Isometry3d T_tcp_flange = c.gripper.T_flange_tcp.inverse();
  path.assign(1, cand.q_pregrasp);
  flange.assign(1, cand.T_base_flange_pregrasp);
  for (int k = 1; k <= n; ++k) {
    const Eigen::Isometry3d T = approachPose(cand.T_base_tcp_grasp, g, k, n) * T_tcp_flange;
    IKSettings opt = c.ik;
    opt.q_free = path.back();  // singular free angles continue the previous sample's
    const IKSolution s = ikClosest(c.arm, T, path.back(), opt);
    if (!s.ok()) {
      reject(cand, s.status == IKStatus::OutsideLimits ? GraspReason::OutsideLimits : GraspReason::Unreachable,
             sampleName(k, n) + ": no IK solution within " + (s.status == IKStatus::OutsideLimits ? "the joint limits" : "reach"));
      return false;
    }
    const int config = configIndex(s.config);
    Eigen::Index j = 0;
    const double step = (s.q - path.back()).cwiseAbs().maxCoeff(&j);
    if (config != cand.config_index) {
      // Say why the configuration was left: it ends there (reach, limits) or another one is nearer.
      const IKSolution own = ik(c.arm, T, opt).solutions[static_cast<std::size_t>(cand.config_index)];
      const std::string why = own.status == IKStatus::OutsideLimits ? " (configuration " +
                                  std::to_string(cand.config_index) + " is outside the joint limits there)"
                              : own.status == IKStatus::Unreachable ? " (configuration " +
                                  std::to_string(cand.config_index) + " is out of reach there)"
                                                                    : "";
      reject(cand, GraspReason::ApproachBranchChange,
             sampleName(k, n) + ": the IK configuration changes from " + std::to_string(cand.config_index) + " to " +
                 std::to_string(config) + why);
      return false;
    }
    if (step > c.settings.max_joint_step) {
      reject(cand, GraspReason::ApproachBranchChange,
             sampleName(k, n) + ": joint " + std::to_string(j + 1) + " jumps " + num(step) +
                 " rad (max_joint_step " + num(c.settings.max_joint_step) + ")");
      return false;
    }
    path.push_back(s.q);
    flange.push_back(T);
  }
  return true;
}

/// Checks one candidate whose pre-grasp IK solution is `sol`; on success cand.reason is Ok.
void checkCandidate(const Cell& c, const Grasp& g, const IKSolution& sol, GraspCandidate& cand,
                    std::vector<Vector6d>& path) {
  if (sol.status == IKStatus::OutsideLimits)
    return reject(cand, GraspReason::OutsideLimits,
                  "the pre-grasp: " + jointsOutside(c, cand.T_base_flange_pregrasp, cand.config_index) +
                      "outside the joint limits for every multiple of 2 pi");
  if (!sol.ok())
    return reject(cand, GraspReason::Unreachable,
                  std::string("the pre-grasp: no IK solution in this configuration (") +
                      (sol.unreachable_step == IKStep::Shoulder ? "shoulder: wrist within d4 of the first axis"
                       : sol.unreachable_step == IKStep::FkCheck ? "forward-kinematics check"
                                                                 : "elbow: wrist out of the arm's reach") + ")");
  cand.q_pregrasp = nearestMultiple(c, sol.q);
  // The pre-grasp first: most rejections are decided there, before the approach is followed.
  if (const std::string t = tableProblem(c, cand.q_pregrasp, cand.T_base_flange_pregrasp); !t.empty())
    return reject(cand, GraspReason::BelowTable, "the pre-grasp: " + t);
  if (const std::string s = singularity(c, cand.q_pregrasp); !s.empty())
    return reject(cand, GraspReason::NearSingularity, "the pre-grasp: " + s);
  const double n_samples = std::ceil(g.pre_grasp_distance / c.settings.approach_step - 1e-9);
  const int n = std::max(1, static_cast<int>(n_samples));
  std::vector<Eigen::Isometry3d> flange;
  if (!followApproach(c, g, cand, n, path, flange)) return;
  for (int k = 0; k <= n; ++k) {  // the FK check of every joint target, then table and singularities
    const double e = fkError(c, path[static_cast<std::size_t>(k)], flange[static_cast<std::size_t>(k)]);
    if (!(e <= kFkTolerance))
      return reject(cand, GraspReason::Unreachable,
                    sampleName(k, n) + ": forward kinematics misses the flange pose by " + num(e) + " (> 1e-9)");
  }
  for (int k = 1; k <= n; ++k) {
    const std::string t = tableProblem(c, path[static_cast<std::size_t>(k)], flange[static_cast<std::size_t>(k)]);
    if (!t.empty()) return reject(cand, GraspReason::BelowTable, sampleName(k, n) + ": " + t);
  }
  for (int k = 1; k <= n; ++k) {
    const std::string s = singularity(c, path[static_cast<std::size_t>(k)]);
    if (!s.empty()) return reject(cand, GraspReason::NearSingularity, sampleName(k, n) + ": " + s);
  }
  cand.q_grasp = path.back();
  cand.cost = weightedMotion(c, c.q_current, cand.q_pregrasp);
  for (std::size_t k = 1; k < path.size(); ++k) cand.cost += weightedMotion(c, path[k - 1], path[k]);
  reject(cand, GraspReason::Ok, "");
}

std::string summary(const GraspPlanResult& plan, const std::vector<Grasp>& grasps) {
  std::array<int, 6> count{};
  for (const GraspCandidate& cand : plan.candidates) ++count[static_cast<std::size_t>(cand.reason)];
  const int total = static_cast<int>(plan.candidates.size());
  if (plan.found) {
    const GraspCandidate& ch = plan.candidates[static_cast<std::size_t>(plan.chosen)];
    return "grasp '" + grasps[static_cast<std::size_t>(ch.grasp_index)].name + "' (grasp " +
           std::to_string(ch.grasp_index) + ", symmetry copy " + std::to_string(ch.symmetry_index) +
           ", IK configuration " + std::to_string(ch.config_index) + "), joint motion " + num(ch.cost) + " rad; " +
           std::to_string(count[0]) + " of " + std::to_string(total) + " candidates feasible";
  }
  if (count[1] == total)
    return "out of reach: every candidate unreachable (" + std::to_string(total) + " candidates)";
  static const char* names[] = {"ok", "unreachable", "outside the joint limits", "near a singularity",
                                "below the table", "approach branch change"};
  std::string out = "no feasible grasp among " + std::to_string(total) + " candidates:";
  for (std::size_t r = 1; r < count.size(); ++r)
    if (count[r]) out += std::string(out.back() == ':' ? " " : ", ") + std::to_string(count[r]) + " " + names[r];
  return out;
}

Cell makeCell(const Robot& robot, const Gripper& gripper, const Eigen::Vector4d& table_plane,
              const Vector6d& q_current, const GraspPlannerSettings& settings) {
  Cell c;
  c.arm = robot;
  c.arm.T_flange_tool = Eigen::Isometry3d::Identity();
  c.geometry = robot.geometry();
  if (c.geometry == ArmGeometry::Unsupported)
    throw std::invalid_argument("robot '" + robot.name + "': its DH table is not one the analytic IK covers");
  requireRigid(robot.T_base_dh0.matrix(), "robot.T_base_dh0");
  gripper.validate();
  settings.validate();
  if (!table_plane.allFinite() || std::abs(table_plane.head<3>().norm() - 1) > kUnitTolerance)
    throw std::invalid_argument("table_plane: (n, d) must be finite with a unit normal n, got |n| = " +
                                num(table_plane.head<3>().norm()));
  if (!q_current.allFinite() || (q_current.array().abs() > 1e6).any())
    throw std::invalid_argument("q_current must be 6 finite joint values within +-1e6 rad");
  c.gripper = gripper;
  c.n = table_plane.head<3>();
  c.d = table_plane[3];
  c.q_current = q_current;
  c.settings = settings;
  c.ik.respect_limits = settings.respect_limits;
  c.ik.q_free = q_current;
  return c;
}

}  // namespace

GraspPlanResult planGrasp(const Robot& robot, const Eigen::Isometry3d& T_base_model,
                          const std::vector<Grasp>& grasps, const PartSymmetry& symmetry, const Gripper& gripper,
                          const Eigen::Vector4d& table_plane, const Vector6d& q_current,
                          const GraspPlannerSettings& settings) {
  const Cell c = makeCell(robot, gripper, table_plane, q_current, settings);
  requireRigid(T_base_model.matrix(), "T_base_model");
  if (grasps.empty()) throw std::invalid_argument("grasps: the grasp list is empty");
  for (std::size_t i = 0; i < grasps.size(); ++i) {
    grasps[i].validate("grasps[" + std::to_string(i) + "]");
    if (grasps[i].pre_grasp_distance / settings.approach_step > kMaxApproachSamples)
      throw std::invalid_argument("grasps[" + std::to_string(i) + "].pre_grasp_distance / settings.approach_step "
                                  "exceeds 100000 approach samples");
  }
  symmetry.validate();
  const std::size_t copies_per_grasp =
      symmetry.order == 0 ? static_cast<std::size_t>(settings.continuous_symmetry_steps) : static_cast<std::size_t>(std::max(1, symmetry.order));
  // About 0.1 ms per candidate: this bounds a call to seconds, never an apparent hang.
  if (grasps.size() * copies_per_grasp > kMaxGraspCopies)
    throw std::invalid_argument("grasps: " + std::to_string(grasps.size()) + " grasps x " +
                                std::to_string(copies_per_grasp) + " symmetry copies exceeds " +
                                std::to_string(kMaxGraspCopies) + " (8 IK candidates each)");
  const Eigen::Isometry3d T_tcp_flange = gripper.T_flange_tcp.inverse();
  GraspPlanResult plan;
  std::vector<Vector6d> path;
  for (std::size_t gi = 0; gi < grasps.size(); ++gi) {
    const std::vector<Grasp> copies = equivalentGrasps(grasps[gi], symmetry, settings.continuous_symmetry_steps);
    for (std::size_t si = 0; si < copies.size(); ++si) {
      const Grasp& g = copies[si];
      GraspCandidate base;
      base.grasp_index = static_cast<int>(gi);
      base.symmetry_index = static_cast<int>(si);
      base.T_base_tcp_grasp = T_base_model * g.T_model_grasp;
      base.T_base_tcp_pregrasp = T_base_model * g.preGrasp();
      base.T_base_flange_grasp = base.T_base_tcp_grasp * T_tcp_flange;
      base.T_base_flange_pregrasp = base.T_base_tcp_pregrasp * T_tcp_flange;
      const IKResult r = ik(c.arm, base.T_base_flange_pregrasp, c.ik);
      for (int k = 0; k < 8; ++k) {
        GraspCandidate cand = base;
        cand.config_index = k;
        checkCandidate(c, g, r.solutions[static_cast<std::size_t>(k)], cand, path);
        if (cand.reason == GraspReason::Ok &&
            (plan.chosen < 0 || cand.cost < plan.candidates[static_cast<std::size_t>(plan.chosen)].cost)) {
          plan.chosen = static_cast<int>(plan.candidates.size());
          plan.approach_q = path;
        }
        plan.candidates.push_back(std::move(cand));
      }
    }
  }
  plan.found = plan.chosen >= 0;
  plan.message = summary(plan, grasps);
  return plan;
}

}  // namespace scanalign

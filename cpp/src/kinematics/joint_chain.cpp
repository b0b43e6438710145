// Robots from serial chains of joint axes (kinematics/joint_chain.hpp): DH frames through the
// joint lines (Denavit and Hartenberg 1955, common normals of consecutive axes), the x-axis
// sign search for an analytic layout (Kleppe, PhD thesis, NTNU 2018, Paper 1 §4-5) and the
// joint-sign hint.
#include "scanalign/kinematics/joint_chain.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>
#include <Eigen/Geometry>  // cross()

#include "scanalign/common/rigid.hpp"

namespace scanalign {

namespace {

using Eigen::Vector3d;
using Table = Eigen::Matrix<double, 6, 4>;  ///< rows [a (m), alpha (rad), d (m), theta_offset (rad)]

/// The six joint lines (point p_i, unit direction u_i) in the base frame at q = 0, with the
/// joint signs applied to the directions, and the tip's origin.
struct Lines {
  std::array<Vector3d, 6> p, u;
  Vector3d tip;
};

Lines linesOf(const JointChain& chain, const Vector6d& signs) {
  Lines l;
  Eigen::Isometry3d F = Eigen::Isometry3d::Identity();
  for (std::size_t i = 0; i < 6; ++i) {
    F = F * chain.origins[i];
    l.p[i] = F.translation();
    l.u[i] = signs[static_cast<int>(i)] * (F.linear() * (chain.axes[i] / chain.axes[i].norm()));
  }
  l.tip = (F * chain.T_joint6_tip).translation();
  return l;
}

/// The point of the line (p, u) nearest to x.
Vector3d foot(const Vector3d& x, const Vector3d& p, const Vector3d& u) { return p + u * (x - p).dot(u); }

/// DH frames through the joint lines with x-axis signs flips[0..4] (frames 1..5); see the
/// header for the choices. Returns the table and T_base_dh0.
Table dhTable(const Lines& l, const std::array<double, 5>& flips, double tol, Eigen::Isometry3d& T_base_dh0) {
  std::array<Vector3d, 7> z, o, x;
  for (std::size_t i = 0; i < 6; ++i) z[i] = l.u[i];
  z[6] = l.u[5];
  o[0] = foot(Vector3d::Zero(), l.p[0], l.u[0]);
  for (std::size_t i = 1; i < 6; ++i) {
    const Vector3d &pa = l.p[i - 1], &ua = l.u[i - 1], &pb = l.p[i], &ub = l.u[i];
    const Vector3d c = ua.cross(ub);
    Vector3d n, B;
    if (c.norm() > tol) {  // skew or intersecting: the unique common normal
      const Vector3d w = pa - pb;
      const double b = ua.dot(ub);
      const double t = (ub.dot(w) - b * ua.dot(w)) / (1.0 - b * b);  // the nearest point on axis i+1
      n = c / c.norm();
      B = pb + t * ub;
    } else {
      B = foot(o[i - 1], pb, ub);
      n = B - o[i - 1];
      n = n - ub * n.dot(ub);
      if (n.norm() > tol) {
        n = n / n.norm();
        if (i > 1 && n.dot(x[i - 1]) < 0) n = -n;
      } else if (i > 1) {  // collinear axes: any normal, keep the previous x
        n = x[i - 1];
      } else {
        n = ua.cross(std::abs(ua[0]) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY());
        n = n / n.norm();
      }
    }
    x[i] = flips[i - 1] * n;
    o[i] = B;
  }
  x[0] = x[1];
  x[6] = x[5];
  o[6] = foot(l.tip, l.p[5], l.u[5]);
  Table dh;
  for (std::size_t i = 1; i < 7; ++i) {
    const Vector3d step = o[i] - o[i - 1];
    dh.row(static_cast<int>(i - 1)) << step.dot(x[i]), std::atan2(z[i - 1].cross(z[i]).dot(x[i]), z[i - 1].dot(z[i])),
        step.dot(z[i - 1]), std::atan2(x[i - 1].cross(x[i]).dot(z[i - 1]), x[i - 1].dot(x[i]));
  }
  T_base_dh0 = Eigen::Isometry3d::Identity();
  T_base_dh0.linear().col(0) = x[0];
  T_base_dh0.linear().col(1) = z[0].cross(x[0]);
  T_base_dh0.linear().col(2) = z[0];
  T_base_dh0.translation() = o[0];
  return dh;
}

/// dh with the values within tol of what the layouts test exactly (alpha a multiple of pi/2,
/// a and d zero) set to them.
Table snapped(Table dh, double tol) {
  for (int i = 0; i < 6; ++i) {
    const double quarter = std::nearbyint(dh(i, 1) / (M_PI / 2)) * (M_PI / 2);
    if (std::abs(dh(i, 1) - quarter) <= tol) dh(i, 1) = quarter;
    for (int c : {0, 2})
      if (std::abs(dh(i, c)) <= tol) dh(i, c) = 0.0;
  }
  return dh;
}

/// The Robot of a DH table, refused as Robot.from_dh refuses it (the message names the column).
Robot robotOf(const Table& dh, const std::array<Eigen::Vector2d, 6>& limits, const std::string& name,
              const Eigen::Isometry3d& T_base_dh0) {
  static const char* const kColumns[] = {"a", "alpha", "d", "theta_offset"};
  for (int c = 0; c < 4; ++c)
    if (!dh.col(c).allFinite()) throw std::invalid_argument(std::string(kColumns[c]) + ": non-finite values");
  for (int c : {0, 2})
    if (dh.col(c).cwiseAbs().maxCoeff() > 1e6)
      throw std::invalid_argument(std::string(kColumns[c]) + ": link lengths must lie within +-1e6 m");
  requireRigid(T_base_dh0.matrix(), "T_base_dh0");
  Robot r;
  r.name = name;
  for (std::size_t i = 0; i < 6; ++i) {
    const int k = static_cast<int>(i);
    DHJoint& j = r.joints[i];
    j.a = dh(k, 0), j.alpha = dh(k, 1), j.d = dh(k, 2), j.theta_offset = dh(k, 3);
    j.q_min = limits[i][0], j.q_max = limits[i][1];
  }
  r.T_base_dh0 = T_base_dh0;
  return r;
}

/// The Robot (no tool yet) over the 32 x-sign choices: an analytic layout with the smallest
/// sum of |theta offsets| if one exists, else the table with all signs +1 (forward kinematics
/// only). Throws std::invalid_argument for a table no Robot can hold.
Robot bestRobot(const Lines& l, const std::array<Eigen::Vector2d, 6>& limits, const std::string& name, double tol) {
  std::optional<Robot> best, fallback;
  double best_cost = 0;
  for (int k = 0; k < 32; ++k) {  // flips (+1, ..., +1), (+1, ..., -1), ..., (-1, ..., -1)
    std::array<double, 5> flips;
    for (int j = 0; j < 5; ++j) flips[static_cast<std::size_t>(j)] = (k >> (4 - j)) & 1 ? -1.0 : 1.0;
    Eigen::Isometry3d T0;
    const Table raw = dhTable(l, flips, tol, T0);
    for (const Table& dh : {raw, snapped(raw, tol)}) {  // the exact table first; rounded only if that makes it analytic
      Robot r = robotOf(dh, limits, name, T0);
      if (!fallback) fallback = r;
      if (r.geometry() != ArmGeometry::Unsupported) {
        const double cost = dh.col(3).cwiseAbs().sum();
        if (!best || cost < best_cost - 1e-12) best = r, best_cost = cost;
        break;
      }
    }
  }
  return best ? *best : *fallback;
}

/// The Robot without tool for joint signs s: the DH z axes along s_i times the chain's axes,
/// limits mirrored where s_i = -1.
Robot buildWithSigns(const JointChain& chain, const Vector6d& s, const JointChainSettings& settings, double tol) {
  std::array<Eigen::Vector2d, 6> limits = chain.limits;
  for (std::size_t i = 0; i < 6; ++i)
    if (s[static_cast<int>(i)] < 0) limits[i] = Eigen::Vector2d(-chain.limits[i][1], -chain.limits[i][0]);
  try {
    return bestRobot(linesOf(chain, s), limits, settings.name, tol);
  } catch (const std::invalid_argument& e) {  // e.g. nearly parallel axes giving huge offsets
    char now[32];
    std::snprintf(now, sizeof now, "%g", settings.tolerance);
    throw std::invalid_argument(settings.what + " gives no usable DH table (" + e.what() +
                                "): nearly parallel joint axes put their common normal far away; a tolerance above "
                                "their angle (now " + now + ") treats them as parallel");
  }
}

std::string tableText(const Robot& r) {
  // Each value rounded to 6 decimals, -0 shown as 0, 6 significant digits.
  std::string out;
  for (std::size_t i = 0; i < 6; ++i) {
    const DHJoint& j = r.joints[i];
    out += i ? "; " : "";
    const double v[4] = {j.a, j.alpha, j.d, j.theta_offset};
    for (int c = 0; c < 4; ++c) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.6g", std::nearbyint(v[c] * 1e6) / 1e6 + 0.0);
      out += std::string(c ? ", " : "") + buf;
    }
  }
  return out;
}

/// "; with joint_signs=(1, 1, 1, -1, 1, 1) (...) it is a '...' arm" for the first sign choice
/// (fewest reversed joints, then in the order of the sign tuples) that is analytic, or "".
std::string signHint(const JointChain& chain, const JointChainSettings& settings, double tol) {
  std::vector<int> order;  // the 63 choices other than all +1: bit j set = joint j+1 reversed
  for (int k = 1; k < 64; ++k) order.push_back(k);
  const auto reversed = [](int k) {
    int n = 0;
    for (int j = 0; j < 6; ++j) n += (k >> j) & 1;
    return n;
  };
  // Stable by count; within a count in the order of the tuples (+1, ..., +1), (+1, ..., -1), ...
  const auto tupleRank = [](int k) {
    int r = 0;
    for (int j = 0; j < 6; ++j) r = 2 * r + ((k >> j) & 1);
    return r;
  };
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return reversed(a) != reversed(b) ? reversed(a) < reversed(b) : tupleRank(a) < tupleRank(b);
  });
  for (int k : order) {
    Vector6d s;
    for (int j = 0; j < 6; ++j) s[j] = (k >> j) & 1 ? -1.0 : 1.0;
    const ArmGeometry g = buildWithSigns(chain, s, settings, tol).geometry();
    if (g == ArmGeometry::Unsupported) continue;
    std::string t;
    for (int j = 0; j < 6; ++j) t += std::string(j ? ", " : "") + (s[j] > 0 ? "1" : "-1");
    return "; with joint_signs=(" + t + ") (q = joint_signs * q_chain) it is a '" + toString(g) + "' arm";
  }
  return "";
}

}  // namespace

void JointChain::validate() const {
  for (std::size_t i = 0; i < 6; ++i) {
    const std::string at = "[" + std::to_string(i) + "]";
    requireRigid(origins[i].matrix(), "origins" + at);
    if (!axes[i].allFinite() || !(axes[i].norm() > 1e-12))
      throw std::invalid_argument("axes" + at + ": expected a finite non-zero 3-vector");
    if (std::isnan(limits[i][0]) || std::isnan(limits[i][1]) || limits[i][0] > limits[i][1])
      throw std::invalid_argument("limits" + at + ": expected [q_min, q_max] with q_min <= q_max (no NaN)");
  }
  requireRigid(T_joint6_tip.matrix(), "T_joint6_tip");
}

Eigen::Isometry3d JointChain::forward(const Vector6d& q) const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (std::size_t i = 0; i < 6; ++i)
    T = T * origins[i] * Eigen::AngleAxisd(q[static_cast<int>(i)], axes[i] / axes[i].norm());
  return T * T_joint6_tip;
}

void JointChainSettings::validate() const {
  if (joint_signs && !(joint_signs->cwiseAbs().array() == 1.0).all())
    throw std::invalid_argument("joint_signs: expected 6 values of +1 or -1");
  if (!(std::isfinite(tolerance) && tolerance >= 0 && tolerance < 1e-3))
    throw std::invalid_argument("tolerance: expected 0 <= tolerance < 1e-3, got " + std::to_string(tolerance));
}

Robot Robot::fromJointChain(const JointChain& chain, const JointChainSettings& settings) {
  settings.validate();
  chain.validate();
  const double tol = std::max(settings.tolerance, 1e-12);  // below ~1e-12 rounding alone would break parallel axes
  const Vector6d signs = settings.joint_signs.value_or(Vector6d::Ones());
  Robot robot = buildWithSigns(chain, signs, settings, tol);
  if (robot.geometry() == ArmGeometry::Unsupported && !settings.fk_only) {
    const std::string hint = settings.joint_signs ? "" : signHint(chain, settings, tol);
    throw std::invalid_argument(settings.what + " is none of the layouts the analytic IK solves, " +
                                analyticLayoutsText() + "; its DH table [a (m), alpha, d (m), theta_offset] is [" +
                                tableText(robot) + "]" + hint +
                                ". Pass fk_only=True for a Robot with forward kinematics only");
  }
  // The tip in the flange frame, from the Robot's own flange pose: exact at q = 0 even after
  // the rounding of near-layout values.
  const Eigen::Isometry3d T_tip0 = chain.forward(Vector6d::Zero());
  const Eigen::Isometry3d F6 = robot.forwardFlange(Vector6d::Zero());
  Eigen::Isometry3d T_flange_tip = Eigen::Isometry3d::Identity();
  T_flange_tip.linear() = F6.linear().transpose() * T_tip0.linear();
  T_flange_tip.translation() = F6.linear().transpose() * (T_tip0.translation() - F6.translation());
  requireRigid(T_flange_tip.matrix(), "T_flange_tool");
  robot.T_flange_tool = T_flange_tip;
  // Checked against the chain itself: a wrong frame shows here, not later in a cell.
  std::mt19937_64 rng(0);
  for (int n = 0; n < 9; ++n) {
    Vector6d q = Vector6d::Zero();
    for (int i = 0; n > 0 && i < 6; ++i) {
      const DHJoint& j = robot.joints[static_cast<std::size_t>(i)];
      const double lo = std::clamp(j.q_min, -M_PI, M_PI), hi = std::clamp(j.q_max, -M_PI, M_PI);
      q[i] = std::uniform_real_distribution<double>(lo, hi)(rng);
    }
    const Vector6d q_chain = signs.cwiseProduct(q);
    const double err = (robot.forward(q).matrix() - chain.forward(q_chain).matrix()).cwiseAbs().maxCoeff();
    if (!(err <= 1e-9 + 100 * tol)) {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%.3g", err);
      std::string qs;
      for (int i = 0; i < 6; ++i) qs += std::string(i ? ", " : "") + std::to_string(q[i]);
      throw std::runtime_error(settings.what + ": its DH model departs from the chain by " + buf + " m at q = (" + qs +
                               ")");
    }
  }
  return robot;
}

}  // namespace scanalign

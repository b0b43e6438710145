// DH robots and forward kinematics (Kleppe, PhD thesis, NTNU 2018, Paper 1 eqs. (1)-(3)).
#include "scanalign/kinematics/robot.hpp"
#include "scanalign/common/threads.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <omp.h>

namespace scanalign {

namespace {

constexpr double kPi = M_PI;
constexpr double deg(double v) { return v * kPi / 180.0; }

bool near(double x, double y) { return std::abs(x - y) <= 1e-12 * std::max(1.0, std::abs(y)); }

/// Rot_z(theta) Trans_z(d) Trans_x(a) Rot_x(alpha) (P1 (1)), written out.
inline void dhTransform(const DHJoint& j, double q, Eigen::Matrix3d& R, Eigen::Vector3d& t) {
  const double th = q + j.theta_offset;
  const double ct = std::cos(th), st = std::sin(th);
  const double ca = std::cos(j.alpha), sa = std::sin(j.alpha);
  R << ct, -st * ca, st * sa,  //
      st, ct * ca, -ct * sa,   //
      0, sa, ca;
  t << j.a * ct, j.a * st, j.d;
}

Robot makeUR(const char* name, double d1, double a2, double a3, double d4, double d5, double d6, double limit) {
  Robot r;
  r.name = name;
  const double alpha[6] = {kPi / 2, 0, 0, kPi / 2, -kPi / 2, 0};
  const double a[6] = {0, a2, a3, 0, 0, 0};
  const double d[6] = {d1, 0, 0, d4, d5, d6};
  for (int i = 0; i < 6; ++i) {
    r.joints[i].a = a[i];
    r.joints[i].alpha = alpha[i];
    r.joints[i].d = d[i];
    r.joints[i].q_min = -limit;
    r.joints[i].q_max = limit;
  }
  return r;
}

}  // namespace

const char* toString(ArmGeometry g) {
  switch (g) {
    case ArmGeometry::SphericalWrist: return "spherical_wrist";
    case ArmGeometry::UniversalRobots: return "universal_robots";
    default: return "unsupported";
  }
}

const char* analyticLayoutsText() {
  return "'spherical_wrist' (KUKA type: alpha = (-pi/2, 0, -pi/2, pi/2, -pi/2, 0), d2 = d3 = d5 = 0, a4 = a5 = a6 = 0, "
         "a2 > 0, d4 > 0) and 'universal_robots' (alpha = (pi/2, 0, 0, pi/2, -pi/2, 0), a1 = a4 = a5 = a6 = 0, "
         "d2 = d3 = 0, a2, a3 != 0, d4, d5 > 0)";
}

ArmGeometry Robot::geometry() const {
  const auto& J = joints;
  for (const auto& j : J)
    if (!std::isfinite(j.a) || !std::isfinite(j.alpha) || !std::isfinite(j.d) || !std::isfinite(j.theta_offset))
      return ArmGeometry::Unsupported;
  // KUKA-type (P1 §4): alpha = (-pi/2, 0, -pi/2, pi/2, -pi/2, 0).
  if (near(J[0].alpha, -kPi / 2) && near(J[1].alpha, 0) && near(J[2].alpha, -kPi / 2) && near(J[3].alpha, kPi / 2) &&
      near(J[4].alpha, -kPi / 2) && near(J[5].alpha, 0) && near(J[1].d, 0) && near(J[2].d, 0) && near(J[4].d, 0) &&
      near(J[3].a, 0) && near(J[4].a, 0) && near(J[5].a, 0) && J[1].a > 0 && J[3].d > 0)
    return ArmGeometry::SphericalWrist;
  // UR-type (P1 §5): alpha = (pi/2, 0, 0, pi/2, -pi/2, 0).
  if (near(J[0].alpha, kPi / 2) && near(J[1].alpha, 0) && near(J[2].alpha, 0) && near(J[3].alpha, kPi / 2) &&
      near(J[4].alpha, -kPi / 2) && near(J[5].alpha, 0) && near(J[0].a, 0) && near(J[3].a, 0) && near(J[4].a, 0) &&
      near(J[5].a, 0) && near(J[1].d, 0) && near(J[2].d, 0) && J[1].a != 0 && J[2].a != 0 && J[3].d > 0 &&
      J[4].d > 0)
    return ArmGeometry::UniversalRobots;
  return ArmGeometry::Unsupported;
}

Eigen::Isometry3d Robot::link(int i, double q) const {
  if (i < 1 || i > 6) throw std::out_of_range("Robot::link: i must be 1..6");
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  dhTransform(joints[static_cast<std::size_t>(i - 1)], q, R, t);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}

Eigen::Isometry3d Robot::forwardFlange(const Vector6d& q) const {
  // Accumulate rotation and translation separately: 6 x (3x3 product + 3x3-vector).
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity(), Ri;
  Eigen::Vector3d t = Eigen::Vector3d::Zero(), ti;
  for (int i = 0; i < 6; ++i) {
    dhTransform(joints[static_cast<std::size_t>(i)], q[i], Ri, ti);
    t += R * ti;
    R = R * Ri;
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T_base_dh0 * T;
}

Eigen::Isometry3d Robot::forward(const Vector6d& q) const { return forwardFlange(q) * T_flange_tool; }

std::array<Eigen::Isometry3d, 7> Robot::jointFrames(const Vector6d& q) const {
  std::array<Eigen::Isometry3d, 7> F;
  F[0] = Eigen::Isometry3d::Identity();
  for (int i = 1; i <= 6; ++i) F[static_cast<std::size_t>(i)] = F[static_cast<std::size_t>(i - 1)] * link(i, q[i - 1]);
  return F;
}

std::array<Eigen::Vector3d, 7> Robot::jointPositions(const Vector6d& q) const {
  // As forwardFlange, keeping the translation after each link.
  std::array<Eigen::Vector3d, 7> P;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity(), Ri;
  Eigen::Vector3d t = Eigen::Vector3d::Zero(), ti;
  P[0] = T_base_dh0 * t;
  for (int i = 0; i < 6; ++i) {
    dhTransform(joints[static_cast<std::size_t>(i)], q[i], Ri, ti);
    t += R * ti;
    R = R * Ri;
    P[static_cast<std::size_t>(i + 1)] = T_base_dh0 * t;
  }
  return P;
}

void Robot::jointPositionsBatch(const double* q, std::size_t n, double* out, bool tcp, int num_threads) const {
  const long long N = static_cast<long long>(n);
  const int rows = tcp ? 8 : 7;
#pragma omp parallel for schedule(static) num_threads(resolveThreads(num_threads)) if (num_threads != 1 && N > 256)
  for (long long i = 0; i < N; ++i) {
    const Eigen::Map<const Vector6d> qi(q + 6 * i);
    const std::array<Eigen::Vector3d, 7> P = jointPositions(qi);
    double* o = out + 3 * rows * i;
    for (const Eigen::Vector3d& p : P) o = std::copy(p.data(), p.data() + 3, o);
    if (tcp) {
      const Eigen::Vector3d p = forward(qi).translation();
      std::copy(p.data(), p.data() + 3, o);
    }
  }
}

void Robot::forwardBatch(const double* q, std::size_t n, double* out, int num_threads) const {
  const long long N = static_cast<long long>(n);
#pragma omp parallel for schedule(static) num_threads(resolveThreads(num_threads)) if (num_threads != 1 && N > 256)
  for (long long i = 0; i < N; ++i) {
    const Eigen::Map<const Vector6d> qi(q + 6 * i);
    const Eigen::Matrix4d T = forward(qi).matrix();
    Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(out + 16 * i) = T;
  }
}

bool Robot::withinLimits(const Vector6d& q, double tol) const {
  for (int i = 0; i < 6; ++i)
    if (!(q[i] >= joints[static_cast<std::size_t>(i)].q_min - tol && q[i] <= joints[static_cast<std::size_t>(i)].q_max + tol))
      return false;
  return true;
}

// ---------------------------------------------------------------------------
// Built-in models
// ---------------------------------------------------------------------------

Robot Robot::kukaKR6R900sixx() {
  // DH of the thesis authors' CluCalc code (the printed thesis Table 1 is garbled):
  // (d, a, alpha) = (400, 25, -pi/2), (0, 455, 0), (0, 35, -pi/2), (420, 0, pi/2),
  // (0, 0, -pi/2), (80, 0, 0) mm, with theta3 = q3 - pi/2, so that q equals KUKA's axis
  // values A1..A6 in the home pose q = (0, -90°, 90°, 0, 0, 0), where the flange is at
  // (525, 0, 890) mm pointing along +x (thesis Table 1). These are KUKA's published link
  // dimensions of the KR6 R900 sixx: base height 400, A1-A2 offset 25, upper arm 455,
  // A3-A4 offset 35, forearm 420, wrist to flange 80 mm.
  // Limits: KUKA KR AGILUS sixx data sheet (KR 6 R900 sixx): A1 ±170°, A2 -190°..+45°,
  // A3 -120°..+156°, A4 ±185°, A5 ±120°, A6 ±350°. A2 and A3 turn in the sense of the DH
  // joints here (A2 = 0 is the upper arm horizontal, forward); A1, A4, A5 and A6 have
  // symmetric limits, so their sense does not change the ranges.
  Robot r;
  r.name = "kr6_r900_sixx";
  const double d[6] = {0.400, 0, 0, 0.420, 0, 0.080};
  const double a[6] = {0.025, 0.455, 0.035, 0, 0, 0};
  const double alpha[6] = {-kPi / 2, 0, -kPi / 2, kPi / 2, -kPi / 2, 0};
  const double lo[6] = {deg(-170), deg(-190), deg(-120), deg(-185), deg(-120), deg(-350)};
  const double hi[6] = {deg(170), deg(45), deg(156), deg(185), deg(120), deg(350)};
  for (int i = 0; i < 6; ++i) {
    r.joints[i].d = d[i];
    r.joints[i].a = a[i];
    r.joints[i].alpha = alpha[i];
    r.joints[i].q_min = lo[i];
    r.joints[i].q_max = hi[i];
  }
  r.joints[2].theta_offset = -kPi / 2;
  return r;
}

// Universal Robots' published DH tables ("DH parameters for calculations of kinematics and
// dynamics", Universal Robots support article), metres; alpha = (pi/2, 0, 0, pi/2, -pi/2, 0),
// no theta offsets, so q equals the joint angles the controller shows. DH frame 0 is UR's
// "base" frame; ROS's base_link is rotated by pi about z from it. Joint limits ±360° for
// every joint (UR data sheets); the UR3 / UR3e wrist 3 turns without limit and is given
// ±360° here too.
Robot Robot::ur5() { return makeUR("ur5", 0.089159, -0.425, -0.39225, 0.10915, 0.09465, 0.0823, 2 * kPi); }
Robot Robot::ur3() { return makeUR("ur3", 0.1519, -0.24365, -0.21325, 0.11235, 0.08535, 0.0819, 2 * kPi); }
Robot Robot::ur10() { return makeUR("ur10", 0.1273, -0.612, -0.5723, 0.163941, 0.1157, 0.0922, 2 * kPi); }
Robot Robot::ur3e() { return makeUR("ur3e", 0.15185, -0.24355, -0.2132, 0.13105, 0.08535, 0.0921, 2 * kPi); }
Robot Robot::ur5e() { return makeUR("ur5e", 0.1625, -0.425, -0.3922, 0.1333, 0.0997, 0.0996, 2 * kPi); }
Robot Robot::ur10e() { return makeUR("ur10e", 0.1807, -0.6127, -0.57155, 0.17415, 0.11985, 0.11655, 2 * kPi); }
// The thesis's Table 2 numbers (a mix of UR5 series 1 and 3): FK at
// q = 0 gives (-817.43, -191.45, -5.45) mm (thesis Table 2).
Robot Robot::ur5Thesis() { return makeUR("ur5_thesis", 0.0892, -0.425, -0.39243, 0.10915, 0.09465, 0.0823, 2 * kPi); }

Robot Robot::byName(const std::string& name) {
  if (name == "kr6_r900_sixx" || name == "agilus" || name == "kuka_kr6_r900_sixx") return kukaKR6R900sixx();
  if (name == "ur5") return ur5();
  if (name == "ur3") return ur3();
  if (name == "ur10") return ur10();
  if (name == "ur3e") return ur3e();
  if (name == "ur5e") return ur5e();
  if (name == "ur10e") return ur10e();
  if (name == "ur5_thesis") return ur5Thesis();
  throw std::invalid_argument("unknown robot '" + name +
                              "' (known: kr6_r900_sixx, agilus, ur3, ur5, ur10, ur3e, ur5e, ur10e, ur5_thesis)");
}

}  // namespace scanalign

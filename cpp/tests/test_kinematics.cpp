// Robot kinematics and CGA inverse kinematics (Kleppe, PhD thesis, NTNU 2018,
// Paper 1 §3-5, thesis Tables 1-2).
// Truth: analytic poses of the thesis, FK round trips, and the general G(4,1) multivector
// core (scanalign/cga), which computes each point pair as Q = (A* ^ B* ^ C*)* and its
// points (Q ± sqrt(Q²)) / (−e∞·Q) independently of the solver's closed forms.
#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Geometry>  // cross()

#include "scanalign/cga/multivector.hpp"
#include "scanalign/cga/objects.hpp"
#include "scanalign/kinematics/ik.hpp"
#include "scanalign/kinematics/robot.hpp"

using namespace scanalign;
namespace cga = scanalign::cga;

namespace {

Vector6d randomQ(std::mt19937& g, const Robot& r, bool inside_limits) {
  Vector6d q;
  for (int i = 0; i < 6; ++i) {
    const double lo = inside_limits ? r.joints[i].q_min : -M_PI;
    const double hi = inside_limits ? r.joints[i].q_max : M_PI;
    q[i] = std::uniform_real_distribution<double>(lo, hi)(g);
  }
  return q;
}

double poseError(const Eigen::Isometry3d& A, const Eigen::Isometry3d& B) {
  return (A.matrix() - B.matrix()).cwiseAbs().maxCoeff();
}

double angleDistance(const Vector6d& a, const Vector6d& b) {
  double d = 0;
  for (int i = 0; i < 6; ++i) d = std::max(d, std::abs(std::remainder(a[i] - b[i], 2 * M_PI)));
  return d;
}

/// The two points of the point pair (A ^ B ^ C)* of three dual vectors (5-vectors on
/// e1, e2, e3, e∞, e0), with the general multivector algebra: P± = (Q ± sqrt(Q²)) / (−e∞·Q)
/// (thesis (4.63)). Returns Q².
double multivectorPointPair(const cga::Vector5& A, const cga::Vector5& B, const cga::Vector5& C, Eigen::Vector3d& p,
                            Eigen::Vector3d& m) {
  const cga::Multivector T = cga::fromVector5(A).outer(cga::fromVector5(B)).outer(cga::fromVector5(C));
  const cga::Multivector Q = T.dual();
  const double Q2 = (Q * Q).scalar();
  const cga::Multivector den = -(cga::Multivector::eInf().inner(Q));
  const cga::Multivector inv = den.inverse();
  const double s = std::sqrt(std::max(Q2, 0.0));
  p = cga::down((Q + cga::Multivector(s)) * inv);
  m = cga::down((Q - cga::Multivector(s)) * inv);
  return Q2;
}
cga::Vector5 sphere5(const Eigen::Vector3d& c, double r2) {
  return (cga::Vector5() << c, 0.5 * (c.squaredNorm() - r2), 1.0).finished();
}
cga::Vector5 plane5(const Eigen::Vector3d& n, double delta) { return (cga::Vector5() << n, delta, 0.0).finished(); }

}  // namespace

TEST(Kinematics, Claim22AgilusHomePose) {
  const Robot r = Robot::kukaKR6R900sixx();
  EXPECT_EQ(r.geometry(), ArmGeometry::SphericalWrist);
  const Vector6d q = (Vector6d() << 0, -M_PI / 2, M_PI / 2, 0, 0, 0).finished();
  const Eigen::Isometry3d T = r.forward(q);
  EXPECT_NEAR((T.translation() - Eigen::Vector3d(0.525, 0, 0.890)).norm(), 0, 1e-12);
  Eigen::Matrix3d R;
  R << 0, 0, 1, 0, -1, 0, 1, 0, 0;  // thesis Table 1 home pose: a_e = +e1
  EXPECT_LE((T.linear() - R).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Kinematics, Claim23UR5ThesisNumbersAtZero) {
  const Robot r = Robot::ur5Thesis();
  EXPECT_EQ(r.geometry(), ArmGeometry::UniversalRobots);
  const Eigen::Vector3d p = r.forward(Vector6d::Zero()).translation();
  EXPECT_NEAR((p - Eigen::Vector3d(-0.81743, -0.19145, -0.00545)).norm(), 0, 1e-12);
  // UR's published UR5 table: a2 + a3 = -0.81725, -(d4 + d6) = -0.19145, d1 - d5 = -0.005491
  const Eigen::Vector3d p5 = Robot::ur5().forward(Vector6d::Zero()).translation();
  EXPECT_NEAR((p5 - Eigen::Vector3d(-0.81725, -0.19145, -0.005491)).norm(), 0, 1e-12);
}

TEST(Kinematics, ForwardMatchesJointFramesAndBatch) {
  std::mt19937 g(3);
  const Robot r = Robot::ur5();
  const Vector6d q = randomQ(g, r, true);
  const auto F = r.jointFrames(q);
  EXPECT_LE(poseError(F[6], r.forwardFlange(q)), 1e-14);
  double out[32];
  Vector6d qs[2] = {q, randomQ(g, r, true)};
  double qbuf[12];
  for (int k = 0; k < 2; ++k)
    for (int i = 0; i < 6; ++i) qbuf[6 * k + i] = qs[k][i];
  r.forwardBatch(qbuf, 2, out, 1);
  for (int k = 0; k < 2; ++k) {
    const Eigen::Matrix4d M = Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(out + 16 * k);
    EXPECT_LE((M - r.forward(qs[k]).matrix()).cwiseAbs().maxCoeff(), 0.0);
  }
}

TEST(Kinematics, UnknownRobotNameThrows) { EXPECT_THROW(Robot::byName("ur99"), std::invalid_argument); }

class IKRoundTrip : public ::testing::TestWithParam<const char*> {};

TEST_P(IKRoundTrip, EverySolutionReachesThePoseAndTheGeneratorIsFound) {
  const Robot r = Robot::byName(GetParam());
  std::mt19937 g(7);
  IKSettings o;
  o.respect_limits = false;
  int hist[9] = {0};
  const int N = 3000;
  for (int t = 0; t < N; ++t) {
    const Vector6d q = randomQ(g, r, false);
    const Eigen::Isometry3d T = r.forward(q);
    const IKResult res = ik(r, T, o);
    ASSERT_EQ(res.status, IKStatus::Ok);
    bool found = false;
    for (int k = 0; k < 8; ++k) {
      const IKSolution& s = res.solutions[k];
      EXPECT_EQ(configIndex(s.config), k);
      if (!s.ok()) {
        EXPECT_TRUE(std::isnan(s.q[0]));
        continue;
      }
      EXPECT_LE(poseError(r.forward(s.q), T), 1e-10) << GetParam() << " config " << k;
      // wrist label = sign(sin θ5) (ik.hpp)
      const double th5 = s.q[4] + r.joints[4].theta_offset;
      if (std::abs(std::sin(th5)) > 1e-9) EXPECT_EQ(s.config.wrist, std::sin(th5) > 0 ? 1 : -1);
      found = found || angleDistance(s.q, q) < 1e-7;
    }
    EXPECT_TRUE(found) << GetParam() << " pose " << t;
    ++hist[res.count()];
  }
  for (int c = 1; c <= 7; c += 2) EXPECT_EQ(hist[c], 0) << "odd solution count " << c;
  // Paper 1 §4-5: typically 8 distinct solutions (Agilus 899/1000; UR5 779/1000)
  // (UR3 / UR3e: about 68% here; their offsets are large relative to the links)
  EXPECT_GE(hist[8], (r.geometry() == ArmGeometry::SphericalWrist ? 0.85 : 0.60) * N);
}

INSTANTIATE_TEST_SUITE_P(Robots, IKRoundTrip,
                         ::testing::Values("kr6_r900_sixx", "ur5", "ur5_thesis", "ur3", "ur10", "ur3e", "ur5e",
                                           "ur10e"));

TEST(IK, BaseAndToolTransforms) {
  Robot r = Robot::ur5();
  r.T_base_dh0 = Eigen::Translation3d(0.3, -0.2, 0.75) * Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ());
  r.T_flange_tool = Eigen::Translation3d(0.01, 0.02, 0.15) * Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 1, 0).normalized());
  std::mt19937 g(11);
  for (int t = 0; t < 200; ++t) {
    const Vector6d q = randomQ(g, r, true);
    const Eigen::Isometry3d T = r.forward(q);
    const IKResult res = ik(r, T);
    bool found = false;
    for (const auto& s : res.solutions) {
      if (!s.ok()) continue;
      EXPECT_LE(poseError(r.forward(s.q), T), 1e-10);
      found = found || angleDistance(s.q, q) < 1e-7;
    }
    EXPECT_TRUE(found);
  }
}

TEST(IK, CgaMultivectorOracleAgilus) {
  // P1, P2 and P_wx of every configuration are points of the point pairs that the general
  // algebra computes from the thesis's spheres and planes (Paper 1 §4 with the corrections noted in ik.cpp).
  const Robot r = Robot::kukaKR6R900sixx();
  std::mt19937 g(5);
  const double d1 = 0.4, a1 = 0.025, a2 = 0.455, a3 = 0.035, d4 = 0.42;
  int checked = 0;
  IKSettings o;
  o.respect_limits = false;
  for (int t = 0; t < 40; ++t) {
    const Eigen::Isometry3d T = r.forward(randomQ(g, r, false));
    for (int k = 0; k < 8; ++k) {
      const IKConstruction c = ikConstruction(r, T, configFromIndex(k), o);
      if (!c.solution.ok()) continue;
      ASSERT_EQ(c.num_points, 5);
      const Eigen::Vector3d pw = c.points[1], P1 = c.points[2], P2 = c.points[3], Pwx = c.points[4];
      // Π_c = e0 ^ e3 ^ P_w ^ e∞ (25), normalised
      const Eigen::Vector3d n = Eigen::Vector3d::UnitZ().cross(Eigen::Vector3d(pw.x(), pw.y(), 0)).normalized();
      const cga::Vector5 Pic = plane5(n, 0);
      Eigen::Vector3d A, B;
      // (29): S0* = e0 − ½(d1² + a1²)e∞, Π1* = e3 + d1 e∞
      double Q2 = multivectorPointPair(sphere5(Eigen::Vector3d::Zero(), d1 * d1 + a1 * a1),
                                       plane5(Eigen::Vector3d::UnitZ(), d1), Pic, A, B);
      EXPECT_GT(Q2, 0);
      EXPECT_LE(std::min((P1 - A).norm(), (P1 - B).norm()), 1e-12);
      // (32)-(34)
      Q2 = multivectorPointPair(sphere5(P1, a2 * a2), sphere5(pw, d4 * d4 + a3 * a3), Pic, A, B);
      EXPECT_GE(Q2, -1e-15);
      EXPECT_EQ(Q2 > 0, c.elbow_discriminant > 0);
      EXPECT_LE(std::min((P2 - A).norm(), (P2 - B).norm()), 1e-9);
      // (35)-(37): horizon K* = P_w + (P_w·S2*)e∞
      const cga::Vector5 S2 = sphere5(P2, a3 * a3);
      const cga::Multivector Pw = cga::up(pw);
      const double pws2 = Pw.inner(cga::fromVector5(S2)).scalar();
      const cga::Vector5 K = cga::toVector5(Pw + cga::Multivector::eInf() * pws2);
      multivectorPointPair(K, S2, Pic, A, B);
      EXPECT_LE(std::min((Pwx - A).norm(), (Pwx - B).norm()), 1e-9);
      ++checked;
    }
  }
  EXPECT_GT(checked, 250);
}

TEST(IK, CgaMultivectorOracleUR5) {
  const Robot r = Robot::ur5();
  std::mt19937 g(6);
  const double d1 = 0.089159, a2 = -0.425, a3 = -0.39225, d4 = 0.10915, d5 = 0.09465;
  int checked = 0;
  IKSettings o;
  o.respect_limits = false;
  for (int t = 0; t < 40; ++t) {
    const Eigen::Isometry3d T = r.forward(randomQ(g, r, false));
    const Eigen::Vector3d a_e = T.linear().col(2);
    for (int k = 0; k < 8; ++k) {
      const IKConstruction c = ikConstruction(r, T, configFromIndex(k), o);
      if (!c.solution.ok()) continue;
      ASSERT_EQ(c.num_points, 7);
      const Eigen::Vector3d p5 = c.points[1], Pc = c.points[2], P4 = c.points[3], P3 = c.points[4], P2 = c.points[5];
      Eigen::Vector3d A, B;
      // (43)-(45): S_c* = P5 − ½d4² e∞, K0* = e0 + (e0·S_c*)e∞, horizontal plane through P5
      const cga::Vector5 Sc = sphere5(p5, d4 * d4);
      const cga::Multivector e0 = cga::Multivector::e0();
      const double e0sc = e0.inner(cga::fromVector5(Sc)).scalar();
      const cga::Vector5 K0 = cga::toVector5(e0 + cga::Multivector::eInf() * e0sc);
      const double Q2 = multivectorPointPair(Sc, K0, plane5(Eigen::Vector3d::UnitZ(), p5.z()), A, B);
      EXPECT_GT(Q2, 0);
      EXPECT_LE(std::min((Pc - A).norm(), (Pc - B).norm()), 1e-9);
      // (47)-(49): P4 from L45* ^ S5*
      const Eigen::Vector3d z1 = (p5 - Pc).normalized();
      multivectorPointPair(plane5(z1, z1.dot(p5)), plane5(a_e, a_e.dot(p5)), sphere5(p5, d5 * d5), A, B);
      EXPECT_LE(std::min((P4 - A).norm(), (P4 - B).norm()), 1e-9);
      // (50): P3 in Π_c at distance d4 from P4 along z1
      EXPECT_LE((P3 - (P4 - d4 * z1)).norm(), 1e-12);
      // (52)-(53)
      multivectorPointPair(sphere5(Eigen::Vector3d(0, 0, d1), a2 * a2), sphere5(P3, a3 * a3), plane5(z1, 0), A, B);
      EXPECT_LE(std::min((P2 - A).norm(), (P2 - B).norm()), 1e-9);
      // wrist label = sign of z4·(z1 × a_e), the geometric form used for unreachable elbows
      const double s5 = ((p5 - P4) / d5).dot(z1.cross(a_e));
      if (std::abs(s5) > 1e-9) EXPECT_EQ(c.solution.config.wrist, s5 > 0 ? 1 : -1);
      ++checked;
    }
  }
  EXPECT_GT(checked, 150);
}

TEST(IK, Claim25UnreachableGivesStatusNotAngles) {
  const Robot k = Robot::kukaKR6R900sixx();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() << 2.0, 0.0, 0.5;  // beyond the 0.9 m reach
  IKResult res = ik(k, T);
  EXPECT_EQ(res.status, IKStatus::Unreachable);
  for (const auto& s : res.solutions) {
    EXPECT_EQ(s.status, IKStatus::Unreachable);
    EXPECT_EQ(s.unreachable_step, IKStep::Elbow);
    EXPECT_TRUE(std::isnan(s.q[0]));
  }
  // UR: P5 within d4 of the first axis -> the horizon point pair is imaginary
  const Robot u = Robot::ur5();
  T = Eigen::Isometry3d::Identity();
  T.translation() << 0.0, 0.0, 0.4 + 0.0823;  // a_e = +z: P5 = (0, 0, 0.4)
  res = ik(u, T);
  EXPECT_EQ(res.status, IKStatus::Unreachable);
  for (const auto& s : res.solutions) EXPECT_EQ(s.unreachable_step, IKStep::Shoulder);
}

TEST(IK, Claim28SingularWristKukaUsesFreeAngle) {
  const Robot r = Robot::kukaKR6R900sixx();
  const Vector6d q = (Vector6d() << 0.3, -1.2, 1.4, 0.7, 0.0, -0.4).finished();  // θ5 = 0
  const Eigen::Isometry3d T = r.forward(q);
  IKSettings o;
  o.q_free[3] = 0.25;
  const IKResult res = ik(r, T, o);
  // The pose is singular for the generating arm configuration (θ1-θ3) only: both of its
  // wrist labels are flagged and use the free angle; the other arm configurations are
  // regular solutions of the same pose.
  int n = 0;
  for (const auto& s : res.solutions) {
    if (!s.ok()) continue;
    EXPECT_LE(poseError(r.forward(s.q), T), 1e-10);
    if (!(s.singular & kSingularWrist)) continue;
    ++n;
    EXPECT_LE((s.q.head<3>() - q.head<3>()).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_NEAR(std::remainder(s.q[3] - (s.config.wrist > 0 ? 0.25 : 0.25 + M_PI), 2 * M_PI), 0, 1e-12);
  }
  EXPECT_EQ(n, 2);
}

TEST(IK, Claim28SingularShoulderKukaUsesFreeAngle) {
  const Robot r = Robot::kukaKR6R900sixx();
  // wrist centre on the first axis: P_w = (0, 0, 0.9), tool pointing up
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() << 0, 0, 0.9 + 0.08;
  IKSettings o;
  o.q_free[0] = -0.6;
  const IKResult res = ik(r, T, o);
  int n = 0;
  for (const auto& s : res.solutions) {
    if (!s.ok()) continue;
    ++n;
    EXPECT_TRUE(s.singular & kSingularShoulder);
    EXPECT_LE(poseError(r.forward(s.q), T), 1e-10);
    const double expect = s.config.shoulder > 0 ? -0.6 : -0.6 + M_PI;
    EXPECT_NEAR(std::remainder(s.q[0] - expect, 2 * M_PI), 0, 1e-12);
  }
  EXPECT_GE(n, 2);
}

TEST(IK, Claim28SingularWristUR5UsesFreeAngle) {
  const Robot r = Robot::ur5();
  const Vector6d q = (Vector6d() << 0.4, -1.0, 1.2, -0.5, 0.0, 0.9).finished();  // θ5 = 0: a_e ∥ z1
  const Eigen::Isometry3d T = r.forward(q);
  IKSettings o;
  o.q_free[5] = 0.9;
  const IKResult res = ik(r, T, o);
  bool found = false;
  int n = 0;
  for (const auto& s : res.solutions) {
    if (!s.ok()) continue;
    EXPECT_LE(poseError(r.forward(s.q), T), 1e-10);
    if (!(s.singular & kSingularWrist)) continue;
    ++n;  // a_e ∥ z1 holds for this shoulder (θ1) only
    EXPECT_NEAR(std::remainder(s.q[5] - (s.config.wrist > 0 ? 0.9 : 0.9 + M_PI), 2 * M_PI), 0, 1e-12);
    found = found || angleDistance(s.q, q) < 1e-9;
  }
  EXPECT_GE(n, 2);
  EXPECT_TRUE(found);  // q6 = q_free[5] = the generator's q6 reproduces the generator
}

TEST(IK, NearSingularAndBoundaryPosesStayExact) {
  std::mt19937 g(9);
  for (const char* name : {"kr6_r900_sixx", "ur5"}) {
    const Robot r = Robot::byName(name);
    // θ5 near 0 or π: the wrist nearly singular, on both sides of singular_tolerance
    for (double eps : {1e-4, 1e-6, 1e-8, 1e-10, 4e-11, 2e-11, 1e-11, 1e-13, 0.0}) {
      for (int t = 0; t < 200; ++t) {
        Vector6d q = randomQ(g, r, false);
        q[4] = (t % 2 ? eps : -eps) + (t % 4 >= 2 ? M_PI : 0.0) - r.joints[4].theta_offset;
        const Eigen::Isometry3d T = r.forward(q);
        IKSettings o;
        o.respect_limits = false;
        o.q_free = q;
        const IKResult res = ik(r, T, o);
        for (const auto& s : res.solutions)
          if (s.ok()) EXPECT_LE(poseError(r.forward(s.q), T), 1e-10) << name << " eps " << eps;
      }
    }
  }
  // KUKA shoulder: the wrist centre at distance rho from the first axis
  {
    const Robot r = Robot::kukaKR6R900sixx();
    for (double rho : {1e-6, 1e-9, 1e-10, 3e-11, 1e-11, 1e-13, 0.0}) {
      for (int t = 0; t < 100; ++t) {
        const double ang = std::uniform_real_distribution<double>(-M_PI, M_PI)(g);
        const Eigen::Vector3d axis = Eigen::Vector3d::Random().normalized();
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() = Eigen::AngleAxisd(3.0 * ang, axis).toRotationMatrix();
        // heights 0.45-0.65 m: P_w at least 56 mm from P1 (the elbow folds to 33.5 mm at most)
        const Eigen::Vector3d pw(rho * std::cos(ang), rho * std::sin(ang), 0.55 + 0.1 * std::sin(7 * ang));
        T.translation() = pw + 0.08 * T.linear().col(2);
        IKSettings o;
        o.respect_limits = false;
        const IKResult res = ik(r, T, o);
        EXPECT_EQ(res.status, IKStatus::Ok);
        for (const auto& s : res.solutions)
          if (s.ok()) EXPECT_LE(poseError(r.forward(s.q), T), 1e-10) << "rho " << rho;
      }
    }
  }
  // elbow stretched (Q2² = 0): KUKA θ3^DH such that the forearm is in line with the upper arm
  const Robot k = Robot::kukaKR6R900sixx();
  for (double dq : {0.0, 1e-7, 1e-5}) {
    Vector6d qs = (Vector6d() << 0.2, -0.9, 0, 0.3, 0.8, 0.1).finished();
    // q3 that puts the wrist centre farthest from P1 (arm stretched), by a grid search and
    // a ternary refinement of |P_w − P1|
    double best = 0, bestd = 0;
    for (int i = 0; i <= 20000; ++i) {
      const double c = -M_PI + 2 * M_PI * i / 20000.0;
      qs[2] = c;
      const auto F = k.jointFrames(qs);
      const Eigen::Vector3d pw = F[6].translation() - 0.08 * F[6].linear().col(2);
      const double d = (pw - F[1].translation()).norm();
      if (d > bestd) bestd = d, best = c;
    }
    // refine by golden-section on the distance
    double lo = best - 2 * M_PI / 20000, hi = best + 2 * M_PI / 20000;
    for (int it = 0; it < 200; ++it) {
      const double m1 = lo + (hi - lo) / 3, m2 = hi - (hi - lo) / 3;
      auto dist = [&](double c) {
        Vector6d qq = qs;
        qq[2] = c;
        const auto F = k.jointFrames(qq);
        return (F[6].translation() - 0.08 * F[6].linear().col(2) - F[1].translation()).norm();
      };
      if (dist(m1) < dist(m2)) lo = m1; else hi = m2;
    }
    qs[2] = 0.5 * (lo + hi) + dq;
    const Eigen::Isometry3d T = k.forward(qs);
    const IKResult res = ik(k, T);
    EXPECT_EQ(res.status, IKStatus::Ok);
    bool singular = false;
    for (const auto& s : res.solutions)
      if (s.ok()) {
        EXPECT_LE(poseError(k.forward(s.q), T), 1e-9) << "dq " << dq;
        singular = singular || (s.singular & kSingularElbow);
      }
    if (dq == 0.0) EXPECT_TRUE(singular);
  }
}

TEST(IK, ClosestAndLimits) {
  const Robot r = Robot::ur5();
  std::mt19937 g(13);
  for (int t = 0; t < 200; ++t) {
    const Vector6d q = randomQ(g, r, true);
    const Eigen::Isometry3d T = r.forward(q);
    Vector6d start = q;
    for (int i = 0; i < 6; ++i) start[i] += std::uniform_real_distribution<double>(-0.05, 0.05)(g);
    const IKSolution s = ikClosest(r, T, start);
    ASSERT_TRUE(s.ok());
    // the exact generating joints, including its 2π multiples (UR limits are ±2π)
    EXPECT_LE((s.q - q).cwiseAbs().maxCoeff(), 1e-7);
  }
  // a pose whose solutions all violate a tight limit
  Robot tight = Robot::ur5();
  tight.joints[1].q_min = -0.1, tight.joints[1].q_max = 0.1;
  const Eigen::Isometry3d T = tight.forward((Vector6d() << 0, -1.5, 1.0, 0, 1.0, 0).finished());
  const IKResult res = ik(tight, T);
  for (const auto& s : res.solutions)
    if (s.status == IKStatus::Ok) EXPECT_TRUE(tight.withinLimits(s.q, 1e-12));
  EXPECT_GT(res.count(IKStatus::OutsideLimits), 0);
}

TEST(IK, InvalidInput) {
  const Robot r = Robot::ur5();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.matrix()(0, 3) = std::nan("");
  EXPECT_EQ(ik(r, T).status, IKStatus::InvalidInput);
  T = Eigen::Isometry3d::Identity();
  T.matrix()(0, 0) = 2;  // not a rotation
  EXPECT_EQ(ik(r, T).status, IKStatus::InvalidInput);
  Robot odd = Robot::ur5();
  odd.joints[2].alpha = 0.3;
  EXPECT_EQ(odd.geometry(), ArmGeometry::Unsupported);
  EXPECT_EQ(ik(odd, Eigen::Isometry3d::Identity()).status, IKStatus::InvalidInput);
}

TEST(IK, SingularWristUR5PicksAReachableFreeAngle) {
  // θ5 = π: a_e ∥ z1. With q_free[5] = -1.1 the elbow cannot reach, other q6 values can:
  // the solver takes the nearest q6 that works instead of reporting "unreachable".
  const Robot r = Robot::ur5();
  const Vector6d q = (Vector6d() << 1.27198586, 0.70980771, -0.20467251, -1.27468777, M_PI, -2.61732557).finished();
  const Eigen::Isometry3d T = r.forward(q);
  IKSettings o;
  o.respect_limits = false;
  o.q_free[5] = -1.1;
  const IKResult res = ik(r, T, o);
  int singular = 0;
  for (const auto& s : res.solutions) {
    if (!s.ok()) continue;
    EXPECT_LE(poseError(r.forward(s.q), T), 1e-9);
    singular += (s.singular & kSingularWrist) != 0;
  }
  EXPECT_GE(singular, 2);
  // with the generator's own q6 the generator itself comes back
  o.q_free[5] = q[5];
  bool found = false;
  for (const auto& s : ik(r, T, o).solutions) found = found || (s.ok() && angleDistance(s.q, q) < 1e-9);
  EXPECT_TRUE(found);
}

TEST(IK, ConstructionOfUnreachableConfigurations) {
  // KUKA: the elbow pair is imaginary; P_w and P1 are known, P2 is not, Q² < 0.
  const Robot k = Robot::kukaKR6R900sixx();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() << 1.5, 0.3, 0.2;
  IKConstruction c = ikConstruction(k, T, IKConfig{1, 1, 1});
  ASSERT_EQ(c.num_points, 5);
  EXPECT_EQ(c.solution.status, IKStatus::Unreachable);
  EXPECT_LT(c.elbow_discriminant, 0);
  EXPECT_TRUE(c.points[2].allFinite());  // P1
  EXPECT_TRUE(std::isnan(c.points[3].x()));  // P2
  // UR: the horizon pair is imaginary (P5 within d4 of the first axis)
  const Robot u = Robot::ur5();
  T = Eigen::Isometry3d::Identity();
  T.translation() << 0.03, -0.05, 0.3823;
  c = ikConstruction(u, T, IKConfig{1, 1, 1});
  ASSERT_EQ(c.num_points, 7);
  EXPECT_LT(c.shoulder_discriminant, 0);
  EXPECT_TRUE(c.points[1].allFinite());      // P5
  EXPECT_TRUE(std::isnan(c.points[2].x()));  // P_c
  EXPECT_TRUE(c.points[6].allFinite());      // P1
}

// A stretched elbow with a nearly singular wrist: the wrist point P4 comes from two nearly
// parallel planes and carries an error ~1e-16 / sin(q5) m, which used to push the tangent
// elbow pair imaginary (about 12 % of these reachable UR5 poses were reported unreachable).
// Oracle: forward kinematics of every solution reported ok.
TEST(IK, StretchedArmWithNearlySingularWristIsReachable) {
  const Robot r = Robot::ur5();
  std::mt19937 g(3);
  std::uniform_real_distribution<double> u(-M_PI, M_PI);
  std::normal_distribution<double> n(0.0, 1.0);
  IKSettings o;
  o.respect_limits = false;
  for (double scale : {1e-5, 1e-7, 1e-9, 1e-11})
    for (int k = 0; k < 80; ++k) {
      Vector6d q;
      for (int j = 0; j < 6; ++j) q[j] = u(g);
      q[2] = scale * n(g);
      q[4] = scale * n(g);
      const Eigen::Isometry3d T = r.forward(q);
      const IKResult res = ik(r, T, o);
      ASSERT_EQ(res.status, IKStatus::Ok) << "scale " << scale << " sample " << k;
      for (const IKSolution& s : res.solutions)
        if (s.ok()) EXPECT_LT((r.forward(s.q).matrix() - T.matrix()).cwiseAbs().maxCoeff(), 1e-9);
    }
}

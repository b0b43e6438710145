// Robots from joint chains (kinematics/joint_chain.hpp) and the arm's joint points
// (Robot::jointPositions).
// Truth: the published DH tables of Universal Robots and the KUKA KR6 R900 sixx (robot.cpp),
// recovered from joint chains laid out as their ROS-Industrial URDFs (ur_description's
// ur5_robot.urdf, joint origins and axes copied here; KUKA's link dimensions with A1, A4, A6
// turning about -z / -x), KUKA's data-sheet home pose (flange at (525, 0, 890) mm), and the
// chains' forward kinematics written out here with Rodrigues' formula, independently of the
// library.
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "scanalign/kinematics/joint_chain.hpp"
#include "scanalign/kinematics/robot.hpp"

using namespace scanalign;

namespace {

using Eigen::Vector3d;

/// A URDF <origin>: R = Rz(yaw) Ry(pitch) Rx(roll), then the translation.
Eigen::Isometry3d origin(const Vector3d& xyz, const Vector3d& rpy = Vector3d::Zero()) {
  const auto rot = [](int axis, double a) {
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    const int i = (axis + 1) % 3, j = (axis + 2) % 3;
    R(i, i) = std::cos(a), R(i, j) = -std::sin(a), R(j, i) = std::sin(a), R(j, j) = std::cos(a);
    return R;
  };
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rot(2, rpy.z()) * rot(1, rpy.y()) * rot(0, rpy.x());
  T.translation() = xyz;
  return T;
}

/// Rotation by q about the unit vector u: I + sin q K + (1 - cos q) K^2 (Rodrigues).
Eigen::Matrix4d rodrigues(const Vector3d& axis, double q) {
  const Vector3d u = axis / axis.norm();
  Eigen::Matrix3d K;
  K << 0, -u.z(), u.y(), u.z(), 0, -u.x(), -u.y(), u.x(), 0;
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = Eigen::Matrix3d::Identity() + std::sin(q) * K + (1 - std::cos(q)) * K * K;
  return T;
}

/// T_base_tip(q) of a chain: the product of its origins and joint rotations.
Eigen::Matrix4d chainFk(const JointChain& c, const Vector6d& q) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  for (std::size_t i = 0; i < 6; ++i) T = T * c.origins[i].matrix() * rodrigues(c.axes[i], q[static_cast<int>(i)]);
  return T * c.T_joint6_tip.matrix();
}

/// ur_description's ur5_robot.urdf, base_link -> tool0 (pi/2 exact, or as the file writes it).
JointChain ur5Chain(double half_pi = M_PI / 2) {
  JointChain c;
  c.origins = {origin({0, 0, 0.089159}), origin({0, 0.13585, 0}, {0, half_pi, 0}), origin({0, -0.1197, 0.425}),
               origin({0, 0, 0.39225}, {0, half_pi, 0}), origin({0, 0.093, 0}), origin({0, 0, 0.09465})};
  c.axes = {Vector3d::UnitZ(), Vector3d::UnitY(), Vector3d::UnitY(), Vector3d::UnitY(), Vector3d::UnitZ(),
            Vector3d::UnitY()};
  for (auto& l : c.limits) l = Eigen::Vector2d(-2 * M_PI, 2 * M_PI);
  c.limits[2] = Eigen::Vector2d(-M_PI, M_PI);
  c.T_joint6_tip = origin({0, 0.0823, 0}, {-half_pi, 0, 0});
  return c;
}

/// The KR6 R900 sixx as ROS-Industrial describes KUKA arms: un-turned link frames placed by
/// KUKA's link dimensions, A1 about -z, A4 and A6 about -x, tool0 turned by pi/2 about y.
JointChain kukaChain() {
  JointChain c;
  c.origins = {origin({0, 0, 0.400}), origin({0.025, 0, 0}), origin({0.455, 0, 0}),
               origin({0, 0, 0.035}), origin({0.420, 0, 0}), origin({0.080, 0, 0})};
  c.axes = {-Vector3d::UnitZ(), Vector3d::UnitY(), Vector3d::UnitY(), -Vector3d::UnitX(), Vector3d::UnitY(),
            -Vector3d::UnitX()};
  const Robot k = Robot::kukaKR6R900sixx();
  const double sign[6] = {-1, 1, 1, -1, 1, -1};
  for (std::size_t i = 0; i < 6; ++i) {  // the chain's limits: KUKA's, mirrored where the axis is reversed
    const DHJoint& j = k.joints[i];
    c.limits[i] = sign[i] > 0 ? Eigen::Vector2d(j.q_min, j.q_max) : Eigen::Vector2d(-j.q_max, -j.q_min);
  }
  c.T_joint6_tip = origin({0, 0, 0}, {0, M_PI / 2, 0});
  return c;
}

Vector6d randomQ(std::mt19937& g, const Robot& r) {
  Vector6d q;
  for (int i = 0; i < 6; ++i)
    q[i] = std::uniform_real_distribution<double>(std::max(r.joints[i].q_min, -M_PI),
                                                  std::min(r.joints[i].q_max, M_PI))(g);
  return q;
}

double dhDifference(const Robot& a, const Robot& b) {
  double d = 0;
  for (std::size_t i = 0; i < 6; ++i) {
    const DHJoint &x = a.joints[i], &y = b.joints[i];
    for (double v : {x.a - y.a, x.alpha - y.alpha, x.d - y.d, x.theta_offset - y.theta_offset})
      d = std::max(d, std::abs(v));
  }
  return d;
}

}  // namespace

TEST(JointChain, Ur5UrdfGivesUniversalRobotsPublishedTable) {
  const JointChain chain = ur5Chain();
  JointChainSettings s;
  s.name = "ur5";
  const Robot r = Robot::fromJointChain(chain, s);
  const Robot ur5 = Robot::ur5();
  EXPECT_EQ(r.geometry(), ArmGeometry::UniversalRobots);
  EXPECT_EQ(r.name, "ur5");
  EXPECT_LE(dhDifference(r, ur5), 1e-12);
  // DH frame 0 is UR's "base" frame, turned by pi about z from ROS's base_link; tool0 is the flange.
  EXPECT_LE((r.T_base_dh0.matrix() - Eigen::Vector4d(-1, -1, 1, 1).asDiagonal().toDenseMatrix()).cwiseAbs().maxCoeff(),
            1e-15);
  EXPECT_LE((r.T_flange_tool.matrix() - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(r.joints[2].q_min, -M_PI);
  std::mt19937 g(1);
  for (int t = 0; t < 200; ++t) {
    const Vector6d q = randomQ(g, r);
    EXPECT_LE((r.forward(q).matrix() - chainFk(chain, q)).cwiseAbs().maxCoeff(), 1e-12);
    Robot placed = ur5;
    placed.T_base_dh0 = r.T_base_dh0;
    EXPECT_LE((r.forward(q).matrix() - placed.forward(q).matrix()).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(JointChain, TenDigitHalfPiOnlyMovesThetaOffsets) {
  // The URDF writes pi/2 as 1.57079632679 (4.9e-12 short) in turns about axes parallel to the
  // joints: the theta offsets absorb it, the layout stays exact.
  const JointChain chain = ur5Chain(1.57079632679);
  const Robot r = Robot::fromJointChain(chain, {});
  EXPECT_EQ(r.geometry(), ArmGeometry::UniversalRobots);
  EXPECT_LE(dhDifference(r, Robot::ur5()), 1e-11);
  std::mt19937 g(2);
  for (int t = 0; t < 100; ++t) {
    const Vector6d q = randomQ(g, r);
    EXPECT_LE((r.forward(q).matrix() - chainFk(chain, q)).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(JointChain, NearLayoutTwistIsSnappedWithinTheTolerance) {
  // Wrist 2 twisted by 3e-11 rad: alpha_4 misses pi/2 by that much, which the layout test
  // (1e-12) refuses; within the tolerance (1e-9) it is set to pi/2, FK moving by ~3e-11 m.
  JointChain chain = ur5Chain();
  chain.origins[4] = origin({0, 0.093, 0}, {3e-11, 0, 0});
  const Robot r = Robot::fromJointChain(chain, {});
  EXPECT_EQ(r.geometry(), ArmGeometry::UniversalRobots);
  EXPECT_LE(dhDifference(r, Robot::ur5()), 1e-12);
  std::mt19937 g(2);
  for (int t = 0; t < 100; ++t) {
    const Vector6d q = randomQ(g, r);
    EXPECT_LE((r.forward(q).matrix() - chainFk(chain, q)).cwiseAbs().maxCoeff(), 1e-10);
  }
  JointChainSettings strict;
  strict.tolerance = 0;  // 1e-12 then: the twist stays, no layout fits
  EXPECT_THROW(Robot::fromJointChain(chain, strict), std::invalid_argument);
  strict.fk_only = true;
  EXPECT_EQ(Robot::fromJointChain(chain, strict).geometry(), ArmGeometry::Unsupported);
}

TEST(JointChain, KukaNeedsJointSignsAndThenGivesTheDataSheetRobot) {
  const JointChain chain = kukaChain();
  try {
    Robot::fromJointChain(chain, {});
    FAIL() << "a reversed A4 (d4 < 0) is no analytic layout";
  } catch (const std::invalid_argument& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("the joint chain is none of the layouts"), std::string::npos) << m;
    EXPECT_NE(m.find("spherical_wrist"), std::string::npos) << m;
    EXPECT_NE(m.find("joint_signs=(1, 1, 1, -1, 1, 1)"), std::string::npos) << m;
    EXPECT_NE(m.find("fk_only=True"), std::string::npos) << m;
  }
  JointChainSettings s;
  s.joint_signs = (Vector6d() << -1, 1, 1, -1, 1, -1).finished();
  const Robot r = Robot::fromJointChain(chain, s);
  const Robot kuka = Robot::kukaKR6R900sixx();
  EXPECT_EQ(r.geometry(), ArmGeometry::SphericalWrist);
  EXPECT_LE(dhDifference(r, kuka), 1e-12);
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_NEAR(r.joints[i].q_min, kuka.joints[i].q_min, 1e-15);
    EXPECT_NEAR(r.joints[i].q_max, kuka.joints[i].q_max, 1e-15);
  }
  EXPECT_LE((r.T_base_dh0.matrix() - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  // KUKA's home pose: the flange at (525, 0, 890) mm, tool0's z (the flange normal) along +x.
  const Eigen::Isometry3d home = r.forward((Vector6d() << 0, -M_PI / 2, M_PI / 2, 0, 0, 0).finished());
  EXPECT_LE((home.translation() - Vector3d(0.525, 0, 0.890)).norm(), 1e-12);
  EXPECT_LE((home.linear().col(2) - Vector3d::UnitX()).norm(), 1e-12);
  std::mt19937 g(3);
  for (int t = 0; t < 200; ++t) {
    const Vector6d q = randomQ(g, r);
    EXPECT_LE((r.forward(q).matrix() - chainFk(chain, s.joint_signs->cwiseProduct(q))).cwiseAbs().maxCoeff(), 1e-12);
  }
  // The signs the error suggested: another, equally valid, analytic table.
  JointChainSettings one;
  one.joint_signs = (Vector6d() << 1, 1, 1, -1, 1, 1).finished();
  EXPECT_EQ(Robot::fromJointChain(chain, one).geometry(), ArmGeometry::SphericalWrist);
  // FK only, q 1:1 onto the chain.
  JointChainSettings fk;
  fk.fk_only = true;
  const Robot f = Robot::fromJointChain(chain, fk);
  EXPECT_EQ(f.geometry(), ArmGeometry::Unsupported);
  const Vector6d q = randomQ(g, r);
  EXPECT_LE((f.forward(q).matrix() - chainFk(chain, q)).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(JointChain, SkewChainForwardKinematicsIsExact) {
  std::mt19937 g(4);
  std::uniform_real_distribution<double> u(-0.2, 0.2), a(-M_PI, M_PI);
  std::normal_distribution<double> n;
  for (int trial = 0; trial < 5; ++trial) {
    JointChain c;
    for (std::size_t i = 0; i < 6; ++i) {
      c.origins[i] = origin({u(g), u(g), u(g)}, {a(g), a(g), a(g)});
      c.axes[i] = Vector3d(n(g), n(g), n(g));
      c.limits[i] = Eigen::Vector2d(-2, 2.5);
    }
    c.limits[3] = Eigen::Vector2d(-INFINITY, INFINITY);  // a continuous joint
    c.T_joint6_tip = origin({u(g), u(g), u(g)}, {a(g), a(g), a(g)});
    JointChainSettings s;
    s.fk_only = true;
    const Robot r = Robot::fromJointChain(c, s);
    EXPECT_EQ(r.geometry(), ArmGeometry::Unsupported);
    EXPECT_TRUE(std::isinf(r.joints[3].q_min) && std::isinf(r.joints[3].q_max));
    EXPECT_EQ(r.joints[0].q_min, -2);
    EXPECT_EQ(r.joints[0].q_max, 2.5);
    for (int t = 0; t < 50; ++t) {
      const Vector6d q = randomQ(g, r);
      EXPECT_LE((r.forward(q).matrix() - chainFk(c, q)).cwiseAbs().maxCoeff(), 1e-12);
      EXPECT_LE((c.forward(q).matrix() - chainFk(c, q)).cwiseAbs().maxCoeff(), 1e-14);
    }
  }
}

TEST(JointChain, BadChainsAndSettingsThrowNamingTheField) {
  JointChain c = ur5Chain();
  c.axes[2] = Vector3d::Zero();
  EXPECT_THROW(Robot::fromJointChain(c, {}), std::invalid_argument);
  c = ur5Chain();
  c.limits[1] = Eigen::Vector2d(1, -1);
  EXPECT_THROW(Robot::fromJointChain(c, {}), std::invalid_argument);
  c = ur5Chain();
  c.origins[0].matrix()(0, 0) = 2;
  EXPECT_THROW(Robot::fromJointChain(c, {}), std::invalid_argument);
  JointChainSettings s;
  s.joint_signs = (Vector6d() << 1, 1, 1, 0, 1, 1).finished();
  try {
    Robot::fromJointChain(ur5Chain(), s);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("joint_signs"), std::string::npos);
  }
  s = {};
  s.tolerance = 1e-2;
  EXPECT_THROW(Robot::fromJointChain(ur5Chain(), s), std::invalid_argument);
  // Nearly parallel axes (1e-7 rad, above the tolerance) put the common normal kilometres away.
  c = ur5Chain();
  c.axes[2] = Vector3d(0, 1, 1e-7);
  s = {};
  s.what = "arm.urdf: the chain";
  try {
    Robot::fromJointChain(c, s);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("arm.urdf: the chain gives no usable DH table", 0), 0u) << e.what();
  }
}

TEST(JointPositions, KukaHomePoseFromTheLinkDimensions) {
  // Base 400 mm, A1-A2 offset 25, upper arm 455 (up at home), A3-A4 offset 35, forearm 420
  // (forward), wrist to flange 80 mm.
  Robot r = Robot::kukaKR6R900sixx();
  const Vector6d home = (Vector6d() << 0, -M_PI / 2, M_PI / 2, 0, 0, 0).finished();
  const Vector3d want[7] = {{0, 0, 0},           {0.025, 0, 0.400}, {0.025, 0, 0.855}, {0.025, 0, 0.890},
                            {0.445, 0, 0.890},   {0.445, 0, 0.890}, {0.525, 0, 0.890}};
  const auto P = r.jointPositions(home);
  for (int i = 0; i < 7; ++i) EXPECT_LE((P[static_cast<std::size_t>(i)] - want[i]).norm(), 1e-12) << "frame " << i;
  // In the base frame: T_base_dh0 applied.
  r.T_base_dh0 = origin({0.1, -0.2, 0.3}, {0.1, 0.2, 0.3});
  const auto Q = r.jointPositions(home);
  for (int i = 0; i < 7; ++i) EXPECT_LE((Q[static_cast<std::size_t>(i)] - r.T_base_dh0 * want[i]).norm(), 1e-12);
}

TEST(JointPositions, Ur5AtZeroFromThePublishedTable) {
  // UR5 at q = 0 (UR's DH table): the arm stretched along x, the wrist offsets along -y and -z.
  const double d1 = 0.089159, a2 = -0.425, a3 = -0.39225, d4 = 0.10915, d5 = 0.09465, d6 = 0.0823;
  const Vector3d want[7] = {{0, 0, 0},          {0, 0, d1},          {a2, 0, d1},           {a2 + a3, 0, d1},
                            {a2 + a3, -d4, d1}, {a2 + a3, -d4, d1 - d5}, {a2 + a3, -d4 - d6, d1 - d5}};
  const auto P = Robot::ur5().jointPositions(Vector6d::Zero());
  for (int i = 0; i < 7; ++i) EXPECT_LE((P[static_cast<std::size_t>(i)] - want[i]).norm(), 1e-12) << "frame " << i;
}

TEST(JointPositions, BatchAndToolPointMatchTheSingleCall) {
  std::mt19937 g(5);
  Robot r = Robot::ur10e();
  r.T_base_dh0 = origin({0.5, 0.1, -0.2}, {0.3, -0.2, 1.0});
  r.T_flange_tool = origin({0.01, 0.02, 0.15}, {0.4, 0, 0});
  const int n = 300;  // above the parallel threshold
  std::vector<double> q(6 * n), out7(7 * 3 * n), out8(8 * 3 * n);
  for (int k = 0; k < n; ++k) Eigen::Map<Vector6d>(q.data() + 6 * k) = randomQ(g, r);
  r.jointPositionsBatch(q.data(), n, out7.data(), false, 0);
  r.jointPositionsBatch(q.data(), n, out8.data(), true, 2);
  for (int k = 0; k < n; ++k) {
    const Vector6d qk = Eigen::Map<const Vector6d>(q.data() + 6 * k);
    const auto P = r.jointPositions(qk);
    const auto F = r.jointFrames(qk);
    for (int i = 0; i < 7; ++i) {
      const Vector3d p7 = Eigen::Map<const Vector3d>(out7.data() + 21 * k + 3 * i);
      const Vector3d p8 = Eigen::Map<const Vector3d>(out8.data() + 24 * k + 3 * i);
      EXPECT_EQ(p7, P[static_cast<std::size_t>(i)]);
      EXPECT_EQ(p8, P[static_cast<std::size_t>(i)]);
      EXPECT_LE((P[static_cast<std::size_t>(i)] - r.T_base_dh0 * F[static_cast<std::size_t>(i)].translation()).norm(),
                1e-14);
    }
    EXPECT_LE((Eigen::Map<const Vector3d>(out8.data() + 24 * k + 21) - r.forward(qk).translation()).norm(), 1e-15);
  }
}

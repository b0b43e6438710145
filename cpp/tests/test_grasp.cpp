// Grasp planning (grasp/grasp_planner.hpp) against independent truth: forward kinematics of
// the joint targets, the frame composition T_base_model T_model_grasp written out here, a
// brute-force minimum over the candidates, and cases built so that exactly one reason applies.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "scanalign/grasp/grasp_planner.hpp"

using namespace scanalign;

namespace {

Eigen::Isometry3d pose(const Eigen::Vector3d& t, const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}

Eigen::Matrix3d rotX(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX()).toRotationMatrix(); }
Eigen::Matrix3d rotZ(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix(); }

double maxDiff(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff();
}

/// python/scanalign/synthetic/mount.py robot_mount(): 0.9 m above the table centre (0.5, 0), roll pi.
Robot hanging(Robot r) {
  r.T_base_dh0 = pose({0.5, 0, 0.9}, rotX(M_PI)) * r.T_base_dh0;
  return r;
}

/// A top grasp: TCP 3 cm above the model origin, tool z pointing down.
Grasp topGrasp() {
  Grasp g;
  g.name = "top";
  g.T_model_grasp = pose({0, 0, 0.03}, rotX(M_PI));
  return g;
}

const Eigen::Vector4d kTable(0, 0, 1, 0);  // z = 0 in the base frame, normal up

struct Cell {
  Robot robot;
  Eigen::Isometry3d T_base_model;
  Vector6d q_current;
};

std::vector<Cell> cells() {
  const Vector6d q_ur = (Vector6d() << 0, -M_PI / 2, M_PI / 2, -M_PI / 2, -M_PI / 2, 0).finished();
  const Vector6d q_kuka = (Vector6d() << 0, -M_PI / 2, M_PI / 2, 0, M_PI / 2, 0).finished();
  return {{hanging(Robot::ur5()), pose({0.75, 0.15, 0}, rotZ(0.3)), q_ur},
          {Robot::ur5(), pose({0.45, 0.2, 0}, rotZ(-0.4)), q_ur},
          {hanging(Robot::kukaKR6R900sixx()), pose({1.0, -0.1, 0}, rotZ(0.5)), q_kuka},
          {Robot::kukaKR6R900sixx(), pose({0.55, 0.1, 0}, rotZ(1.0)), q_kuka}};
}

/// Every Ok candidate's joint targets reach the commanded flange poses to 1e-9, and the TCP
/// there is T_base_model T_model_grasp' composed independently here.
void expectExactTargets(const Robot& robot, const Gripper& gripper, const GraspPlanResult& plan,
                        const Eigen::Isometry3d& T_base_model, const std::vector<Grasp>& grasps,
                        const PartSymmetry& sym) {
  const auto S = sym.transforms();
  for (const GraspCandidate& c : plan.candidates) {
    if (c.reason != GraspReason::Ok) continue;
    const Eigen::Isometry3d tcp = T_base_model * S[static_cast<std::size_t>(c.symmetry_index)] *
                                  grasps[static_cast<std::size_t>(c.grasp_index)].T_model_grasp;
    EXPECT_LE(maxDiff(robot.forwardFlange(c.q_grasp), c.T_base_flange_grasp), 1e-9);
    EXPECT_LE(maxDiff(robot.forwardFlange(c.q_pregrasp), c.T_base_flange_pregrasp), 1e-9);
    EXPECT_LE(maxDiff(robot.forwardFlange(c.q_grasp) * gripper.T_flange_tcp, tcp), 1e-9);
    EXPECT_LE(maxDiff(c.T_base_tcp_grasp, tcp), 1e-12);
    EXPECT_TRUE(robot.withinLimits(c.q_grasp) && robot.withinLimits(c.q_pregrasp));
  }
}

}  // namespace

TEST(GraspPlanner, TopGraspFoundWithExactJointTargetsOnEveryCell) {
  const Gripper gripper = Gripper::parallelJaw();
  for (const Cell& cell : cells()) {
    SCOPED_TRACE(cell.robot.name);
    const std::vector<Grasp> grasps{topGrasp()};
    const GraspPlanResult plan = planGrasp(cell.robot, cell.T_base_model, grasps, {}, gripper, kTable, cell.q_current);
    ASSERT_TRUE(plan.found) << plan.message;
    ASSERT_EQ(plan.candidates.size(), 8u);
    expectExactTargets(cell.robot, gripper, plan, cell.T_base_model, grasps, {});
    const GraspCandidate& ch = plan.candidates[static_cast<std::size_t>(plan.chosen)];
    // The approach: pre-grasp first, grasp last, every sample on the straight TCP line with the
    // grasp's orientation, 5 mm apart.
    ASSERT_EQ(plan.approach_q.size(), 17u);
    EXPECT_LE((plan.approach_q.front() - ch.q_pregrasp).norm(), 0);
    EXPECT_LE((plan.approach_q.back() - ch.q_grasp).norm(), 0);
    const Eigen::Isometry3d grasp_tcp = cell.T_base_model * grasps[0].T_model_grasp;
    const Eigen::Vector3d down = grasp_tcp.linear().col(2);
    for (std::size_t k = 0; k < plan.approach_q.size(); ++k) {
      const Eigen::Isometry3d T = cell.robot.forwardFlange(plan.approach_q[k]) * gripper.T_flange_tcp;
      EXPECT_LE((T.linear() - grasp_tcp.linear()).cwiseAbs().maxCoeff(), 1e-9);
      const Eigen::Vector3d expected = grasp_tcp.translation() - (0.08 - 0.005 * double(k)) * down;
      EXPECT_LE((T.translation() - expected).norm(), 1e-9) << "sample " << k;
    }
    // The pre-grasp is 8 cm above the grasp (the tool points down).
    EXPECT_NEAR(ch.T_base_tcp_pregrasp.translation().z() - ch.T_base_tcp_grasp.translation().z(), 0.08, 1e-12);
  }
}

TEST(GraspPlanner, FarOutOfReachEveryCandidateUnreachable) {
  for (const Cell& cell : cells()) {
    const GraspPlanResult plan = planGrasp(cell.robot, pose({5, 0, 0}), {topGrasp()}, {}, Gripper::parallelJaw(), kTable,
                                     cell.q_current);
    EXPECT_FALSE(plan.found);
    EXPECT_EQ(plan.chosen, -1);
    for (const GraspCandidate& c : plan.candidates) EXPECT_EQ(c.reason, GraspReason::Unreachable) << c.detail;
    EXPECT_NE(plan.message.find("out of reach"), std::string::npos) << plan.message;
  }
}

TEST(GraspPlanner, GraspFromBelowTheTableIsBelowTable) {
  Grasp g = topGrasp();
  g.T_model_grasp = pose({0, 0, 0.03});  // tool z up: the hand comes from under the table
  for (const Cell& cell : cells()) {
    GraspPlannerSettings no_limits;  // the limits would hide some branches behind OutsideLimits
    no_limits.respect_limits = false;
    // A hanging arm cannot reach 0.9 m down and more: there the table and the part are 0.4 m higher.
    const double h = cell.robot.T_base_dh0(2, 2) < 0 ? 0.4 : 0.0;
    const GraspPlanResult plan = planGrasp(cell.robot, pose({0, 0, h}) * cell.T_base_model, {g}, {}, Gripper::parallelJaw(),
                                     Eigen::Vector4d(0, 0, 1, -h), cell.q_current, no_limits);
    EXPECT_FALSE(plan.found);
    int below = 0;
    for (const GraspCandidate& c : plan.candidates) {
      below += c.reason == GraspReason::BelowTable;
      if (c.reason != GraspReason::Unreachable && c.reason != GraspReason::OutsideLimits)
        EXPECT_EQ(c.reason, GraspReason::BelowTable) << c.detail;
    }
    EXPECT_GT(below, 0);
    EXPECT_NE(plan.message.find("below the table"), std::string::npos) << plan.message;
  }
}

TEST(GraspPlanner, WristSingularPoseIsNearSingularityForItsBranches) {
  for (const Robot& robot : {Robot::ur5(), Robot::kukaKR6R900sixx()}) {
    SCOPED_TRACE(robot.name);
    // Joints with the DH wrist angle theta5 0.02 rad from 0: the pre-grasp is this flange pose.
    Vector6d q = (Vector6d() << 0.3, -1.2, 1.1, 0.4, 0.02, 0.5).finished();
    q[4] -= robot.joints[4].theta_offset;
    Gripper gripper = Gripper::parallelJaw();
    Grasp g = topGrasp();
    g.pre_grasp_distance = 0;
    g.T_model_grasp = robot.forwardFlange(q) * gripper.T_flange_tcp;
    const Eigen::Vector4d far_table(0, 0, 1, 10);  // 10 m below: only the singularity applies
    const GraspPlanResult plan = planGrasp(robot, Eigen::Isometry3d::Identity(), {g}, {}, gripper, far_table, q);
    const IKResult r = ik(robot, robot.forwardFlange(q));
    int affected = 0;
    for (const GraspCandidate& c : plan.candidates) {
      const IKSolution& s = r.solutions[static_cast<std::size_t>(c.config_index)];
      if (!s.ok()) continue;
      const double theta5 = std::abs(std::sin(s.q[4] + robot.joints[4].theta_offset));
      if (theta5 < 0.04) {  // the branches through q (both wrist labels): wrist angle 0.02 rad
        ++affected;
        EXPECT_EQ(c.reason, GraspReason::NearSingularity);
        EXPECT_NE(c.detail.find("wrist: theta5 is 0.02"), std::string::npos) << c.detail;
      }
    }
    EXPECT_GE(affected, 2);
    // The margin is a setting: 0.01 rad lets those branches through.
    GraspPlannerSettings s;
    s.min_wrist_angle = 0.01;
    EXPECT_TRUE(planGrasp(robot, Eigen::Isometry3d::Identity(), {g}, {}, gripper, far_table, q, s).found);
  }
}

TEST(GraspPlanner, ElbowAndShoulderMarginsMeasureTheArmGeometry) {
  const Eigen::Vector4d far_table(0, 0, 1, 10);
  Gripper flange_only = Gripper::parallelJaw();
  flange_only.T_flange_tcp = Eigen::Isometry3d::Identity();
  {  // UR5 with theta3 = 0.03 rad: upper arm and forearm (both in the arm plane) 0.03 rad from straight
    const Robot robot = Robot::ur5();
    const Vector6d q = (Vector6d() << 0.3, -1.2, 0.03, -1.0, 1.2, 0.5).finished();
    Grasp g;
    g.pre_grasp_distance = 0;
    g.T_model_grasp = robot.forwardFlange(q);
    const GraspPlanResult plan = planGrasp(robot, Eigen::Isometry3d::Identity(), {g}, {}, flange_only, far_table, q);
    const IKSolution mine = ikClosest(robot, g.T_model_grasp, q);
    const GraspCandidate& c = plan.candidates[static_cast<std::size_t>(configIndex(mine.config))];
    EXPECT_EQ(c.reason, GraspReason::NearSingularity);
    EXPECT_NE(c.detail.find("elbow: 0.03 rad from stretched"), std::string::npos) << c.detail;
  }
  {  // KR6, tool down: the wrist centre is d6 = 0.08 m above the flange, here 0.01 m from the first axis
    const Robot robot = Robot::kukaKR6R900sixx();
    Grasp g;
    g.pre_grasp_distance = 0;
    g.T_model_grasp = pose({0.01 * std::cos(0.4), 0.01 * std::sin(0.4), 0.7}, rotX(M_PI));
    const Vector6d q0 = (Vector6d() << 0, -M_PI / 2, M_PI / 2, 0, M_PI / 2, 0).finished();
    const GraspPlanResult plan = planGrasp(robot, Eigen::Isometry3d::Identity(), {g}, {}, flange_only, far_table, q0);
    int shoulder = 0;
    for (const GraspCandidate& c : plan.candidates) {
      if (c.reason == GraspReason::Unreachable || c.reason == GraspReason::OutsideLimits) continue;
      ++shoulder;
      EXPECT_EQ(c.reason, GraspReason::NearSingularity) << c.detail;
      EXPECT_NE(c.detail.find("shoulder: wrist centre 0.01 m from the first axis"), std::string::npos) << c.detail;
    }
    EXPECT_GT(shoulder, 0);
    GraspPlannerSettings s;
    s.min_shoulder_distance = 0.005;
    EXPECT_TRUE(planGrasp(robot, Eigen::Isometry3d::Identity(), {g}, {}, flange_only, far_table, q0, s).found);
  }
}

TEST(GraspPlanner, JointLimitsGiveOutsideLimits) {
  for (Cell cell : cells()) {
    SCOPED_TRACE(cell.robot.name);
    const GraspPlanResult free = planGrasp(cell.robot, cell.T_base_model, {topGrasp()}, {}, Gripper::parallelJaw(), kTable,
                                     cell.q_current);
    ASSERT_TRUE(free.found);
    // Joint 6 may not turn: no grasp orientation about the tool axis fits (a 0.001 rad window).
    const double q6 = free.candidates[static_cast<std::size_t>(free.chosen)].q_pregrasp[5];
    cell.robot.joints[5].q_min = q6 + 0.5, cell.robot.joints[5].q_max = q6 + 0.501;
    const GraspPlanResult plan = planGrasp(cell.robot, cell.T_base_model, {topGrasp()}, {}, Gripper::parallelJaw(), kTable,
                                     cell.q_current);
    EXPECT_FALSE(plan.found);
    int outside = 0;
    for (const GraspCandidate& c : plan.candidates) {
      outside += c.reason == GraspReason::OutsideLimits;
      EXPECT_TRUE(c.reason == GraspReason::OutsideLimits || c.reason == GraspReason::Unreachable) << c.detail;
    }
    EXPECT_GT(outside, 0);
    GraspPlannerSettings ignore;
    ignore.respect_limits = false;
    EXPECT_TRUE(planGrasp(cell.robot, cell.T_base_model, {topGrasp()}, {}, Gripper::parallelJaw(), kTable,
                          cell.q_current, ignore).found);
  }
}

TEST(GraspPlanner, SymmetryMultipliesCandidatesAndTheLeastMotionIsChosen) {
  PartSymmetry sym;
  sym.order = 4;
  sym.point = {0.01, 0.02, 0};  // off the model origin: the copies move, not only turn
  Grasp side = topGrasp();
  side.T_model_grasp = pose({0.03, 0, 0.03}, rotX(M_PI) * rotZ(0.2));
  const std::vector<Grasp> grasps{topGrasp(), side};
  for (const Cell& cell : cells()) {
    SCOPED_TRACE(cell.robot.name);
    const Gripper gripper = Gripper::parallelJaw();
    const GraspPlanResult plan = planGrasp(cell.robot, cell.T_base_model, grasps, sym, gripper, kTable, cell.q_current);
    ASSERT_EQ(plan.candidates.size(), 2u * 4u * 8u);
    ASSERT_TRUE(plan.found);
    expectExactTargets(cell.robot, gripper, plan, cell.T_base_model, grasps, sym);
    double best = INFINITY;
    int feasible = 0, copies_ok[4] = {};
    for (const GraspCandidate& c : plan.candidates) {
      if (c.reason != GraspReason::Ok) continue;
      ++feasible, ++copies_ok[c.symmetry_index];
      best = std::min(best, c.cost);
      // The cost starts with the weighted move to the pre-grasp, and each joint is the
      // 2*pi multiple nearest the current joints.
      EXPECT_GE(c.cost, (c.q_pregrasp - cell.q_current).cwiseAbs().sum() - 1e-12);
      for (int j = 0; j < 6; ++j)
        for (double k : {-2 * M_PI, 2 * M_PI}) {
          const double v = c.q_pregrasp[j] + k;
          if (v >= cell.robot.joints[static_cast<std::size_t>(j)].q_min &&
              v <= cell.robot.joints[static_cast<std::size_t>(j)].q_max)
            EXPECT_GE(std::abs(v - cell.q_current[j]), std::abs(c.q_pregrasp[j] - cell.q_current[j]));
        }
    }
    EXPECT_GT(feasible, 8);
    EXPECT_GT(std::count_if(copies_ok, copies_ok + 4, [](int n) { return n > 0; }), 1);
    EXPECT_EQ(plan.candidates[static_cast<std::size_t>(plan.chosen)].cost, best);
  }
}

TEST(GraspPlanner, ApproachThroughTheShoulderSingularityIsABranchChange) {
  // KR6 upright, tool down, flange = TCP: the wrist centre is d6 above the flange, so a
  // horizontal approach line through x = y = 0 carries it across the first axis, where the
  // shoulder label flips (or q1 jumps by pi).
  const Robot robot = Robot::kukaKR6R900sixx();
  Gripper gripper = Gripper::parallelJaw();
  gripper.T_flange_tcp = Eigen::Isometry3d::Identity();
  gripper.box_half_extents.setZero(), gripper.box_centre.setZero();
  const Eigen::Vector4d far_table(0, 0, 1, 10);
  const Vector6d q0 = (Vector6d() << 0, -M_PI / 2, M_PI / 2, 0, M_PI / 2, 0).finished();
  for (double y : {0.0, 0.1}) {
    Grasp g;
    g.T_model_grasp = pose({0.05, y, 0.75}, rotX(M_PI));
    g.approach = Eigen::Vector3d::UnitX();  // the TCP's x is the base x
    g.pre_grasp_distance = 0.1;
    const GraspPlanResult plan = planGrasp(robot, Eigen::Isometry3d::Identity(), {g}, {}, gripper, far_table, q0);
    if (y == 0.1) {  // the control: the same line 10 cm aside is followed
      EXPECT_TRUE(plan.found) << plan.message;
      continue;
    }
    EXPECT_FALSE(plan.found);
    int changes = 0;
    for (const GraspCandidate& c : plan.candidates) {
      changes += c.reason == GraspReason::ApproachBranchChange;
      if (c.reason != GraspReason::Unreachable && c.reason != GraspReason::OutsideLimits)
        EXPECT_EQ(c.reason, GraspReason::ApproachBranchChange) << c.detail;
    }
    EXPECT_GT(changes, 0);
  }
}

TEST(GraspPlanner, ApproachBeyondReachIsUnreachableAlongTheApproach) {
  // UR5 upright: the pre-grasp 0.65 m out is reachable, the grasp 1.25 m out (beyond the
  // 0.85 m reach) is not; the straight line between them leaves the workspace on the way.
  const Robot robot = Robot::ur5();
  Grasp g = topGrasp();
  g.T_model_grasp = pose({1.25, 0.1, 0.3}, rotX(M_PI));
  g.approach = Eigen::Vector3d::UnitX();
  g.pre_grasp_distance = 0.6;
  const Vector6d q0 = (Vector6d() << 0, -M_PI / 2, M_PI / 2, -M_PI / 2, -M_PI / 2, 0).finished();
  GraspPlannerSettings s;  // the joints speed up towards the stretched elbow: only the reach is tested
  s.max_joint_step = 3;
  const GraspPlanResult plan = planGrasp(robot, Eigen::Isometry3d::Identity(), {g}, {}, Gripper::parallelJaw(),
                                   Eigen::Vector4d(0, 0, 1, 10), q0, s);
  EXPECT_FALSE(plan.found);
  int along = 0;
  for (const GraspCandidate& c : plan.candidates) {
    EXPECT_EQ(c.reason, GraspReason::Unreachable) << c.detail;
    if (c.q_pregrasp.allFinite()) {
      ++along;
      EXPECT_NE(c.detail.find("approach sample"), std::string::npos) << c.detail;
      EXPECT_LE(maxDiff(robot.forwardFlange(c.q_pregrasp), c.T_base_flange_pregrasp), 1e-9);
    }
  }
  EXPECT_GT(along, 0);
}

TEST(GraspPlanner, EquivalentGraspsFollowTheSymmetry) {
  PartSymmetry sym;
  sym.order = 0;
  const auto copies = equivalentGrasps(topGrasp(), sym, 12);
  ASSERT_EQ(copies.size(), 12u);
  for (std::size_t k = 0; k < copies.size(); ++k)
    EXPECT_LE(maxDiff(copies[k].T_model_grasp, pose({0, 0, 0}, rotZ(M_PI * double(k) / 6)) * topGrasp().T_model_grasp),
              1e-12);
  EXPECT_LE(maxDiff(topGrasp().preGrasp(), pose({0, 0, 0.11}, rotX(M_PI))), 1e-15);
}

TEST(GraspPlanner, GripperHeights) {
  const Gripper g = Gripper::parallelJaw();
  const Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  // Tool down with the flange 0.4 m up: the box reaches to the TCP, 0.25 m.
  EXPECT_NEAR(g.bodyHeight(pose({0, 0, 0.4}, rotX(M_PI)), n, 0), 0.25, 1e-12);
  EXPECT_NEAR(g.flangeHeight(pose({0, 0, 0.4}, rotX(M_PI)), n, 0), 0.4, 1e-12);
  // Tool horizontal (flange z along base x): the box's lowest edge is 0.07 m (half of y? no: x
  // of the flange is down after Ry(pi/2)) below the axis; the flange disc reaches its radius down.
  const Eigen::Isometry3d side = pose({0, 0, 0.4}, Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()).toRotationMatrix());
  EXPECT_NEAR(g.bodyHeight(side, n, 0), 0.4 - 0.04, 1e-12);
  EXPECT_NEAR(g.flangeHeight(side, n, 0), 0.4 - 0.0315, 1e-12);
  Gripper cap = g;
  cap.shape = GripperShape::Capsule;
  EXPECT_NEAR(cap.bodyHeight(pose({0, 0, 0.4}, rotX(M_PI)), n, 0), 0.4 - 0.11 - 0.04, 1e-12);
}

TEST(GraspPlanner, BadInputNamesTheField) {
  const Robot robot = Robot::ur5();
  const Vector6d q = Vector6d::Zero();
  const Gripper gr = Gripper::parallelJaw();
  const auto message = [&](auto&& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  const auto plan = [&](const Robot& r, const Eigen::Isometry3d& T, const std::vector<Grasp>& g, const PartSymmetry& s,
                        const Gripper& grip, const Eigen::Vector4d& plane, const Vector6d& qc,
                        const GraspPlannerSettings& set) {
    return message([&] { planGrasp(r, T, g, s, grip, plane, qc, set); });
  };
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d scaled = I;
  scaled.linear() *= 2;
  EXPECT_NE(plan(robot, scaled, {topGrasp()}, {}, gr, kTable, q, {}).find("T_base_model"), std::string::npos);
  EXPECT_NE(plan(robot, I, {}, {}, gr, kTable, q, {}).find("grasps"), std::string::npos);
  Grasp g = topGrasp();
  g.T_model_grasp = scaled;
  EXPECT_NE(plan(robot, I, {topGrasp(), g}, {}, gr, kTable, q, {}).find("grasps[1].T_model_grasp"), std::string::npos);
  g = topGrasp(), g.approach = {0, 0, 2};
  EXPECT_NE(plan(robot, I, {g}, {}, gr, kTable, q, {}).find("grasps[0].approach"), std::string::npos);
  g = topGrasp(), g.approach = {0, 0, 0};
  EXPECT_NE(plan(robot, I, {g}, {}, gr, kTable, q, {}).find("approach"), std::string::npos);
  g = topGrasp(), g.pre_grasp_distance = -0.1;
  EXPECT_NE(plan(robot, I, {g}, {}, gr, kTable, q, {}).find("pre_grasp_distance"), std::string::npos);
  g = topGrasp(), g.pre_grasp_distance = 1e6;
  EXPECT_NE(plan(robot, I, {g}, {}, gr, kTable, q, {}).find("100000"), std::string::npos);
  EXPECT_NE(plan(robot, I, {topGrasp()}, {}, gr, Eigen::Vector4d(0, 0, NAN, 0), q, {}).find("table_plane"),
            std::string::npos);
  EXPECT_NE(plan(robot, I, {topGrasp()}, {}, gr, Eigen::Vector4d(0, 0, 2, 0), q, {}).find("table_plane"),
            std::string::npos);
  Gripper bad = gr;
  bad.capsule_radius = -1;
  EXPECT_NE(plan(robot, I, {topGrasp()}, {}, bad, kTable, q, {}).find("capsule_radius"), std::string::npos);
  bad = gr, bad.T_flange_tcp = scaled;
  EXPECT_NE(plan(robot, I, {topGrasp()}, {}, bad, kTable, q, {}).find("T_flange_tcp"), std::string::npos);
  GraspPlannerSettings s;
  s.approach_step = 0;
  EXPECT_NE(plan(robot, I, {topGrasp()}, {}, gr, kTable, q, s).find("approach_step"), std::string::npos);
  s = {}, s.table_clearance = NAN;
  EXPECT_NE(plan(robot, I, {topGrasp()}, {}, gr, kTable, q, s).find("table_clearance"), std::string::npos);
  s = {}, s.joint_weights[3] = 1e7;
  EXPECT_NE(plan(robot, I, {topGrasp()}, {}, gr, kTable, q, s).find("joint_weights"), std::string::npos);
  PartSymmetry sym;
  sym.order = 0;
  s = {}, s.continuous_symmetry_steps = 3600;
  EXPECT_NE(plan(robot, I, std::vector<Grasp>(3, topGrasp()), sym, gr, kTable, q, s).find("symmetry copies exceeds"),
            std::string::npos);
  sym.order = -1;
  EXPECT_NE(plan(robot, I, {topGrasp()}, sym, gr, kTable, q, {}).find("symmetry order"), std::string::npos);
  Vector6d qn = q;
  qn[2] = NAN;
  EXPECT_NE(plan(robot, I, {topGrasp()}, {}, gr, kTable, qn, {}).find("q_current"), std::string::npos);
  Robot odd = robot;
  odd.joints[1].alpha = 0.3;
  EXPECT_NE(plan(odd, I, {topGrasp()}, {}, gr, kTable, q, {}).find("robot"), std::string::npos);
}

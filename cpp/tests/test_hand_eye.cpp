// Hand-eye calibration (calibration/hand_eye.hpp) against constructed truth: poses built
// from a known X = T_flange_camera and Z = T_base_world, so that A_i X = Z B_i holds exactly.
#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "scanalign/calibration/hand_eye.hpp"
#include "scanalign/common/rigid.hpp"

using namespace scanalign;

namespace {

Eigen::Matrix4d pose(const Eigen::Vector3d& axis, double angle, const Eigen::Vector3d& t) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  T.topRightCorner<3, 1>() = t;
  return T;
}

Eigen::Matrix4d randomPose(std::mt19937& rng, double max_angle, double max_t) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d axis(u(rng), u(rng), u(rng));
  return pose(axis, max_angle * std::abs(u(rng)), max_t * Eigen::Vector3d(u(rng), u(rng), u(rng)));
}

const Eigen::Matrix4d kX = pose({0.3, -0.2, 1.0}, 0.4, {0.035, -0.012, 0.05});  // T_flange_camera
const Eigen::Matrix4d kZ = pose({-0.5, 0.1, 0.8}, 1.1, {0.6, 0.1, -0.2});      // T_base_world

/// The camera poses B_i = inv(Z) A_i X of the flange poses A_i.
std::vector<Eigen::Matrix4d> cameraPoses(const std::vector<Eigen::Matrix4d>& A) {
  std::vector<Eigen::Matrix4d> B;
  for (const auto& Ai : A) B.push_back(rigidInverse(kZ) * Ai * kX);
  return B;
}

std::vector<Eigen::Matrix4d> flangePoses(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<Eigen::Matrix4d> A;
  for (int i = 0; i < n; ++i) A.push_back(pose({0, 0, 1}, 0.2 * i, {0.5, 0, 0.4}) * randomPose(rng, 0.8, 0.2));
  return A;
}

double maxDiff(const Eigen::Matrix4d& a, const Eigen::Matrix4d& b) { return (a - b).cwiseAbs().maxCoeff(); }

}  // namespace

TEST(HandEye, ExactRecoveryWithoutNoise) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    const auto A = flangePoses(8, seed);
    const HandEyeResult r = calibrateHandEye(A, cameraPoses(A));
    ASSERT_TRUE(r.ok()) << r.message;
    EXPECT_LT(maxDiff(r.T_flange_camera_closed_form, kX), 1e-9) << "seed " << seed;
    EXPECT_LT(maxDiff(r.T_base_world_closed_form, kZ), 1e-9) << "seed " << seed;
    EXPECT_LT(maxDiff(r.T_flange_camera, kX), 1e-9) << "seed " << seed;
    EXPECT_LT(maxDiff(r.T_base_world, kZ), 1e-9) << "seed " << seed;
    EXPECT_LT(r.rms_translation, 1e-9);
    EXPECT_LT(r.rms_rotation, 1e-9);
    EXPECT_EQ(r.pairs, 28);
    EXPECT_EQ(r.residual_rotation.size(), 8);
    EXPECT_TRUE(r.converged);
  }
}

TEST(HandEye, ManyPosesUseSpreadPairsAndStayExact) {
  // beyond 64 poses: pairs j - i = 1, 2, 4, ..., 256 (500 poses: 499 + 498 + ... + 244)
  const auto A = flangePoses(500, 11);
  const HandEyeResult r = calibrateHandEye(A, cameraPoses(A));
  ASSERT_TRUE(r.ok()) << r.message;
  int expected = 0;
  for (int step = 1; step < 500; step *= 2) expected += 500 - step;
  EXPECT_LE(r.pairs, expected);  // less those rotating by over 174 deg
  EXPECT_GT(r.pairs, expected * 9 / 10);
  EXPECT_LT(maxDiff(r.T_flange_camera_closed_form, kX), 1e-9);
  EXPECT_LT(maxDiff(r.T_flange_camera, kX), 1e-9);
  EXPECT_LT(maxDiff(r.T_base_world, kZ), 1e-9);
}

TEST(HandEye, ExactRecoveryFromTargetViews) {
  const auto A = flangePoses(5, 42);
  std::vector<Eigen::Matrix4d> T_camera_target;
  for (const auto& B : cameraPoses(A)) T_camera_target.push_back(rigidInverse(B));
  HandEyeSettings s;
  s.refine = false;
  const HandEyeResult r = calibrateHandEyeFromTarget(A, T_camera_target, s);
  ASSERT_TRUE(r.ok()) << r.message;
  EXPECT_LT(maxDiff(r.T_flange_camera, kX), 1e-9);
  EXPECT_LT(maxDiff(r.T_base_world, kZ), 1e-9);  // T_base_target
  EXPECT_EQ(r.iterations, 0);
}

TEST(HandEye, RefinementLowersTheResidualOfNoisyPoses) {
  // The closed form weighs pairs, the refinement the poses: with noise on B its answer has the
  // smaller weighted residual, and both stay near the truth.
  std::mt19937 rng(7);
  std::normal_distribution<double> n(0.0, 1.0);
  const auto A = flangePoses(15, 3);
  auto B = cameraPoses(A);
  for (auto& Bi : B) {
    const Eigen::Vector3d phi(n(rng), n(rng), n(rng)), dt(n(rng), n(rng), n(rng));
    Bi = Bi * pose(phi, 2e-4 * phi.norm(), 1e-4 * dt);
  }
  const HandEyeResult r = calibrateHandEye(A, B);
  ASSERT_TRUE(r.ok()) << r.message;
  const double w = HandEyeSettings{}.rotation_weight;
  const auto cost = [&](double rot, double trans) { return trans * trans + w * w * rot * rot; };
  EXPECT_LT(cost(r.rms_rotation, r.rms_translation),
            cost(r.rms_rotation_closed_form, r.rms_translation_closed_form));
  EXPECT_GT(r.iterations, 0);
  EXPECT_TRUE(r.converged);
  EXPECT_LT((r.T_flange_camera.topRightCorner<3, 1>() - kX.topRightCorner<3, 1>()).norm(), 1e-3);
  EXPECT_LT(maxDiff(r.T_flange_camera, kX), 2e-3);
}

TEST(HandEye, HuberLossResistsOneBadView) {
  const auto A = flangePoses(12, 5);
  auto B = cameraPoses(A);
  B[4] = B[4] * pose({1, 1, 0}, 0.05, {0.02, -0.01, 0.03});  // one view 4 cm and 3 deg off
  HandEyeSettings s;
  const HandEyeResult plain = calibrateHandEye(A, B, s);
  s.huber_delta = 0.001;
  const HandEyeResult robust = calibrateHandEye(A, B, s);
  ASSERT_TRUE(plain.ok() && robust.ok());
  const double e_plain = maxDiff(plain.T_flange_camera, kX), e_robust = maxDiff(robust.T_flange_camera, kX);
  EXPECT_LT(e_robust, 0.2 * e_plain);
  // the bad view stands out in the per-pose residuals
  Eigen::Index worst = 0;
  robust.residual_translation.maxCoeff(&worst);
  EXPECT_EQ(worst, 4);
}

TEST(HandEye, PosesThatFitNoAnswerAreReported) {
  // camera poses paired with the wrong robot poses (shifted by one): no X and Z fit them
  const auto A = flangePoses(10, 9);
  auto B = cameraPoses(A);
  std::rotate(B.begin(), B.begin() + 1, B.end());
  const HandEyeResult r = calibrateHandEye(A, B);
  EXPECT_EQ(r.status, HandEyeStatus::InconsistentPoses);
  EXPECT_STREQ(toString(r.status), "inconsistent_poses");
  EXPECT_FALSE(r.ok());
  EXPECT_GT(r.rms_translation, 0.02);
  EXPECT_NE(r.message.find("paired"), std::string::npos) << r.message;
  EXPECT_EQ(r.residual_translation.size(), 10);
}

TEST(HandEye, RotationsAboutOneAxisAreRefused) {
  std::vector<Eigen::Matrix4d> A;
  for (int i = 0; i < 10; ++i) A.push_back(pose({0.1, 0.2, 1.0}, 0.3 * i, {0.1 * i, 0.02 * i * i, 0.3}));
  const HandEyeResult r = calibrateHandEye(A, cameraPoses(A));
  EXPECT_EQ(r.status, HandEyeStatus::DegenerateMotion);
  EXPECT_NE(r.message.find("parallel"), std::string::npos) << r.message;
  EXPECT_LT(r.axis_spread, 1e-6);
  EXPECT_NEAR(r.max_relative_rotation, 2.7, 1e-9);
  EXPECT_STREQ(toString(r.status), "degenerate_motion");

  // the last pose tilted by 0.2 deg: its motions' axes spread by under 2 deg (the default),
  // still refused; accepted with min_axis_angle 0.05 deg
  A[9] = A[9] * pose({1, 0, 0}, 0.2 * M_PI / 180.0, Eigen::Vector3d::Zero());
  EXPECT_EQ(calibrateHandEye(A, cameraPoses(A)).status, HandEyeStatus::DegenerateMotion);
  HandEyeSettings s;
  s.min_axis_angle = 0.05 * M_PI / 180.0;
  const HandEyeResult loose = calibrateHandEye(A, cameraPoses(A), s);
  EXPECT_TRUE(loose.ok()) << loose.message;
  EXPECT_GT(loose.axis_spread, s.min_axis_angle);
}

TEST(HandEye, TinyRotationsAreRefused) {
  std::mt19937 rng(1);
  std::vector<Eigen::Matrix4d> A;
  for (int i = 0; i < 6; ++i) A.push_back(pose({0, 0, 1}, 0.5, {0.4, 0, 0.3}) * randomPose(rng, 0.01, 0.1));
  const HandEyeResult r = calibrateHandEye(A, cameraPoses(A));
  EXPECT_EQ(r.status, HandEyeStatus::DegenerateMotion);
  EXPECT_NE(r.message.find("too small"), std::string::npos) << r.message;
  EXPECT_LT(r.max_relative_rotation, 0.03);
}

TEST(HandEye, TooFewPosesAreRefused) {
  for (int n : {0, 1, 2}) {
    const auto A = flangePoses(n, 0);
    const HandEyeResult r = calibrateHandEye(A, cameraPoses(A));
    EXPECT_EQ(r.status, HandEyeStatus::TooFewPoses) << n;
    EXPECT_FALSE(r.ok());
    EXPECT_NE(r.message.find("at least 3"), std::string::npos);
  }
}

TEST(HandEye, NonRigidOrNonFinitePosesAreNamed) {
  const auto A = flangePoses(6, 2);
  auto B = cameraPoses(A);
  B[3].topLeftCorner<3, 3>() *= 1.01;  // scaled
  HandEyeResult r = calibrateHandEye(A, B);
  EXPECT_EQ(r.status, HandEyeStatus::InvalidInput);
  EXPECT_NE(r.message.find("T_world_camera[3]"), std::string::npos) << r.message;

  auto A2 = A;
  A2[5](0, 3) = std::nan("");
  r = calibrateHandEye(A2, cameraPoses(A));
  EXPECT_EQ(r.status, HandEyeStatus::InvalidInput);
  EXPECT_NE(r.message.find("T_base_flange[5]"), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("non-finite"), std::string::npos) << r.message;

  std::vector<Eigen::Matrix4d> targets(6, Eigen::Matrix4d::Identity());
  targets[1](3, 0) = 0.5;  // last row not 0 0 0 1
  r = calibrateHandEyeFromTarget(A, targets);
  EXPECT_EQ(r.status, HandEyeStatus::InvalidInput);
  EXPECT_NE(r.message.find("T_camera_target[1]"), std::string::npos) << r.message;

  auto far = cameraPoses(A);
  far[2](1, 3) = 1e20;  // squared, still finite; but no robot cell is 1e20 m wide
  r = calibrateHandEye(A, far);
  EXPECT_EQ(r.status, HandEyeStatus::InvalidInput);
  EXPECT_NE(r.message.find("T_world_camera[2]"), std::string::npos) << r.message;
  EXPECT_NE(r.message.find("1e6 m"), std::string::npos) << r.message;

  r = calibrateHandEye(A, std::vector<Eigen::Matrix4d>(B.begin(), B.begin() + 5));
  EXPECT_EQ(r.status, HandEyeStatus::InvalidInput);
  EXPECT_NE(r.message.find("6 and 5"), std::string::npos) << r.message;
}

TEST(HandEye, InvalidSettingsThrow) {
  const auto A = flangePoses(5, 0);
  const auto B = cameraPoses(A);
  const auto expectThrow = [&](auto edit) {
    HandEyeSettings s;
    edit(s);
    EXPECT_THROW(calibrateHandEye(A, B, s), std::invalid_argument);
  };
  expectThrow([](HandEyeSettings& s) { s.rotation_weight = 0.0; });
  expectThrow([](HandEyeSettings& s) { s.rotation_weight = std::nan(""); });
  expectThrow([](HandEyeSettings& s) { s.huber_delta = -1.0; });
  expectThrow([](HandEyeSettings& s) { s.max_iterations = 0; });
  expectThrow([](HandEyeSettings& s) { s.max_rms_translation = 0.0; });
  expectThrow([](HandEyeSettings& s) { s.max_rms_rotation = -1.0; });
  expectThrow([](HandEyeSettings& s) { s.min_axis_angle = 2.0; });
  expectThrow([](HandEyeSettings& s) { s.min_relative_rotation = -0.1; });
  expectThrow([](HandEyeSettings& s) { s.step_tolerance = INFINITY; });
}

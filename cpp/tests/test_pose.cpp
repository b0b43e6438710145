// CAD-pose chain (Kleppe, PhD thesis, NTNU 2018, ch. 6-7): Valkenburg–Dorst motor estimation vs Kabsch, CBD
// keypoints and descriptors (claims 15-19), correspondence RANSAC, paper 4 flags (33-34).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "scanalign/pose/cbd.hpp"
#include "scanalign/pose/cbd_alignment.hpp"
#include "scanalign/pose/correspondence_ransac.hpp"
#include "scanalign/pose/flag_alignment.hpp"
#include "scanalign/pose/motor_estimation.hpp"

using namespace scanalign;

namespace {

Eigen::Matrix4d randomPose(std::mt19937& g, double t_scale) {
  std::normal_distribution<double> n(0, 1);
  Eigen::Vector3d axis(n(g), n(g), n(g));
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = Eigen::AngleAxisd(std::fmod(std::abs(n(g)) * 2.0, 3.1), axis.normalized()).toRotationMatrix();
  T.topRightCorner<3, 1>() = t_scale * Eigen::Vector3d(n(g), n(g), n(g));
  return T;
}

std::vector<double> transformed(const std::vector<double>& p, const Eigen::Matrix4d& T) {
  std::vector<double> out(p.size());
  for (std::size_t i = 0; i < p.size() / 3; ++i) {
    const Eigen::Vector3d y = T.topLeftCorner<3, 3>() * Eigen::Vector3d(p[3 * i], p[3 * i + 1], p[3 * i + 2]) +
                              T.topRightCorner<3, 1>();
    for (int k = 0; k < 3; ++k) out[3 * i + k] = y(k);
  }
  return out;
}

/// A closed, non-symmetric test surface: an ellipsoid with a bump, sampled on a grid in
/// (u, v); `partial` keeps only the z > -0.2 part (a single-view-like cap).
std::vector<double> bumpyEllipsoid(int n, bool partial, std::vector<double>* normals = nullptr) {
  std::vector<double> p;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < 2 * n; ++j) {
      const double th = M_PI * (i + 0.5) / n, ph = 2 * M_PI * j / (2 * n);
      const double r = 1.0 + 0.3 * std::exp(-8 * ((th - 1.0) * (th - 1.0) + (ph - 1.0) * (ph - 1.0)));
      const Eigen::Vector3d x(0.05 * r * std::sin(th) * std::cos(ph), 0.03 * r * std::sin(th) * std::sin(ph),
                              0.02 * r * std::cos(th));
      if (partial && x.z() < -0.004) continue;
      p.insert(p.end(), {x.x(), x.y(), x.z()});
      if (normals) {
        // Normal of the smooth ellipsoid (the bump's slope is ignored: fine for the flags test).
        const Eigen::Vector3d nn = Eigen::Vector3d(x.x() / 0.0025, x.y() / 0.0009, x.z() / 0.0004).normalized();
        normals->insert(normals->end(), {nn.x(), nn.y(), nn.z()});
      }
    }
  return p;
}

}  // namespace

TEST(MotorEstimation, ExactOnNoiseFreePairsAndEqualToSvdOnNoisyOnes) {  // paper 5 §III-E
  std::mt19937 g(7);
  std::normal_distribution<double> n(0, 1);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Matrix4d T = randomPose(g, trial % 2 ? 5.0 : 0.1);  // also large translations
    std::vector<double> x(3 * 40);
    for (double& v : x) v = 0.1 * n(g);
    std::vector<double> y = transformed(x, T);
    const CloudView<double> xs(x.data(), 40), ys(y.data(), 40);
    for (bool normalize : {true, false}) {
      const MotorEstimationResult m = estimateMotor(xs, ys, nullptr, normalize);
      ASSERT_TRUE(m.valid);
      EXPECT_LT((m.T_target_source - T).cwiseAbs().maxCoeff(), 1e-9) << "trial " << trial;
      EXPECT_NEAR(m.motor.head<4>().norm(), 1.0, 1e-12);
    }
    for (double& v : y) v += 0.003 * n(g);
    const MotorEstimationResult a = estimateMotor(xs, ys), b = estimateRigidSvd(xs, ys);
    const MotorEstimationResult c = estimateMotor(xs, ys, nullptr, false);
    EXPECT_LT((a.T_target_source - b.T_target_source).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LT((c.T_target_source - b.T_target_source).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_NEAR(a.rmse, b.rmse, 1e-12);
  }
}

TEST(MotorEstimation, WeightsActLikeDuplicatedPairsAndDegenerateInputIsReported) {
  std::mt19937 g(3);
  std::normal_distribution<double> n(0, 1);
  std::vector<double> x(3 * 10), y(3 * 10), w(10);
  for (double& v : x) v = n(g);
  for (double& v : y) v = n(g);
  for (int i = 0; i < 10; ++i) w[i] = 1 + (i % 3);
  std::vector<double> xd, yd;
  for (int i = 0; i < 10; ++i)
    for (int r = 0; r < w[i]; ++r) {
      xd.insert(xd.end(), x.begin() + 3 * i, x.begin() + 3 * i + 3);
      yd.insert(yd.end(), y.begin() + 3 * i, y.begin() + 3 * i + 3);
    }
  const MotorEstimationResult a = estimateMotor({x.data(), 10}, {y.data(), 10}, w.data());
  const MotorEstimationResult b = estimateMotor({xd.data(), xd.size() / 3}, {yd.data(), yd.size() / 3});
  EXPECT_LT((a.T_target_source - b.T_target_source).cwiseAbs().maxCoeff(), 1e-9);
  const std::vector<double> line = {0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0};
  EXPECT_FALSE(estimateMotor({line.data(), 4}, {line.data(), 4}).valid);
  EXPECT_FALSE(estimateRigidSvd({line.data(), 2}, {line.data(), 2}).valid);
  EXPECT_THROW(estimateMotor({x.data(), 10}, {y.data(), 9}), std::invalid_argument);
  x[4] = NAN;
  EXPECT_THROW(estimateMotor({x.data(), 10}, {y.data(), 10}), std::invalid_argument);
}

TEST(CorrespondenceRansac, RecoversThePoseFromMostlyWrongPairs) {
  std::mt19937 g(11);
  std::normal_distribution<double> n(0, 1);
  std::uniform_int_distribution<std::uint32_t> pick(0, 499);
  std::vector<double> x(3 * 500);
  for (double& v : x) v = 0.05 * n(g);
  const Eigen::Matrix4d T = randomPose(g, 0.2);
  const std::vector<double> y = transformed(x, T);
  std::vector<std::uint32_t> pairs;
  for (std::uint32_t i = 0; i < 500; ++i) pairs.insert(pairs.end(), {i, i % 5 == 0 ? i : pick(g)});  // ~80 % outliers
  CorrespondenceRansacSettings s;
  s.max_iterations = 5000;
  s.inlier_threshold = 0.002;
  for (int threads : {1, 2}) {
    s.num_threads = threads;
    const auto r = ransacRigidMotion({x.data(), 500}, {y.data(), 500}, pairs.data(), 500, s);
    ASSERT_TRUE(r.found);
    EXPECT_LT((r.T_target_source - T).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_GE(r.inliers.size(), 100u);
    EXPECT_LE(r.inliers.size(), 110u);
  }
  const auto none = ransacRigidMotion({x.data(), 500}, {y.data(), 500}, pairs.data(), 2, s);
  EXPECT_FALSE(none.found);
  pairs[1] = 999;
  EXPECT_THROW(ransacRigidMotion({x.data(), 500}, {y.data(), 500}, pairs.data(), 500, s), std::invalid_argument);
}

TEST(Cbd, KeypointThresholdsAndAutomaticModeFollowTheThesis) {  // claims 15-17
  std::vector<NeighbourhoodPca> p(4);
  p[0] = {300, {1, 0, 0}};       // line: C_l = 1
  p[1] = {300, {1, 1, 0}};       // plane: C_p = 1
  p[2] = {300, {1, 1, 1}};       // isotropic: C_s = 1
  p[3] = {100, {1, 0, 0}};       // too few neighbours
  for (int i = 0; i < 3; ++i) {
    const auto f = shapeFactorsOf(p[i]);
    EXPECT_NEAR(f.linear + f.planar + f.spherical, 1.0, 1e-15);
  }
  EXPECT_DOUBLE_EQ(shapeFactorsOf(p[0]).linear, 1.0);
  EXPECT_DOUBLE_EQ(shapeFactorsOf(p[1]).planar, 1.0);
  EXPECT_DOUBLE_EQ(shapeFactorsOf(p[2]).spherical, 1.0);
  // δ_p = 1 disables the planar term even for C_p = 1; n_min rejects point 3 ((6.4)).
  EXPECT_EQ(selectKeypoints(p, {0.3, 1.0, 0.3}, 200), (std::vector<std::uint32_t>{0, 2}));
  EXPECT_EQ(selectKeypoints(p, {1.0, 0.5, 1.0}, 200), (std::vector<std::uint32_t>{1}));
  EXPECT_EQ(selectKeypoints(p, {0.3, 1.0, 0.3}, 50), (std::vector<std::uint32_t>{0, 2, 3}));
  EXPECT_DOUBLE_EQ(keypointScore(p[3], 200), 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(keypointScore(p[0], 200), 0.0);
  // Automatic mode (paper 5 §III-B4): random shapes; the derived δ's re-select the keypoints.
  std::mt19937 g(5);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<NeighbourhoodPca> q(1000);
  for (auto& e : q) e = {static_cast<std::uint32_t>(150 + 100 * u(g)), {1.0, u(g), 0.3 * u(g) * u(g)}};
  ShapeThresholds t;
  const auto keys = automaticKeypoints(q, 100, 200, &t);
  ASSERT_EQ(keys.size(), 100u);
  const auto again = selectKeypoints(q, t, 200, true);
  for (auto k : keys) EXPECT_TRUE(std::binary_search(again.begin(), again.end(), k));
  for (auto k : again) EXPECT_GE(q[k].count, 200u);
}

TEST(Cbd, DescriptorsAreInvariantToRigidMotionAndMatchThemselves) {  // claims 18-20
  const std::vector<double> x = bumpyEllipsoid(120, false);
  std::mt19937 g(2);
  const Eigen::Matrix4d T = randomPose(g, 0.3);
  const std::vector<double> y = transformed(x, T);
  CbdSettings s;
  s.min_neighbors = 0;  // automatic n_min for this grid's density
  s.radius = 0.006;
  s.keypoint_mode = CbdKeypointMode::Automatic;  // a smooth surface: no edge passes (6.4)
  s.num_keypoints = 400;
  const CloudView<double> xs(x.data(), x.size() / 3), ys(y.data(), y.size() / 3);
  const CbdFeatures a = computeCbd(xs, s), b = computeCbd(ys, s);
  ASSERT_GT(a.keypoints.size(), 50u);
  ASSERT_EQ(a.keypoints, b.keypoints);  // same points: the shape factors are motion invariant
  for (std::size_t i = 0; i < a.keypoints.size(); ++i) {
    EXPECT_LT((a.descriptors[i] - b.descriptors[i]).cwiseAbs().maxCoeff(), 1e-7);
    EXPECT_NEAR(a.scalar[i], b.scalar[i], 1e-9);
    for (const CbdSphere* sp : {&a.sphere1[i], &a.sphere2[i]}) {
      if (sp->flat) continue;
      // (6.14)-(6.16): F term = S·P for the e0-normalised sphere, S·P = ½(r² − d²)
      const Eigen::Vector3d c = sp->dual.head<3>();
      const Eigen::Vector3d p(x[3 * a.keypoints[i]], x[3 * a.keypoints[i] + 1], x[3 * a.keypoints[i] + 2]);
      EXPECT_NEAR((c - p).norm(), sp->distance, 1e-9);
      Eigen::Matrix<double, 5, 1> P;
      P << p, 0.5 * p.squaredNorm(), 1.0;
      const double SP = sp->dual.head<3>().dot(P.head<3>()) - sp->dual(3) * P(4) - sp->dual(4) * P(3);
      EXPECT_NEAR(SP, 0.5 * (sp->radius * sp->radius - sp->distance * sp->distance), 1e-12);
    }
  }
  // Self-alignment (paper 5 Exp. 1): most keypoints match themselves (the ellipsoid's mirror
  // symmetries, broken only near the bump, make the rest ambiguous).
  const CbdMatches m = matchCbd(a, b, CbdDescriptorVariant::RadiusDistance);
  std::size_t same = 0;
  for (std::size_t k = 0; k < m.source.size(); ++k) same += m.source[k] == m.target[k];
  EXPECT_GT(double(same) / m.source.size(), 0.6);
  CbdAlignmentSettings as;
  as.cbd = s;
  as.ransac.inlier_threshold = 0.001;
  // MSAC ranking: on this near-symmetric ellipsoid the answer does not hang on the seed.
  for (std::uint64_t seed = 1; seed < 4; ++seed) {
    as.ransac.seed = seed;
    const CbdAlignmentResult q = alignCbd(xs, ys, as);
    ASSERT_TRUE(q.found) << q.message;
    EXPECT_LT((q.T_target_source - T).cwiseAbs().maxCoeff(), 1e-3) << "seed " << seed;
  }
  as.ransac.seed = 0;
  const CbdAlignmentResult r = alignCbd(xs, ys, as);
  ASSERT_TRUE(r.found) << r.message;
  // Coarse only: near-miss matches within the 1 mm threshold enter the refit (ICP removes the rest).
  EXPECT_LT((r.T_target_source - T).cwiseAbs().maxCoeff(), 1e-3);
  EXPECT_GT(r.fitness, 0.99);
}

TEST(Cbd, TooSparseCloudsGiveNoKeypointsAndNoPoseInsteadOfAnError) {
  const std::vector<double> x = bumpyEllipsoid(10, false);
  const CloudView<double> xs(x.data(), x.size() / 3);
  EXPECT_TRUE(computeCbd(xs, CbdSettings{}).keypoints.empty());  // n_min = 200 cannot be met
  const CbdAlignmentResult r = alignCbd(xs, xs);
  EXPECT_FALSE(r.found);
  EXPECT_FALSE(r.message.empty());
  CbdSettings bad;
  bad.radius = -1;
  EXPECT_THROW(computeCbd(xs, bad), std::invalid_argument);
}

TEST(FlagAlignment, RecoversTheMotionOfAPartialViewAndRefusesClosedSurfaces) {  // claims 33-34
  std::vector<double> nx;
  const std::vector<double> x = bumpyEllipsoid(80, true, &nx);
  std::mt19937 g(9);
  const Eigen::Matrix4d T = randomPose(g, 0.2);
  const std::vector<double> y = transformed(x, T);
  Eigen::Matrix4d Tr = T;
  Tr.topRightCorner<3, 1>().setZero();
  const std::vector<double> ny = transformed(nx, Tr);
  const auto r = alignFlags(CloudView<double>(x.data(), x.size() / 3), CloudView<double>(nx.data(), nx.size() / 3),
                            CloudView<double>(y.data(), y.size() / 3), CloudView<double>(ny.data(), ny.size() / 3));
  ASSERT_TRUE(r.valid) << r.message;
  EXPECT_LT((r.T_target_source - T).cwiseAbs().maxCoeff(), 1e-8);
  EXPECT_LT(r.cost, 1e-16);
  // Closed surface: a sphere sampled uniformly; the normals cancel.
  std::vector<double> s, ns;
  std::mt19937 h(1);
  std::normal_distribution<double> n(0, 1);
  for (int i = 0; i < 20000; ++i) {
    Eigen::Vector3d v(n(h), n(h), n(h));
    v.normalize();
    s.insert(s.end(), {0.05 * v.x(), 0.05 * v.y(), 0.05 * v.z()});
    ns.insert(ns.end(), {v.x(), v.y(), v.z()});
  }
  const CloudView<double> sv(s.data(), 20000), nv(ns.data(), 20000);
  EXPECT_LT(normalLineFlag(sv, nv).mean_normal_length, 0.03);
  const auto closed = alignFlags(sv, nv, sv, nv);
  EXPECT_FALSE(closed.valid);
  EXPECT_NE(closed.message.find("closed"), std::string::npos);
}

// Five points, collinear points and 1e30 m coordinates used to be aligned "valid".
TEST(FlagAlignment, RefusesTooFewCollinearAndHugeClouds) {
  std::vector<double> nx;
  const std::vector<double> x = bumpyEllipsoid(80, true, &nx);
  const CloudView<double> xv(x.data(), x.size() / 3), nv(nx.data(), nx.size() / 3);
  const CloudView<double> x5(x.data(), 5), n5(nx.data(), 5);
  const auto five = alignFlags(x5, n5, xv, nv);
  EXPECT_FALSE(five.valid);
  EXPECT_NE(five.message.find("min_points"), std::string::npos);
  std::vector<double> line;
  for (int i = 0; i < 100; ++i) line.insert(line.end(), {0.001 * i, 0.0, 0.0});
  const auto collinear = alignFlags(CloudView<double>(line.data(), 100), CloudView<double>(nx.data(), 100), xv, nv);
  EXPECT_FALSE(collinear.valid);
  EXPECT_NE(collinear.message.find("collinear"), std::string::npos);
  std::vector<double> huge = x;
  for (double& v : huge) v *= 1e30;
  EXPECT_THROW(alignFlags(CloudView<double>(huge.data(), huge.size() / 3), nv, xv, nv), std::invalid_argument);
}

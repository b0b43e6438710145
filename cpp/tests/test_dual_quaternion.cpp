// The dual-quaternion point-to-point estimator (Walker, Shao & Volz 1991) against known
// motions and the SVD closed form (solvePointToPoint) on the same sums; the engine's ICP with
// it against a known motion. PCL-free (PCL's own dual-quaternion estimator: test_lls.cpp).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "scanalign/common/mesh_sampling.hpp"
#include "scanalign/registration/dual_quaternion.hpp"
#include "scanalign/registration/icp.hpp"
#include "scanalign/registration/point_to_point.hpp"
#include "scanalign/synthetic/builtin_part.hpp"
#include "test_support.hpp"

using namespace scanalign;

namespace {

constexpr double kPi = 3.14159265358979323846;

Eigen::Matrix4d pose(const Eigen::Vector3d& axis, double angle, const Eigen::Vector3d& t) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  T.topRightCorner<3, 1>() = t;
  return T;
}

struct Pairs {
  std::vector<Eigen::Vector3d> src, dst;
};

/// n source points around a camera-like centre, and their images under T plus noise (m).
Pairs pairs(const Eigen::Matrix4d& T, int n, double noise, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  std::normal_distribution<double> g(0.0, noise);
  Pairs p;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d x = Eigen::Vector3d(0.1, -0.05, 0.7) + Eigen::Vector3d(u(rng), u(rng), u(rng));
    Eigen::Vector3d y = T.topLeftCorner<3, 3>() * x + T.topRightCorner<3, 1>();
    if (noise > 0) y += Eigen::Vector3d(g(rng), g(rng), g(rng));
    p.src.push_back(x);
    p.dst.push_back(y);
  }
  return p;
}

PointToPointSystem systemOf(const Pairs& p) {
  PointToPointSystem sys;
  for (std::size_t i = 0; i < p.src.size(); ++i) sys.add(p.src[i].data(), p.dst[i].data());
  return sys;
}

double cost(const Pairs& p, const Eigen::Matrix4d& T) {
  double c = 0.0;
  for (std::size_t i = 0; i < p.src.size(); ++i)
    c += (T.topLeftCorner<3, 3>() * p.src[i] + T.topRightCorner<3, 1>() - p.dst[i]).squaredNorm();
  return c;
}

double maxAbs(const Eigen::Matrix4d& A, const Eigen::Matrix4d& B) { return (A - B).cwiseAbs().maxCoeff(); }

/// Random poses: uniform axes, angles over [0, pi] and at (or within 1e-9..1e-3 rad of) pi,
/// where the quaternion's scalar part vanishes.
std::vector<Eigen::Matrix4d> poses(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> angle(0.0, kPi), shift(-1.0, 1.0);
  std::vector<Eigen::Matrix4d> out;
  for (int k = 0; k < 200; ++k) {
    const Eigen::Vector3d axis(g(rng), g(rng), g(rng)), t(shift(rng), shift(rng), shift(rng));
    const double a = k < 150 ? angle(rng) : kPi - (k % 5 == 0 ? 0.0 : std::pow(10.0, -9.0 + 6.0 * (k % 5) / 4.0));
    out.push_back(pose(axis, a, t));
  }
  out.push_back(pose(Eigen::Vector3d::UnitX(), kPi, Eigen::Vector3d::Zero()));  // axis-aligned half turns
  out.push_back(pose(Eigen::Vector3d::UnitZ(), kPi, Eigen::Vector3d(0.3, 0, 0)));
  out.push_back(Eigen::Matrix4d::Identity());
  return out;
}

}  // namespace

TEST(DualQuaternion, NoiseFreeEqualsTheTruthAndTheSvdIncludingHalfTurns) {
  std::mt19937 rng(11);
  double worst_svd = 0.0, worst_true = 0.0;
  for (const Eigen::Matrix4d& T_true : poses(rng)) {
    const Pairs p = pairs(T_true, 40, 0.0, rng);
    const PointToPointSystem sys = systemOf(p);
    const PointToPointSolve dq = solveDualQuaternion(sys), svd = solvePointToPoint(sys);
    ASSERT_FALSE(dq.degenerate);
    EXPECT_EQ(dq.rank, svd.rank);
    worst_svd = std::max(worst_svd, maxAbs(dq.T, svd.T));
    worst_true = std::max(worst_true, maxAbs(dq.T, T_true));
    EXPECT_LT(maxAbs(dq.T, svd.T), 1e-10) << T_true;
    EXPECT_LT(maxAbs(dq.T, T_true), 1e-10) << T_true;
    EXPECT_LT((dq.T.topLeftCorner<3, 3>().transpose() * dq.T.topLeftCorner<3, 3>() - Eigen::Matrix3d::Identity())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-12);
    EXPECT_NEAR((dq.T.topLeftCorner<3, 3>().determinant()), 1.0, 1e-12);
  }
  std::printf("[ measured ] noise-free: max |DQ - SVD| = %.3g, max |DQ - truth| = %.3g\n", worst_svd, worst_true);
}

TEST(DualQuaternion, NoisyEqualsTheSvdLeastSquaresAnswer) {
  std::mt19937 rng(12);
  double worst = 0.0;
  for (const Eigen::Matrix4d& T_true : poses(rng)) {
    for (double noise : {0.001, 0.01, 0.05}) {
      const Pairs p = pairs(T_true, 60, noise, rng);
      const PointToPointSystem sys = systemOf(p);
      const PointToPointSolve dq = solveDualQuaternion(sys), svd = solvePointToPoint(sys);
      worst = std::max(worst, maxAbs(dq.T, svd.T));
      EXPECT_LT(maxAbs(dq.T, svd.T), 1e-9) << "noise " << noise << "\n" << T_true;
      EXPECT_NEAR(cost(p, dq.T), cost(p, svd.T), 1e-12 * (1.0 + cost(p, svd.T)));
      // Least squares: no nearby rigid motion does better.
      EXPECT_LE(cost(p, dq.T), cost(p, pose(Eigen::Vector3d(1, 2, 3), 1e-4, Eigen::Vector3d(1e-5, 0, 0)) * dq.T));
    }
  }
  std::printf("[ measured ] noisy: max |DQ - SVD| = %.3g\n", worst);
}

TEST(DualQuaternion, DegenerateInputsAreFlaggedWithoutNaN) {
  const Eigen::Vector3d shift(0.01, -0.02, 0.03);
  std::vector<Pairs> cases(4);
  for (int i = 0; i < 30; ++i) {
    const Eigen::Vector3d on_line(0.1 + 0.01 * i, 0.2 + 0.02 * i, 0.7 - 0.005 * i), same(0.1, 0.2, 0.7);
    cases[0].src.push_back(on_line), cases[0].dst.push_back(on_line + shift);  // collinear
    cases[1].src.push_back(same), cases[1].dst.push_back(same + shift);        // coincident
    cases[2].src.push_back(on_line), cases[2].dst.push_back(same);             // targets coincide
  }
  cases[3].src.push_back(Eigen::Vector3d(0.1, 0.2, 0.7)), cases[3].dst.push_back(Eigen::Vector3d(0.1, 0.2, 0.7) + shift);
  for (std::size_t k = 0; k < cases.size(); ++k) {
    const PointToPointSystem sys = systemOf(cases[k]);
    const PointToPointSolve dq = solveDualQuaternion(sys), svd = solvePointToPoint(sys);
    EXPECT_TRUE(dq.degenerate) << k;
    EXPECT_LT(dq.rank, 2) << k;
    EXPECT_EQ(dq.rank, svd.rank) << k;
    EXPECT_TRUE(dq.T.allFinite()) << k;
    EXPECT_TRUE((dq.T.topLeftCorner<3, 3>().isIdentity())) << k;  // the translation of the means only
    EXPECT_TRUE(dq.T == svd.T) << k;
  }
  EXPECT_NEAR(solveDualQuaternion(systemOf(cases[0])).T(2, 3), shift.z(), 1e-15);
  const PointToPointSolve none = solveDualQuaternion(PointToPointSystem{});  // no pairs at all
  EXPECT_TRUE(none.degenerate);
  EXPECT_TRUE(none.T.isIdentity());
}

TEST(IcpEngine, DualQuaternionEstimatorRecoversAKnownMotionOnTheBuiltinPart) {
  // The built-in block (planar faces, a boss and a spherical cap) seen from a moved camera.
  const MeshSamples part = sampleBuiltinBlock(20000, 3);
  std::vector<double> model;
  for (const auto& p : part.points) model.insert(model.end(), {p.x(), p.y(), p.z()});
  const Eigen::Matrix4d T_true = test::rigid(0.05, -0.04, 0.06, 0.004, -0.003, 0.005);
  std::vector<double> source;
  const Eigen::Matrix4d T_inv = T_true.inverse();
  for (const auto& p : part.points) {
    const Eigen::Vector3d q = T_inv.topLeftCorner<3, 3>() * p + T_inv.topRightCorner<3, 1>();
    source.insert(source.end(), {q.x(), q.y(), q.z()});
  }
  Eigen::Matrix4d results[2];
  for (int k = 0; k < 2; ++k) {
    IcpSettings settings;
    settings.estimator = k == 0 ? IcpEstimator::DualQuaternion : IcpEstimator::PointToPoint;
    settings.max_iterations = 500;
    settings.max_correspondence_distance = 0.02;
    EXPECT_STREQ(toString(settings.estimator), k == 0 ? "dual_quaternion" : "point_to_point");
    Icp<double> icp(settings);
    icp.setTarget(CloudView<double>(model.data(), model.size() / 3));
    const IcpResult r = icp.align(CloudView<double>(source.data(), source.size() / 3));
    EXPECT_TRUE(r.converged) << toString(r.status);
    EXPECT_FALSE(r.degenerate);
    EXPECT_LT(test::rotationError(r.T_target_source, T_true), 1e-6);
    EXPECT_LT(test::translationError(r.T_target_source, T_true), 1e-6);
    results[k] = r.T_target_source;
  }
  // Each iteration solves the same least-squares problem: the same path to the same answer.
  EXPECT_LT(maxAbs(results[0], results[1]), 1e-9);
}

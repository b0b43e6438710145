// Shape factors (Kleppe, PhD thesis, NTNU 2018, (6.1)-(6.3)) against analytic truth and PCA of
// sampled line / plane / ball point sets.
#include <random>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "scanalign/features/shape_factors.hpp"

using scanalign::shapeFactors;

namespace {
Eigen::Vector3d pcaEigenvalues(const Eigen::Matrix3Xd& p) {
  const Eigen::Vector3d mean = p.rowwise().mean();
  const Eigen::Matrix3Xd q = p.colwise() - mean;
  const Eigen::Matrix3d C = q * q.transpose();  // P5(11), no 1/n
  return Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(C).eigenvalues();  // ascending
}
}  // namespace

TEST(ShapeFactors, SumToOneAndIdealShapes) {
  std::mt19937 g(7);
  std::uniform_real_distribution<double> u(0.0, 2.0);
  for (int i = 0; i < 200; ++i) {
    const auto f = shapeFactors(u(g), u(g), u(g));
    EXPECT_NEAR(f.linear + f.planar + f.spherical, 1.0, 1e-12);
    EXPECT_GE(f.linear, 0);
    EXPECT_GE(f.planar, 0);
    EXPECT_GE(f.spherical, 0);
  }
  const auto line = shapeFactors(2.5, 0, 0);
  EXPECT_DOUBLE_EQ(line.linear, 1.0);
  const auto plane = shapeFactors(1.5, 1.5, 0);
  EXPECT_DOUBLE_EQ(plane.planar, 1.0);
  const auto ball = shapeFactors(0.3, 0.3, 0.3);
  EXPECT_DOUBLE_EQ(ball.spherical, 1.0);
  // (6.1)-(6.3) by hand: l = (3, 2, 1), S = 6 -> (1/6, 2/6, 3/6); order does not matter.
  const auto f = shapeFactors(1, 3, 2);
  EXPECT_NEAR(f.linear, 1.0 / 6, 1e-15);
  EXPECT_NEAR(f.planar, 2.0 / 6, 1e-15);
  EXPECT_NEAR(f.spherical, 3.0 / 6, 1e-15);
}

TEST(ShapeFactors, RejectsInvalid) {
  EXPECT_THROW(shapeFactors(1, -0.1, 0), std::invalid_argument);
  EXPECT_THROW(shapeFactors(1, std::nan(""), 0), std::invalid_argument);
  EXPECT_THROW(shapeFactors(0, 0, 0), std::invalid_argument);
}

TEST(ShapeFactors, PcaOfSampledShapesGivesDominantFactor) {
  std::mt19937 g(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const int n = 2000;
  Eigen::Matrix3Xd line(3, n), plane(3, n), ball(3, n);
  const Eigen::Vector3d d = Eigen::Vector3d(1, 2, -0.5).normalized();
  for (int i = 0; i < n; ++i) {
    line.col(i) = Eigen::Vector3d(0.1, -0.2, 0.3) + u(g) * d + 1e-3 * Eigen::Vector3d(u(g), u(g), u(g));
    plane.col(i) = Eigen::Vector3d(u(g), u(g), 1e-3 * u(g));
    Eigen::Vector3d b;
    do b = Eigen::Vector3d(u(g), u(g), u(g)); while (b.norm() > 1);
    ball.col(i) = b;
  }
  const auto fl = shapeFactors(pcaEigenvalues(line));
  EXPECT_GT(fl.linear, 0.95);
  const auto fp = shapeFactors(pcaEigenvalues(plane));
  EXPECT_GT(fp.planar, 0.95);
  const auto fb = shapeFactors(pcaEigenvalues(ball));
  EXPECT_GT(fb.spherical, 0.85);
  EXPECT_GT(fb.spherical, fb.linear + fb.planar);
}

// Eigenvalues near the top of the double range (coordinates of ~1e154 m) used to overflow
// their sum into inf and give NaN / zero factors; the factors are scale-free.
TEST(ShapeFactors, HugeEigenvaluesStayFinite) {
  const auto ball = shapeFactors(1e308, 1e308, 1e308);
  EXPECT_DOUBLE_EQ(ball.spherical, 1.0);
  const auto f = shapeFactors(1e300, 3e300, 2e300);
  EXPECT_NEAR(f.linear, 1.0 / 6, 1e-15);
  EXPECT_NEAR(f.planar, 2.0 / 6, 1e-15);
  EXPECT_NEAR(f.spherical, 3.0 / 6, 1e-15);
}

// CGA sphere fit (Kleppe, PhD thesis, NTNU 2018, (5.26)-(5.34), (6.5)-(6.11)) and Pratt's circle fit ((5.1)-(5.25)), checked
// against analytic spheres, planes and circles.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "scanalign/fitting/sphere_fit.hpp"

using scanalign::CloudView;
using scanalign::fitCirclePratt;
using scanalign::fitSphere;
using scanalign::fitSpheres;

namespace {

std::vector<double> spherePoints(const Eigen::Vector3d& c, double r, int n, std::mt19937& rng, double noise = 0,
                                 double max_polar = M_PI) {
  std::normal_distribution<double> g(0, 1);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> pts;
  for (int i = 0; i < n; ++i) {
    const double ct = 1 - u(rng) * (1 - std::cos(max_polar)), phi = 2 * M_PI * u(rng);
    const double st = std::sqrt(std::max(0.0, 1 - ct * ct));
    const Eigen::Vector3d d(st * std::cos(phi), st * std::sin(phi), ct);
    const Eigen::Vector3d p = c + (r + noise * g(rng)) * d;
    pts.insert(pts.end(), {p.x(), p.y(), p.z()});
  }
  return pts;
}

CloudView<double> view(const std::vector<double>& v) { return CloudView<double>(v.data(), v.size() / 3); }

}  // namespace

TEST(SphereFit, ExactPointsOnRandomSpheres) {  // thesis (5.31)
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-5, 5), ur(0.01, 3);
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Vector3d c(u(rng), u(rng), u(rng));
    const double r = ur(rng);
    const auto pts = spherePoints(c, r, 5 + trial, rng);
    const auto fit = fitSphere(view(pts));
    ASSERT_FALSE(fit.is_plane);
    EXPECT_FALSE(fit.imaginary);
    EXPECT_LT((fit.center - c).norm(), 1e-9 * (1 + c.norm()));
    EXPECT_NEAR(fit.radius, r, 1e-9 * (1 + c.norm()));
    EXPECT_LT(fit.rms, 1e-9);
    EXPECT_NEAR(fit.objective, 0.0, 1e-12);
    EXPECT_EQ(fit.count, static_cast<std::size_t>(5 + trial));
    EXPECT_DOUBLE_EQ(fit.dual(4), 1.0);
    EXPECT_NEAR(fit.dual(3), 0.5 * (c.squaredNorm() - r * r), 1e-8 * (1 + c.squaredNorm()));
  }
}

TEST(SphereFit, FloatInput) {
  std::mt19937 rng(2);
  const auto pts = spherePoints({0.1, -0.2, 0.4}, 0.05, 100, rng);
  std::vector<float> f(pts.begin(), pts.end());
  const auto fit = fitSphere(CloudView<float>(f.data(), 100));
  EXPECT_LT((fit.center - Eigen::Vector3d(0.1, -0.2, 0.4)).norm(), 1e-6);
  EXPECT_NEAR(fit.radius, 0.05, 1e-6);
}

TEST(SphereFit, ObjectiveIsEigenvalueAndOneNegativeEigenvalue) {  // thesis (5.29)-(5.31)
  std::mt19937 rng(3);
  const Eigen::Vector3d c(1, 2, 3);
  const auto pts = spherePoints(c, 0.5, 200, rng, 0.01, 1.0);
  const auto fit = fitSphere(view(pts));
  // L(S) = mean (S*·P)²/S*² evaluated directly with the 5x5 metric (5.27, 5.32).
  const auto M = scanalign::cga5::metric();
  double L = 0;
  Eigen::Matrix<double, 5, 5> Q = Eigen::Matrix<double, 5, 5>::Zero();
  for (std::size_t i = 0; i < pts.size() / 3; ++i) {
    const auto P = scanalign::cga5::up(Eigen::Vector3d(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]));
    const double sp = fit.dual.dot(M * P);
    L += sp * sp / fit.dual.dot(M * fit.dual);
    Q += P * P.transpose() * M;
  }
  L /= 200, Q /= 200;
  EXPECT_NEAR(fit.objective, L, 1e-9 * L);
  // Q[S*] = λ[S*] (5.31) and Q has exactly one negative eigenvalue.
  EXPECT_LT((Q * fit.dual - fit.objective * fit.dual).norm(), 1e-6 * fit.dual.norm());
  const Eigen::VectorXcd ev = Q.eigenvalues();
  int negative = 0;
  double smallest_positive = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 5; ++i) {
    EXPECT_NEAR(ev(i).imag(), 0.0, 1e-9);
    negative += ev(i).real() < -1e-12;
    if (ev(i).real() > 0) smallest_positive = std::min(smallest_positive, ev(i).real());
  }
  EXPECT_EQ(negative, 1);
  // the fit picks the smallest positive eigenvalue of the (non-symmetric) Q, computed directly
  // (the direct eigensolve of the raw, unnormalized Q is the less accurate side: ~1e-8 relative)
  EXPECT_NEAR(fit.objective, smallest_positive, 1e-6 * smallest_positive);
}

TEST(SphereFit, NoisyCapWithinNoise) {
  std::mt19937 rng(4);
  const Eigen::Vector3d c(0.3, -0.1, 0.8);
  const double r = 0.04, sigma = 2e-4;
  const auto pts = spherePoints(c, r, 2000, rng, sigma, M_PI / 3);
  const auto fit = fitSphere(view(pts));
  EXPECT_LT((fit.center - c).norm(), 5e-4);
  EXPECT_NEAR(fit.radius, r, 5e-4);
  EXPECT_NEAR(fit.rms, sigma, 0.2 * sigma);
}

TEST(SphereFit, CoplanarPointsGiveAPlane) {  // thesis (5.26)-(5.34)
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  const Eigen::Vector3d n = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
  const double delta = 1.7;
  const Eigen::Vector3d a = n.unitOrthogonal(), b = n.cross(a);
  std::vector<double> pts;
  for (int i = 0; i < 30; ++i) {
    const Eigen::Vector3d p = delta * n + u(rng) * a + u(rng) * b;
    pts.insert(pts.end(), {p.x(), p.y(), p.z()});
  }
  const auto fit = fitSphere(view(pts));
  ASSERT_TRUE(fit.is_plane);
  EXPECT_LT((fit.normal - n).norm(), 1e-9);
  EXPECT_NEAR(fit.distance, delta, 1e-9);
  EXPECT_LT(fit.rms, 1e-9);
  EXPECT_DOUBLE_EQ(fit.dual(4), 0.0);
  EXPECT_FALSE(std::isfinite(fit.radius));
}

TEST(SphereFit, WeightsZeroRemovesIntegerDuplicates) {  // thesis (6.6)
  std::mt19937 rng(6);
  auto pts = spherePoints({0, 0, 1}, 0.2, 40, rng, 0.01, 1.2);
  std::vector<double> w(40);
  std::uniform_int_distribution<int> k(0, 3);
  for (auto& x : w) x = k(rng);
  w[0] = 1, w[1] = 1, w[2] = 2, w[3] = 3, w[4] = 1;
  // duplicated cloud
  std::vector<double> dup;
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < static_cast<int>(w[i]); ++j) dup.insert(dup.end(), {pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]});
  // a zero-weight point may be anything, even NaN
  for (int i = 5; i < 40; ++i)
    if (w[i] == 0) pts[3 * i] = std::nan("");
  const auto fw = fitSphere(view(pts), w.data());
  const auto fd = fitSphere(view(dup));
  EXPECT_LT((fw.center - fd.center).norm(), 1e-10);
  EXPECT_NEAR(fw.radius, fd.radius, 1e-10);
  EXPECT_NEAR(fw.rms, fd.rms, 1e-10);
  EXPECT_NEAR(fw.objective, fd.objective, 1e-12);
  // uniform scaling of the weights changes nothing
  for (auto& x : w) x *= 7.5;
  const auto fs = fitSphere(view(pts), w.data());
  EXPECT_LT((fs.center - fd.center).norm(), 1e-10);
}

TEST(SphereFit, RigidMotionEquivariance) {  // thesis (6.6)
  std::mt19937 rng(7);
  const auto pts = spherePoints({0.1, 0.2, 0.3}, 0.1, 60, rng, 0.005, 1.0);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const Eigen::Vector3d t(0.5, -2, 3);
  std::vector<double> moved;
  for (std::size_t i = 0; i < 60; ++i) {
    const Eigen::Vector3d p = R * Eigen::Vector3d(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]) + t;
    moved.insert(moved.end(), {p.x(), p.y(), p.z()});
  }
  const auto a = fitSphere(view(pts)), b = fitSphere(view(moved));
  EXPECT_LT((R * a.center + t - b.center).norm(), 1e-10);
  EXPECT_NEAR(a.radius, b.radius, 1e-10);
}

TEST(SphereFit, BadInput) {
  std::mt19937 rng(8);
  auto pts = spherePoints({0, 0, 0}, 1, 5, rng);
  EXPECT_THROW(fitSphere(CloudView<double>(pts.data(), 4)), std::invalid_argument);
  auto nan = pts;
  nan[4] = std::numeric_limits<double>::infinity();
  EXPECT_THROW(fitSphere(view(nan)), std::invalid_argument);
  std::vector<double> zero(5, 0.0), neg(5, 1.0);
  neg[2] = -1;
  EXPECT_THROW(fitSphere(view(pts), zero.data()), std::invalid_argument);
  EXPECT_THROW(fitSphere(view(pts), neg.data()), std::invalid_argument);
  std::vector<double> line, same, circle;
  for (int i = 0; i < 10; ++i) {
    line.insert(line.end(), {0.1 * i, 0.2 * i, -0.05 * i});
    same.insert(same.end(), {1, 2, 3});
    circle.insert(circle.end(), {std::cos(0.6 * i), std::sin(0.6 * i), 2.0});
  }
  EXPECT_THROW(fitSphere(view(line)), std::invalid_argument);
  EXPECT_THROW(fitSphere(view(same)), std::invalid_argument);
  EXPECT_THROW(fitSphere(view(circle)), std::invalid_argument);
}

TEST(SphereFit, Batched) {
  std::mt19937 rng(9);
  std::vector<double> pts;
  std::vector<std::int64_t> off{0};
  std::vector<Eigen::Vector4d> truth;
  for (int g = 0; g < 20; ++g) {
    const Eigen::Vector3d c(g, -g, 0.5 * g);
    const double r = 0.1 + 0.01 * g;
    const auto p = spherePoints(c, r, 30, rng);
    pts.insert(pts.end(), p.begin(), p.end());
    off.push_back(static_cast<std::int64_t>(pts.size() / 3));
    truth.emplace_back(c.x(), c.y(), c.z(), r);
  }
  off.push_back(off.back() + 2);  // a group of 2 points: fails without throwing
  pts.insert(pts.end(), {0, 0, 0, 1, 1, 1});
  const auto fits = fitSpheres(view(pts), off.data(), 21);
  ASSERT_EQ(fits.size(), 21u);
  for (int g = 0; g < 20; ++g) {
    EXPECT_LT((fits[g].center - truth[g].head<3>()).norm(), 1e-9);
    EXPECT_NEAR(fits[g].radius, truth[g](3), 1e-9);
  }
  EXPECT_EQ(fits[20].count, 0u);
  EXPECT_TRUE(std::isnan(fits[20].radius));
}

TEST(CirclePratt, AnalyticCircles) {
  std::mt19937 rng(10);
  std::uniform_real_distribution<double> u(-3, 3), ur(0.01, 2), ua(0, 2 * M_PI);
  for (int trial = 0; trial < 30; ++trial) {
    const Eigen::Vector2d c(u(rng), u(rng));
    const double r = ur(rng);
    std::vector<double> xy;
    for (int i = 0; i < 3 + trial; ++i) {
      const double t = ua(rng);
      xy.insert(xy.end(), {c.x() + r * std::cos(t), c.y() + r * std::sin(t)});
    }
    const auto fit = fitCirclePratt(xy.data(), xy.size() / 2);
    EXPECT_LT((fit.center - c).norm(), 1e-9);
    EXPECT_NEAR(fit.radius, r, 1e-9);
    EXPECT_LT(fit.rms, 1e-9);
    // coefficients satisfy Pratt's constraint d² + e² − 4af = 1 and vanish on the points
    const auto& k = fit.coefficients;
    EXPECT_NEAR(k(1) * k(1) + k(2) * k(2) - 4 * k(0) * k(3), 1.0, 1e-9);
    EXPECT_NEAR(k(0) * xy[0] * xy[0] + k(0) * xy[1] * xy[1] + k(1) * xy[0] + k(2) * xy[1] + k(3), 0.0, 1e-8);
  }
}

TEST(CirclePratt, BadInput) {
  std::vector<double> two{0, 0, 1, 1}, line{0, 0, 1, 1, 2, 2, 3, 3}, nan{0, 0, 1, 0, NAN, 1};
  EXPECT_THROW(fitCirclePratt(two.data(), 2), std::invalid_argument);
  EXPECT_THROW(fitCirclePratt(line.data(), 4), std::invalid_argument);
  EXPECT_THROW(fitCirclePratt(nan.data(), 3), std::invalid_argument);
}

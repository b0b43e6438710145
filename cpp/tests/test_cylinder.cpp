// RANSAC cylinders from two oriented points and their least-squares refit, against known
// cylinders (analytic surface points and normals, noise, a plane and outliers beside them).
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>
#include <stdexcept>
#include <vector>

#include <Eigen/Geometry>

#include "scanalign/segmentation/cylinder.hpp"

namespace scanalign {
namespace {

using V3 = Eigen::Vector3d;

struct Truth {
  V3 point, axis;
  double radius;
};

V3 randomUnit(std::mt19937& rng) {
  std::normal_distribution<double> g;
  return V3(g(rng), g(rng), g(rng)).normalized();
}

/// A point of the true cylinder at angle phi and height h, and its outward normal.
void surfacePoint(const Truth& t, double phi, double h, V3& p, V3& n) {
  const V3 e1 = t.axis.unitOrthogonal(), e2 = t.axis.cross(e1);
  n = std::cos(phi) * e1 + std::sin(phi) * e2;
  p = t.point + h * t.axis + t.radius * n;
}

double axisAngle(const V3& a, const V3& b) {  // radians between two lines
  return std::atan2(a.normalized().cross(b.normalized()).norm(), std::abs(a.normalized().dot(b.normalized())));
}

/// Distance between the fitted axis line and the true one near the true point.
double axisOffset(const CylinderModel& m, const Truth& t) {
  const V3 d = t.point - m.point;
  return (d - d.dot(m.axis) * m.axis).norm();
}

TEST(Cylinder, TwoOrientedPointsGiveTheExactCylinder) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0, 2 * M_PI), h(-0.1, 0.1), r(0.005, 0.2);
  for (int trial = 0; trial < 200; ++trial) {
    const Truth t{V3::Random(), randomUnit(rng), r(rng)};
    V3 p1, n1, p2, n2;
    surfacePoint(t, u(rng), h(rng), p1, n1);
    surfacePoint(t, u(rng), h(rng), p2, n2);
    CylinderModel m;
    if (axisAngle(n1, n2) < 0.05 || std::abs(axisAngle(n1, n2) - M_PI) < 0.05) continue;  // near-parallel normals
    ASSERT_TRUE(cylinderFromOrientedPoints(p1, -3.0 * n1, p2, n2, 1e-9, m)) << trial;  // any length and sign
    EXPECT_LT(axisAngle(m.axis, t.axis), 1e-9);
    EXPECT_NEAR(m.radius, t.radius, 1e-9);
    EXPECT_LT(axisOffset(m, t), 1e-9);
  }
  CylinderModel m;
  EXPECT_FALSE(cylinderFromOrientedPoints(V3(0, 0, 0), V3(0, 0, 1), V3(1, 0, 0), V3(0, 0, 1), 1.0, m));  // a plane
  // Both normals radial from different axes (distances 1 and 3 from the line they define).
  EXPECT_FALSE(cylinderFromOrientedPoints(V3(1, 0, 0), V3(1, 0, 0), V3(0, 3, 0), V3(0, 1, 0), 0.01, m));
}

TEST(Cylinder, LeastSquaresRefitConvergesFromAPerturbedStart) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.0005);
  std::uniform_real_distribution<double> arc(0.0, 2.0 * M_PI / 3.0), h(-0.05, 0.05);  // a third of the mantle
  const Truth t{V3(0.1, -0.2, 0.8), V3(0.2, 0.3, 1.0).normalized(), 0.04};
  std::vector<double> xyz;
  for (int i = 0; i < 3000; ++i) {
    V3 p, n;
    surfacePoint(t, arc(rng), h(rng), p, n);
    p += V3(noise(rng), noise(rng), noise(rng));
    xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
  }
  std::vector<std::uint32_t> all(3000);
  for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
  const CloudView<double> cloud(xyz.data(), 3000);
  CylinderModel m;
  m.axis = Eigen::AngleAxisd(0.1, t.axis.unitOrthogonal()) * t.axis;  // 5.7 degrees off
  m.point = t.point + V3(0.004, -0.003, 0.0);
  m.radius = 0.05;  // 25 % too large
  ASSERT_TRUE(fitCylinderLeastSquares(cloud, all, m));
  EXPECT_LT(axisAngle(m.axis, t.axis), 0.5 * M_PI / 180);
  EXPECT_NEAR(m.radius, t.radius, 3e-4);
  EXPECT_LT(axisOffset(m, t), 5e-4);
  // A least-squares optimum: its cost is not above the truth's own.
  auto cost = [&](const CylinderModel& c) {
    double s = 0;
    for (std::uint32_t i : all) s += std::pow(c.axisDistance(cloud[i]) - c.radius, 2);
    return s;
  };
  EXPECT_LE(cost(m), cost(CylinderModel{t.point, t.axis, t.radius}) * (1 + 1e-9));
  CylinderModel few = m;
  EXPECT_FALSE(fitCylinderLeastSquares(cloud, {0, 1, 2, 3}, few));
}

TEST(Cylinder, RansacFindsACylinderBesideAPlaneAndOutliers) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.0003);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Truth t{V3(0.0, 0.0, 0.72), V3(0.05, -0.8, -0.6).normalized(), 0.035};  // a mug on a tilted table
  std::vector<double> xyz;
  std::vector<int> label;
  for (int i = 0; i < 4000; ++i) {  // the half of the mantle a camera sees, 12 cm tall
    V3 p, n;
    surfacePoint(t, M_PI * u(rng), 0.12 * u(rng), p, n);
    p += V3(noise(rng), noise(rng), noise(rng));
    xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
    label.push_back(1);
  }
  const V3 e1 = t.axis.unitOrthogonal(), e2 = t.axis.cross(e1);
  for (int i = 0; i < 6000; ++i) {  // the table under it
    const V3 p = t.point - 0.005 * t.axis + (u(rng) - 0.5) * 0.4 * e1 + (u(rng) - 0.5) * 0.4 * e2 +
                 V3(noise(rng), noise(rng), noise(rng));
    xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
    label.push_back(0);
  }
  for (int i = 0; i < 1500; ++i) {  // clutter
    const V3 p = t.point + 0.3 * V3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
    xyz.insert(xyz.end(), {p.x(), p.y(), p.z()});
    label.push_back(2);
  }
  CylinderSettings s;
  s.ransac.threshold = 0.002;
  s.ransac.max_iterations = 5000;
  s.max_radius = 0.1;
  s.normal_radius = 0.008;
  const auto r = ransacCylinder(CloudView<double>(xyz.data(), label.size()), s);
  ASSERT_TRUE(r.success());
  EXPECT_TRUE(r.refined);
  EXPECT_LT(axisAngle(r.model.axis, t.axis), 1.0 * M_PI / 180);
  EXPECT_NEAR(r.model.radius, t.radius, 1e-3);
  EXPECT_LT(axisOffset(r.model, t), 1e-3);
  std::size_t on_cylinder = 0, on_table = 0;
  for (std::uint32_t i : r.inliers) {
    on_cylinder += label[i] == 1 ? 1 : 0;
    on_table += label[i] == 0 ? 1 : 0;
  }
  EXPECT_GT(on_cylinder, 0.9 * 4000);
  EXPECT_LT(on_table, 0.02 * 6000);  // the table's normals are not radial
  // Seeded: the same answer again.
  const auto again = ransacCylinder(CloudView<double>(xyz.data(), label.size()), s);
  EXPECT_EQ(again.inliers, r.inliers);
}

TEST(Cylinder, StatusesAndSettings) {
  std::vector<double> one = {0, 0, 1}, n1 = {0, 0, 1};
  CylinderSettings s;
  EXPECT_EQ(ransacCylinder(CloudView<double>(one.data(), 1), CloudView<double>(n1.data(), 1), s).status,
            RansacStatus::kTooFewPoints);
  std::vector<double> plane, normals;
  for (int i = 0; i < 400; ++i) {
    plane.insert(plane.end(), {0.01 * (i % 20), 0.01 * (i / 20), 0.5});
    normals.insert(normals.end(), {0, 0, -1});
  }
  const auto flat = ransacCylinder(CloudView<double>(plane.data(), 400), CloudView<double>(normals.data(), 400), s);
  EXPECT_EQ(flat.status, RansacStatus::kDegenerate);  // parallel normals: no axis
  EXPECT_THROW(ransacCylinder(CloudView<double>(plane.data(), 400), CloudView<double>(normals.data(), 399), s),
               std::invalid_argument);
  auto bad = s;
  bad.max_normal_angle = 2.0;
  EXPECT_THROW(validate(bad), std::invalid_argument);
  bad = s;
  bad.min_radius = 0.2;
  bad.max_radius = 0.1;
  EXPECT_THROW(validate(bad), std::invalid_argument);
  bad = s;
  bad.normal_radius = 0;
  EXPECT_THROW(validate(bad), std::invalid_argument);
}

}  // namespace
}  // namespace scanalign

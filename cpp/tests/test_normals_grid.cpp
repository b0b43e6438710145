// The grid neighbourhood search of estimateNormals (cell moments, shell tests) against an
// independent brute-force PCA: every pair tested, moments summed in double about the
// query, eigenvectors by Eigen's iterative solver (not the closed form the library uses).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Eigenvalues>

#include "scanalign/features/normals.hpp"
#include "scanalign/registration/kdtree.hpp"

using scanalign::CloudView;

namespace {

/// Scan-like test cloud (m) around z = 0.5 m: a noisy tilted plane at ~1 mm spacing with a
/// depth step (an occluding edge) and a convex 90-degree edge, a noisy sphere, a thin line
/// (a degenerate neighbourhood), exact duplicates, a sparse scatter (isolated points, too
/// few neighbours) and non-finite rows.
std::vector<double> scanLikeCloud(const Eigen::Vector3d& shift, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.0003);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  std::vector<double> v;
  auto add = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector3d q = p + shift;
    v.insert(v.end(), {q.x(), q.y(), q.z()});
  };
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 50; ++j) {
      const double x = -0.03 + 0.001 * (i + 0.3 * u(rng)), y = -0.025 + 0.001 * (j + 0.3 * u(rng));
      double z = 0.5 + 0.3 * x + 0.1 * y;
      if (x > 0.005) z += 0.008;                          // depth step
      if (y > 0.01) z -= 0.8 * (y - 0.01);                // convex edge
      add({x, y, z + noise(rng)});
    }
  std::normal_distribution<double> g(0.0, 1.0);
  for (int k = 0; k < 2500; ++k) {  // sphere of radius 15 mm
    Eigen::Vector3d d(g(rng), g(rng), g(rng));
    d.normalize();
    add(Eigen::Vector3d(0.05, 0.0, 0.49) + (0.015 + noise(rng)) * d);
  }
  for (int k = 0; k < 80; ++k) add({-0.05 + 0.0005 * k, 0.04, 0.52});  // a line
  for (int k = 0; k < 20; ++k) {                                         // duplicates
    const std::size_t i = 3 * static_cast<std::size_t>(k * 97);
    add(Eigen::Vector3d(v[i], v[i + 1], v[i + 2]) - shift);
  }
  for (int k = 0; k < 300; ++k) add({0.12 * u(rng), 0.12 * u(rng), 0.6 + 0.1 * u(rng)});  // sparse
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  v.insert(v.end(), {nan, 0.0, 0.5, 0.0, inf, 0.5});
  return v;
}

struct Reference {
  bool valid = false;      // at least min_neighbors neighbours
  bool ambiguous = false;  // a point lies within rounding of the sphere
  double gap = 0.0;        // (lambda1 - lambda0) / lambda2: how well the normal is defined
  double facing = 0.0;     // |n . (viewpoint - q)| / |viewpoint - q|
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double curvature = 0.0;
};

/// Brute-force PCA of every finite point over all points within `radius`, in double.
template <typename Scalar>
std::vector<Reference> bruteForce(const std::vector<Scalar>& pts, double radius, double ambiguity,
                                  const Eigen::Vector3d& viewpoint, int min_neighbors) {
  const std::size_t n = pts.size() / 3;
  std::vector<Reference> out(n);
  const double r2 = radius * radius;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d q(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
    if (!q.allFinite()) continue;
    Eigen::Vector3d s1 = Eigen::Vector3d::Zero();
    Eigen::Matrix3d s2 = Eigen::Matrix3d::Zero();
    int k = 0;
    Reference& ref = out[i];
    for (std::size_t j = 0; j < n; ++j) {
      const Eigen::Vector3d d = Eigen::Vector3d(pts[3 * j], pts[3 * j + 1], pts[3 * j + 2]) - q;
      if (!d.allFinite()) continue;
      const double d2 = d.squaredNorm();
      if (std::abs(d2 - r2) <= ambiguity * r2) ref.ambiguous = true;
      if (d2 > r2) continue;
      s1 += d;
      s2 += d * d.transpose();
      ++k;
    }
    if (k < min_neighbors) continue;
    ref.valid = true;
    const Eigen::Vector3d mean = s1 / k;
    const Eigen::Matrix3d cov = s2 / k - mean * mean.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    const Eigen::Vector3d l = eig.eigenvalues().cwiseMax(0.0);
    ref.gap = l(2) > 0.0 ? (l(1) - l(0)) / l(2) : 0.0;
    ref.normal = eig.eigenvectors().col(0).normalized();
    const Eigen::Vector3d to_view = (viewpoint - q).normalized();
    if (ref.normal.dot(to_view) < 0.0) ref.normal = -ref.normal;
    ref.facing = std::abs(ref.normal.dot(to_view));
    ref.curvature = l.sum() > 0.0 ? l(0) / l.sum() : 0.0;
  }
  return out;
}

/// Compares normals and curvature with the reference. `eps` is the relative rounding of
/// the covariance sums; the normal's angle error is bounded by about eps / gap.
template <typename Scalar>
void expectMatches(const std::vector<Reference>& ref, const std::vector<Scalar>& normals,
                   const std::vector<Scalar>& curvature, double eps, const std::string& what) {
  std::size_t compared = 0, skipped = 0;
  for (std::size_t i = 0; i < ref.size(); ++i) {
    const Eigen::Vector3d n(normals[3 * i], normals[3 * i + 1], normals[3 * i + 2]);
    if (ref[i].ambiguous) {
      ++skipped;
      continue;
    }
    if (!ref[i].valid) {
      ASSERT_TRUE(std::isnan(n.x()) && std::isnan(n.y()) && std::isnan(n.z()) && std::isnan(curvature[i]))
          << what << " point " << i << " should have too few neighbours";
      continue;
    }
    ASSERT_TRUE(n.allFinite()) << what << " point " << i;
    ASSERT_NEAR(curvature[i], ref[i].curvature, 20 * eps + 1e-15) << what << " point " << i;
    if (ref[i].gap < 1e-3) continue;  // a line or an isotropic blob: no well-defined normal
    ++compared;
    // Near-tangent views may flip the orientation legitimately: compare the axis there.
    const Eigen::Vector3d m = ref[i].facing <= 1e-6 && n.dot(ref[i].normal) < 0.0 ? Eigen::Vector3d(-n) : n;
    const double angle = (m - ref[i].normal).norm();  // the angle, to first order (acos is too coarse near 0)
    ASSERT_LE(angle, 20 * eps / ref[i].gap + 4 * std::numeric_limits<Scalar>::epsilon())
        << what << " point " << i << " gap " << ref[i].gap;
  }
  EXPECT_GT(compared, ref.size() / 2) << what;
  EXPECT_LT(skipped, ref.size() / 50) << what << ": too many points on a sphere's rim";
}

template <typename Scalar>
void checkAgainstBruteForce(const Eigen::Vector3d& shift) {
  const std::vector<double> base = scanLikeCloud(shift, 7);
  const std::vector<Scalar> pts(base.begin(), base.end());
  const std::size_t n = pts.size() / 3;
  const bool single = sizeof(Scalar) == sizeof(float);
  // Float clouds are tested and summed in float near the sphere: allow float rounding.
  const double eps = single ? 2e-6 : 1e-12, ambiguity = single ? 2e-6 : 1e-12;
  const Eigen::Vector3d viewpoint = shift;  // the "camera" at the scan's origin
  for (const double radius : {0.003, 0.005, 0.01, 0.02}) {
    const auto ref = bruteForce(pts, radius, ambiguity, viewpoint, 3);
    for (const int d : {0, 1, 2, 3, 5, 8}) {
      scanalign::NormalEstimationSettings s;
      s.radius = radius;
      s.viewpoint = viewpoint;
      s.grid_subdivisions = d;
      std::vector<Scalar> normals(3 * n), curvature(n);
      scanalign::estimateNormals(CloudView<Scalar>(pts.data(), n), s, normals.data(), curvature.data());
      expectMatches(ref, normals, curvature, eps,
                    "radius " + std::to_string(radius) + " subdivisions " + std::to_string(d));
    }
    // The k-d tree path (kept for clouds the grid cannot hold) agrees with the same truth.
    scanalign::NormalEstimationSettings s;
    s.radius = radius;
    s.viewpoint = viewpoint;
    std::vector<Scalar> normals(3 * n), curvature(n);
    scanalign::LeftBalancedKdTree<Scalar> tree(CloudView<Scalar>(pts.data(), n));
    scanalign::estimateNormals(CloudView<Scalar>(pts.data(), n), tree, s, normals.data(), curvature.data());
    expectMatches(ref, normals, curvature, single ? 2e-6 : 1e-12, "tree, radius " + std::to_string(radius));
  }
}

}  // namespace

TEST(NormalsGrid, FloatCloudMatchesBruteForcePca) { checkAgainstBruteForce<float>(Eigen::Vector3d::Zero()); }

TEST(NormalsGrid, DoubleCloudMatchesBruteForcePca) { checkAgainstBruteForce<double>(Eigen::Vector3d::Zero()); }

TEST(NormalsGrid, FarFromTheOriginMatchesBruteForcePca) {
  checkAgainstBruteForce<float>(Eigen::Vector3d(40.0, -25.0, 10.0));
  checkAgainstBruteForce<double>(Eigen::Vector3d(4000.0, -2500.0, 1000.0));
}

TEST(NormalsGrid, HugeExtentFallsBackToTheTreeWithTheSameResult) {
  // Two patches 100 km apart: more than 2^21 cells of 5 mm along x, so no grid.
  std::vector<double> pts = scanLikeCloud(Eigen::Vector3d::Zero(), 3);
  const std::size_t half = pts.size() / 3;
  for (std::size_t i = 0; i < half; ++i) pts.insert(pts.end(), {pts[3 * i] + 1e5, pts[3 * i + 1], pts[3 * i + 2]});
  const std::size_t n = pts.size() / 3;
  const auto ref = bruteForce(pts, 0.005, 1e-8, Eigen::Vector3d::Zero(), 3);
  scanalign::NormalEstimationSettings s;
  std::vector<double> normals(3 * n), curvature(n);
  scanalign::estimateNormals(CloudView<double>(pts.data(), n), s, normals.data(), curvature.data());
  expectMatches(ref, normals, curvature, 1e-10, "100 km extent");  // 1e5 m offsets: 1e-11 relative rounding
}

TEST(NormalsGrid, RejectsBadSubdivisions) {
  std::vector<float> pts = {0, 0, 1, 0.001f, 0, 1, 0, 0.001f, 1};
  std::vector<float> n(9);
  scanalign::NormalEstimationSettings s;
  s.grid_subdivisions = -1;
  EXPECT_THROW(scanalign::estimateNormals(CloudView<float>(pts.data(), 3), s, n.data()), std::invalid_argument);
  s.grid_subdivisions = 17;
  EXPECT_THROW(scanalign::estimateNormals(CloudView<float>(pts.data(), 3), s, n.data()), std::invalid_argument);
}

TEST(NormalsGrid, FarOutlierWithARadiusSpanningTheCloudMatchesTheTree) {
  // One point 10^7 m away used to make the grid too large to index; the k-d tree fallback
  // then visited every neighbour of every point (quadratic with a radius spanning the
  // cloud). The grid now closes the empty gap and must give the tree's normals.
  std::vector<double> pts = scanLikeCloud(Eigen::Vector3d::Zero(), 5);
  pts.insert(pts.end(), {1e7, 0.0, 0.0});
  const std::size_t n = pts.size() / 3;
  for (const double radius : {0.004, 0.05, 10.0}) {
    scanalign::NormalEstimationSettings s;
    s.radius = radius;
    std::vector<double> grid(3 * n), grid_c(n), tree(3 * n), tree_c(n);
    scanalign::estimateNormals(CloudView<double>(pts.data(), n), s, grid.data(), grid_c.data());
    scanalign::LeftBalancedKdTree<double> kd(CloudView<double>(pts.data(), n));
    scanalign::estimateNormals(CloudView<double>(pts.data(), n), kd, s, tree.data(), tree_c.data());
    std::size_t compared = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d a(grid[3 * i], grid[3 * i + 1], grid[3 * i + 2]);
      const Eigen::Vector3d b(tree[3 * i], tree[3 * i + 1], tree[3 * i + 2]);
      ASSERT_EQ(a.allFinite(), b.allFinite()) << "radius " << radius << " point " << i;
      if (!a.allFinite()) continue;
      ASSERT_NEAR(grid_c[i], tree_c[i], 1e-9) << "radius " << radius << " point " << i;
      if (tree_c[i] > 0.2) continue;  // no well-defined normal (near-isotropic neighbourhood)
      ASSERT_LT((a - b).norm(), 1e-6) << "radius " << radius << " point " << i;
      ++compared;
    }
    if (radius < 1.0) EXPECT_GT(compared, n / 10) << "radius " << radius;  // else: one neighbourhood for all
    EXPECT_TRUE(std::isnan(grid[3 * (n - 1)]));  // the outlier has too few neighbours
  }
}

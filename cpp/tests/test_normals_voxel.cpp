// Normals and voxel grid against analytic truth and stock PCL.
#include <gtest/gtest.h>

#include <random>

#include <pcl/features/normal_3d.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_types.h>

#include "scanalign/features/normals.hpp"
#include "scanalign/reconstruction/voxel_grid.hpp"

using scanalign::CloudView;

namespace {
std::vector<float> sphere(int n, double r, const Eigen::Vector3d& c, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  std::vector<float> v;
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3d u(g(rng), g(rng), g(rng));
    u.normalize();
    const Eigen::Vector3d p = c + r * u;
    v.insert(v.end(), {float(p.x()), float(p.y()), float(p.z())});
  }
  return v;
}
}  // namespace

TEST(Normals, SphereNormalsAreRadialAndFaceTheViewpoint) {
  const Eigen::Vector3d c(0.0, 0.0, 0.5);
  const auto pts = sphere(40000, 0.05, c, 1);
  std::vector<float> n(pts.size()), curv(pts.size() / 3);
  scanalign::NormalEstimationSettings s;  // radius 5 mm, viewpoint at the origin
  scanalign::estimateNormals(CloudView<float>(pts.data(), pts.size() / 3), s, n.data(), curv.data());
  for (std::size_t i = 0; i < pts.size() / 3; ++i) {
    const Eigen::Vector3d p(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
    const Eigen::Vector3d radial = (p - c).normalized();
    const Eigen::Vector3d ni(n[3 * i], n[3 * i + 1], n[3 * i + 2]);
    ASSERT_NEAR(ni.norm(), 1.0, 1e-5);
    ASSERT_GT(std::abs(ni.dot(radial)), 0.995) << i;  // within ~6 degrees on a 5 cm sphere, 5 mm patches
    ASSERT_GE(ni.dot(-p), 0.0) << i;                   // faces the viewpoint at the origin
    ASSERT_LT(curv[i], 0.02);
  }
}

TEST(Normals, AgreeWithPclNormalEstimation) {
  const auto pts = sphere(20000, 0.05, Eigen::Vector3d(0.01, 0.02, 0.4), 2);
  auto cloud = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  for (std::size_t i = 0; i < pts.size() / 3; ++i) cloud->emplace_back(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> ne;
  ne.setInputCloud(cloud);
  ne.setRadiusSearch(0.006);
  ne.setViewPoint(0.f, 0.f, 0.f);
  pcl::PointCloud<pcl::Normal> theirs;
  ne.compute(theirs);
  scanalign::NormalEstimationSettings s;
  s.radius = 0.006;
  std::vector<float> ours(pts.size()), curv(pts.size() / 3);
  scanalign::estimateNormals(CloudView<float>(pts.data(), pts.size() / 3), s, ours.data(), curv.data());
  for (std::size_t i = 0; i < theirs.size(); ++i) {
    const Eigen::Vector3f a = theirs[i].getNormalVector3fMap();
    const Eigen::Vector3f b(ours[3 * i], ours[3 * i + 1], ours[3 * i + 2]);
    ASSERT_GT(a.dot(b), 1.f - 1e-4f) << i;
    ASSERT_NEAR(theirs[i].curvature, curv[i], 1e-4);
  }
}

TEST(Normals, TooFewNeighboursGiveNaN) {
  std::vector<float> pts = {0, 0, 1, 1, 1, 1, 2, 2, 2};
  std::vector<float> n(9);
  scanalign::estimateNormals(CloudView<float>(pts.data(), 3), {}, n.data());
  for (float v : n) EXPECT_TRUE(std::isnan(v));
  scanalign::NormalEstimationSettings bad;
  bad.radius = -1;
  EXPECT_THROW(scanalign::estimateNormals(CloudView<float>(pts.data(), 3), bad, n.data()), std::invalid_argument);
}

TEST(VoxelGrid, EqualsPclVoxelGrid) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-0.05f, 0.05f);
  auto cloud = pcl::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  std::vector<float> pts;
  for (int i = 0; i < 200000; ++i) {
    const float x = u(rng), y = u(rng), z = 0.5f + u(rng);
    cloud->emplace_back(x, y, z);
    pts.insert(pts.end(), {x, y, z});
  }
  pcl::VoxelGrid<pcl::PointXYZ> vg;
  vg.setInputCloud(cloud);
  vg.setLeafSize(0.002f, 0.002f, 0.002f);
  pcl::PointCloud<pcl::PointXYZ> theirs;
  vg.filter(theirs);
  const auto ours = scanalign::voxelGrid(CloudView<float>(pts.data(), pts.size() / 3), 0.002);
  ASSERT_EQ(ours.size(), theirs.size());
  for (std::size_t i = 0; i < theirs.size(); ++i)  // same voxels, same order, same centroids
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(ours.points[3 * i + k], theirs[i].data[k], 2e-6) << i;
}

TEST(VoxelGrid, AveragesAttributesAndRejectsTinyLeaves) {
  std::vector<double> pts = {0.0001, 0.0001, 0.0001, 0.0009, 0.0009, 0.0009, 0.0015, 0.0, 0.0};
  std::vector<double> attr = {1.0, 10.0, 3.0, 20.0, 5.0, 30.0};
  const auto r = scanalign::voxelGrid(CloudView<double>(pts.data(), 3), 0.001, attr.data(), 2);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_NEAR(r.points[0], 0.0005, 1e-12);
  EXPECT_EQ(r.attributes[0], 2.0);
  EXPECT_EQ(r.attributes[1], 15.0);
  EXPECT_EQ(r.counts[0], 2u);
  EXPECT_EQ(r.counts[1], 1u);
  std::vector<double> wide = {0, 0, 0, 1000, 0, 0};
  EXPECT_THROW(scanalign::voxelGrid(CloudView<double>(wide.data(), 2), 1e-4), std::invalid_argument);
  EXPECT_THROW(scanalign::voxelGrid(CloudView<double>(wide.data(), 2), 0.0), std::invalid_argument);
}

// RANSAC (thesis §5.2), CGA plane / sphere models (5.35-5.36, 4.58-4.60), least-squares
// refits (5.31) and table segmentation (paper 3), against independent truth.
#include <gtest/gtest.h>

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <vector>

#include <Eigen/Geometry>

#include "scanalign/segmentation/euclidean_clusters.hpp"
#include "scanalign/segmentation/ransac.hpp"
#include "scanalign/segmentation/table_segmentation.hpp"

namespace scanalign {
namespace {

using V3 = Eigen::Vector3d;

CloudView<double> view(const std::vector<double>& xyz) { return CloudView<double>(xyz.data(), xyz.size() / 3, 3); }
void push(std::vector<double>& xyz, const V3& p) { xyz.insert(xyz.end(), {p.x(), p.y(), p.z()}); }

V3 randomUnit(std::mt19937& rng) {
  std::normal_distribution<double> g;
  return V3(g(rng), g(rng), g(rng)).normalized();
}

// A table z = 0.7 (up = -z seen from a camera at the origin looking down +z is not needed
// here: plane tilted arbitrarily), uniform noise +-noise, plus a box and a sphere on it.
struct Scene {
  std::vector<double> xyz;
  std::vector<int> label;  // 0 table, 1 sphere, 2 box, 3 clutter
  V3 n;                    // true unit normal, pointing to the objects
  double d;                // n.p = d on the table
};

Scene tableScene(std::uint32_t seed, double noise = 0.002) {
  Scene s;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.4, V3(1, 0.3, 0).normalized()).toRotationMatrix();
  const V3 t(0.05, -0.1, 0.9);
  s.n = R * V3(0, 0, -1);  // table normal towards the camera at the origin
  s.d = s.n.dot(t);
  auto add = [&](const V3& local, int lab) {
    push(s.xyz, R * V3(local.x(), local.y(), -local.z()) + t);
    s.label.push_back(lab);
  };
  for (int i = 0; i < 6000; ++i) add(V3(0.4 * u(rng), 0.3 * u(rng), noise * u(rng)), 0);
  // sphere of radius 5 cm resting on the table at (0.15, 0.1); only its upper half
  for (int i = 0; i < 1500; ++i) {
    V3 v = randomUnit(rng);
    v.z() = std::abs(v.z());  // the upper half, seen from above: 5 cm and more above the table
    add(V3(0.15, 0.1, 0.05) + 0.05 * v, 1);
  }
  // box 6 x 6 x 10 cm at (-0.15, -0.05), sides from 2 cm up
  for (int i = 0; i < 1500; ++i) {
    const int face = i % 5;
    const double a = 0.03 * u(rng), b = 0.03 * u(rng), h = 0.02 + 0.08 * (0.5 + 0.5 * u(rng));
    V3 p = face == 0 ? V3(a, b, 0.1) : face == 1 ? V3(0.03, a, h) : face == 2 ? V3(-0.03, a, h) : face == 3 ? V3(a, 0.03, h) : V3(a, -0.03, h);
    add(p + V3(-0.15, -0.05, 0), 2);
  }
  return s;
}

TEST(Cga5, PointInnerProductIsHalfSquaredDistance) {  // (4.56)
  const V3 a(0.3, -1, 2), b(1, 0.5, -0.2);
  EXPECT_NEAR(cga5::inner(cga5::up(a), cga5::up(b)), -0.5 * (a - b).squaredNorm(), 1e-12);
  EXPECT_NEAR(cga5::inner(cga5::up(a), cga5::up(a)), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(cga5::inner(cga5::eInf(), [] { cga5::Vec5 e0 = cga5::Vec5::Zero(); e0[4] = 1; return e0; }()), -1.0);
}

TEST(Cga5, DualPlaneMatchesVerifiedExample) {  // with the dual (4.50): -(e3 + e_inf)
  const cga5::Vec5 v = cga5::dualOfOuter4(cga5::up(V3(0, 0, 1)), cga5::up(V3(1, 0, 1)), cga5::up(V3(0, 1, 1)), cga5::eInf());
  cga5::Vec5 expect;
  expect << 0, 0, -1, -1, 0;
  EXPECT_LT((v - expect).norm(), 1e-12);
}

TEST(Models, PlaneFromThreePointsMatchesEuclideanForm) {  // P3 eqs (2)-(4)
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-2, 2);
  for (int k = 0; k < 200; ++k) {
    const V3 a(u(rng), u(rng), u(rng)), b(u(rng), u(rng), u(rng)), c(u(rng), u(rng), u(rng));
    PlaneModel m;
    ASSERT_TRUE(planeFromPoints(a, b, c, m));
    const V3 v = ((b - a).cross(c - a)).normalized();
    EXPECT_NEAR(std::abs(m.normal.dot(v)), 1.0, 1e-10);
    for (const V3& p : {a, b, c}) EXPECT_NEAR(m.signedDistance(p), 0.0, 1e-10);
    // (4.67) P . Pi* = n.p - delta
    const V3 q(u(rng), u(rng), u(rng));
    EXPECT_NEAR(cga5::inner(cga5::up(q), m.dual()), m.signedDistance(q), 1e-10);
    EXPECT_NEAR(std::abs(m.signedDistance(q)), std::abs(v.dot(q - a)), 1e-10);
  }
  PlaneModel m;
  EXPECT_FALSE(planeFromPoints(V3(0, 0, 0), V3(1, 2, 3), V3(2, 4, 6), m));
  EXPECT_FALSE(planeFromPoints(V3(1, 1, 1), V3(1, 1, 1), V3(0, 2, 3), m));
}

TEST(Models, SphereFromFourPoints) {  // (4.58)-(4.61)
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int k = 0; k < 200; ++k) {
    const V3 c(u(rng), u(rng), 1 + u(rng));
    const double r = 0.02 + 0.5 * (1 + u(rng));
    V3 p[4];
    for (auto& q : p) q = c + r * randomUnit(rng);
    SphereModel m;
    ASSERT_TRUE(sphereFromPoints(p[0], p[1], p[2], p[3], m));
    EXPECT_LT((m.center - c).norm(), 1e-7 * (1 + r));
    EXPECT_NEAR(m.radius, r, 1e-7 * (1 + r));
    // S*^2 = r^2 (4.61); S* . up(x) = (r^2 - |x-c|^2)/2
    EXPECT_NEAR(cga5::inner(m.dual(), m.dual()), r * r, 1e-8);
    const V3 x(u(rng), u(rng), u(rng));
    EXPECT_NEAR(cga5::inner(m.dual(), cga5::up(x)), 0.5 * (r * r - (x - c).squaredNorm()), 1e-8);
  }
  SphereModel m;  // coplanar points: the blade is a plane, no sphere
  EXPECT_FALSE(sphereFromPoints(V3(0, 0, 1), V3(1, 0, 1), V3(0, 1, 1), V3(1, 1, 1), m));
}

TEST(Models, SphereLeastSquaresExactAndNoisy) {  // Kleppe thesis (5.26)-(5.34)
  std::mt19937 rng(5);
  const V3 c(0.1, -0.2, 0.8);
  const double r = 0.07;
  std::vector<double> xyz;
  for (int i = 0; i < 300; ++i) push(xyz, c + r * randomUnit(rng));
  std::vector<std::uint32_t> all(300);
  std::iota(all.begin(), all.end(), 0u);
  SphereModel m;
  ASSERT_TRUE(fitSphereLeastSquares(view(xyz), all, m));
  EXPECT_LT((m.center - c).norm(), 1e-9);
  EXPECT_NEAR(m.radius, r, 1e-9);
  // Only a cap (30 deg around +z), noisy: still close.
  std::normal_distribution<double> g(0, 0.0005);
  xyz.clear();
  for (int i = 0; i < 2000; ++i) {
    V3 v = randomUnit(rng);
    if (v.z() < 0.5) v.z() = 1.0 - v.z() * 0.5;
    v.normalize();
    push(xyz, c + (r + g(rng)) * v);
  }
  all.resize(2000);
  std::iota(all.begin(), all.end(), 0u);
  ASSERT_TRUE(fitSphereLeastSquares(view(xyz), all, m));
  EXPECT_LT((m.center - c).norm(), 0.005);
  EXPECT_NEAR(m.radius, r, 0.005);
  // Coplanar data: the fit is a plane (e0 ~ 0), reported as failure.
  xyz.clear();
  for (int i = 0; i < 100; ++i) push(xyz, V3(0.01 * i, 0.003 * (i % 7), 0.5));
  all.resize(100);
  std::iota(all.begin(), all.end(), 0u);
  EXPECT_FALSE(fitSphereLeastSquares(view(xyz), all, m));
}

TEST(Ransac, RequiredIterations) {
  EXPECT_EQ(ransacRequiredIterations(0.5, 3, 0.99), std::ceil(std::log(0.01) / std::log(1 - 0.125)));
  EXPECT_EQ(ransacRequiredIterations(1.0, 3, 0.99), 1.0);
  EXPECT_TRUE(std::isinf(ransacRequiredIterations(0.0, 3, 0.99)));
}

TEST(Ransac, SamplesAreDistinctAndSeeded) {
  std::uint32_t a[4], b[4];
  for (std::uint64_t k = 0; k < 1000; ++k) {
    ransacSample(7, k, 5, 4, a);
    std::set<std::uint32_t> s(a, a + 4);
    EXPECT_EQ(s.size(), 4u);
    for (auto v : a) EXPECT_LT(v, 5u);
    ransacSample(7, k, 5, 4, b);
    EXPECT_TRUE(std::equal(a, a + 4, b));
  }
}

TEST(Ransac, PlaneOnTableSceneInliersAreExactlyTheThresholdSet) {
  const Scene s = tableScene(11);
  RansacSettings rs;
  rs.threshold = 0.005;
  rs.seed = 1;
  const auto r = ransacPlane(view(s.xyz), rs);
  ASSERT_TRUE(r.success());
  EXPECT_TRUE(r.refined);
  EXPECT_GT(std::abs(r.model.normal.dot(s.n)), 1 - 1e-4);
  EXPECT_NEAR(std::abs(r.model.distance), std::abs(s.d), 1e-3);
  // Inliers = exactly the points within the threshold of the returned model.
  std::vector<std::uint32_t> expect;
  for (std::size_t i = 0; i < s.label.size(); ++i) {
    const V3 p(s.xyz[3 * i], s.xyz[3 * i + 1], s.xyz[3 * i + 2]);
    if (std::abs(r.model.normal.dot(p) - r.model.distance) < rs.threshold) expect.push_back(std::uint32_t(i));
  }
  EXPECT_EQ(r.inliers, expect);
  // ... and, against the truth, exactly the table points (objects start 2 cm up).
  std::vector<std::uint32_t> table;
  for (std::size_t i = 0; i < s.label.size(); ++i)
    if (s.label[i] == 0) table.push_back(std::uint32_t(i));
  EXPECT_EQ(r.inliers, table);
  EXPECT_LT(r.iterations, 100);  // adaptive: inlier ratio 2/3
}

TEST(Ransac, ThreadCountIndependentAndSeeded) {
  const Scene s = tableScene(12, 0.004);
  RansacSettings rs;
  rs.threshold = 0.003;  // below the noise: many near-ties among hypotheses
  rs.seed = 42;
  rs.confidence = 0;  // run all max_iterations
  rs.max_iterations = 200;
  std::vector<RansacResult<PlaneModel>> runs;
  for (int t : {1, 2, 3, 8}) {
    rs.num_threads = t;
    runs.push_back(ransacPlane(view(s.xyz), rs));
  }
  for (const auto& r : runs) {
    EXPECT_EQ(r.iterations, 200);
    EXPECT_EQ(r.inliers, runs[0].inliers);
    EXPECT_EQ(r.hypothesis.normal, runs[0].hypothesis.normal);
    EXPECT_EQ(r.model.distance, runs[0].model.distance);
  }
  rs.seed = 43;
  rs.num_threads = 2;
  const auto other = ransacPlane(view(s.xyz), rs);
  EXPECT_NE(other.hypothesis.normal, runs[0].hypothesis.normal);
}

TEST(Ransac, SphereAmidOutliers) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  std::normal_distribution<double> g(0, 0.0005);
  const V3 c(0.05, 0.02, 0.7);
  const double r = 0.06;
  std::vector<double> xyz;
  for (int i = 0; i < 800; ++i) push(xyz, c + (r + g(rng)) * randomUnit(rng));
  for (int i = 0; i < 1200; ++i) push(xyz, c + V3(u(rng), u(rng), u(rng)));  // 60 % outliers
  RansacSettings rs;
  rs.threshold = 0.002;
  rs.max_iterations = 5000;
  const auto res = ransacSphere(view(xyz), rs);
  ASSERT_TRUE(res.success());
  EXPECT_LT((res.model.center - c).norm(), 0.001);
  EXPECT_NEAR(res.model.radius, r, 0.001);
  std::size_t sphere_inliers = 0;
  for (auto i : res.inliers) sphere_inliers += i < 800;
  EXPECT_GE(sphere_inliers, 790u);
  EXPECT_LT(res.inliers.size() - sphere_inliers, 40u);  // outliers that happen to lie in the shell
  // Radius limits exclude it.
  SphereLimits lim;
  lim.max_radius = 0.03;
  const auto small = ransacSphere(view(xyz), rs, lim);
  if (small.success()) EXPECT_LE(small.model.radius, 0.03);
}

TEST(Ransac, FailureStatuses) {
  RansacSettings rs;
  rs.threshold = 0.01;
  rs.max_iterations = 50;
  std::vector<double> xyz;
  push(xyz, V3(0, 0, 1));
  push(xyz, V3(1, 0, 1));
  EXPECT_EQ(ransacPlane(view(xyz), rs).status, RansacStatus::kTooFewPoints);
  xyz.clear();
  for (int i = 0; i < 50; ++i) push(xyz, V3(0.1, 0.2, 0.3) + 0.01 * i * V3(1, -2, 0.5));
  const auto line = ransacPlane(view(xyz), rs);
  EXPECT_EQ(line.status, RansacStatus::kDegenerate);
  EXPECT_EQ(line.degenerate_samples, 50);
  // NaN rows are skipped, indices refer to the input.
  xyz.clear();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  push(xyz, V3(nan, 0, 0));
  for (int i = 0; i < 30; ++i) push(xyz, V3(0.01 * (i % 6), 0.01 * (i / 6), 0.5));
  const auto pl = ransacPlane(view(xyz), rs);
  ASSERT_TRUE(pl.success());
  EXPECT_EQ(pl.inliers.size(), 30u);
  EXPECT_EQ(pl.inliers.front(), 1u);
  // A sphere on planar data (noise below the threshold): every sample is degenerate.
  xyz.clear();
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-0.2, 0.2), w(-0.001, 0.001);
  for (int i = 0; i < 500; ++i) push(xyz, V3(u(rng), u(rng), 0.8 + w(rng)));
  rs.threshold = 0.005;
  rs.max_iterations = 200;
  const auto sp = ransacSphere(view(xyz), rs);
  EXPECT_EQ(sp.status, RansacStatus::kDegenerate);
  EXPECT_THROW(ransacPlane(view(xyz), RansacSettings{-1.0}), std::invalid_argument);
}

TEST(Segmentation, EuclideanClustersMatchBruteForceComponents) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> xyz;
  for (int i = 0; i < 600; ++i) push(xyz, V3(u(rng), u(rng), 0.2 * u(rng)));
  const auto v = view(xyz);
  std::vector<std::uint32_t> sel;
  for (std::uint32_t i = 0; i < 600; ++i)
    if (i % 5 != 0) sel.push_back(i);  // a subset: the others must be ignored
  const double tol = 0.07;
  // Brute-force connected components (union-find) over the subset.
  std::vector<std::uint32_t> parent(600);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (auto i : sel)
    for (auto j : sel)
      if (i < j && (v[i] - v[j]).norm() <= tol) parent[find(i)] = find(j);
  std::map<std::uint32_t, std::vector<std::uint32_t>> comps;
  for (auto i : sel) comps[find(i)].push_back(i);
  std::set<std::vector<std::uint32_t>> expect;
  for (auto& [root, c] : comps)
    if (c.size() >= 3 && c.size() <= 400) expect.insert(c);
  const auto got = euclideanClusters(v, sel, tol, 3, 400);
  EXPECT_EQ(std::set<std::vector<std::uint32_t>>(got.begin(), got.end()), expect);
  EXPECT_GT(expect.size(), 1u);
  for (std::size_t k = 1; k < got.size(); ++k) EXPECT_GE(got[k - 1].size(), got[k].size());
}

TEST(Segmentation, TableSceneObjectsSeparated) {
  Scene s = tableScene(13);
  // Points under the table (seen through it) and far clutter, removed by crop/below test.
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  const V3 e1 = s.n.cross(V3(1, 0, 0)).normalized(), e2 = s.n.cross(e1);
  for (int i = 0; i < 300; ++i) {
    push(s.xyz, V3(0.05, -0.1, 0.9) - (0.1 + std::abs(u(rng))) * s.n + u(rng) * e1 + u(rng) * e2);
    s.label.push_back(3);
  }
  TableSegmentationSettings ts;
  ts.plane.threshold = 0.005;
  ts.cluster_tolerance = 0.01;
  ts.min_cluster_size = 50;
  const auto seg = segmentTable(view(s.xyz), ts);
  ASSERT_TRUE(seg.success());
  EXPECT_GT(seg.plane.model.normal.dot(s.n), 1 - 1e-4);  // oriented towards the camera
  ASSERT_EQ(seg.objects.size(), 2u);
  for (const auto& obj : seg.objects) {
    std::set<int> labels;
    for (auto i : obj) labels.insert(s.label[i]);
    EXPECT_EQ(labels.size(), 1u);
    EXPECT_TRUE(*labels.begin() == 1 || *labels.begin() == 2);
  }
  EXPECT_EQ(seg.objects[0].size() + seg.objects[1].size(), 3000u);  // every object point, nothing else
}

TEST(Segmentation, AnUpThatPutsTheCameraBelowTheTableIsReported) {
  // The camera-frame scene (camera at the origin): no up orients the table towards the
  // camera, no warning; an up pointing away from the camera removes the objects as "below the
  // table" and says so; a world frame's up with the camera centre given above the table is fine.
  const Scene s = tableScene(13);
  TableSegmentationSettings ts;
  ts.plane.threshold = 0.005;
  ts.cluster_tolerance = 0.01;
  ts.min_cluster_size = 50;
  const auto plain = segmentTable(view(s.xyz), ts);
  ASSERT_TRUE(plain.success());
  EXPECT_EQ(plain.warning, "");
  EXPECT_EQ(plain.objects.size(), 2u);
  ts.up = -s.n;
  const auto wrong = segmentTable(view(s.xyz), ts);
  EXPECT_NE(wrong.warning.find("below the table"), std::string::npos) << wrong.warning;
  EXPECT_NE(wrong.warning.find("the origin"), std::string::npos) << wrong.warning;
  EXPECT_TRUE(wrong.objects.empty());  // what the warning is about
  ts.up = s.n;
  EXPECT_EQ(segmentTable(view(s.xyz), ts).warning, "");
  // A world frame: the same scene moved so that the origin is under the table, the camera
  // centre given. Its up is not contradicted; a viewpoint under the table is.
  std::vector<double> moved = s.xyz;
  const V3 shift = 2.0 * s.n;
  for (std::size_t i = 0; i < moved.size(); i += 3)
    for (int k = 0; k < 3; ++k) moved[i + k] -= shift[k];
  ts.viewpoint = -shift;
  const auto world = segmentTable(view(moved), ts);
  EXPECT_EQ(world.warning, "");
  EXPECT_EQ(world.objects.size(), 2u);
  ts.viewpoint = V3(-shift - 3.0 * s.n);
  const auto under = segmentTable(view(moved), ts);
  EXPECT_NE(under.warning.find("below the table"), std::string::npos);
  EXPECT_EQ(under.warning.find("the origin"), std::string::npos);  // a given viewpoint is named as such
}


std::atomic<int> ransac_hook_calls{0};
bool stopOnThirdCall() { return ++ransac_hook_calls >= 3; }

TEST(Ransac, InterruptHookStopsTheLoopBetweenBatches) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<double> xyz;
  for (int i = 0; i < 2000; ++i) push(xyz, V3(u(rng), u(rng), 0.01 * u(rng)));
  RansacSettings rs;
  rs.threshold = 0.001;
  rs.max_iterations = 1 << 30;
  rs.confidence = 0;  // no adaptive stop: 2^30 hypotheses unless interrupted
  ransac_hook_calls = 0;
  interrupt_hook.store(&stopOnThirdCall);
  EXPECT_THROW(ransacPlane(view(xyz), rs), Interrupted);
  interrupt_hook.store(nullptr);
  EXPECT_EQ(ransac_hook_calls.load(), 3);
  rs.max_iterations = 50;  // and the next call runs normally
  EXPECT_EQ(ransacPlane(view(xyz), rs).iterations, 50);
}

TEST(Segmentation, EuclideanClustersMatchBruteForceAtEveryTolerance) {
  // Clumps, a sparse scatter, exact duplicates and a tolerance from far below the spacing
  // to far beyond the extent (one cluster): the cell union-find gives exactly the connected
  // components of |p - q| <= tolerance.
  std::mt19937 rng(23);
  std::normal_distribution<double> g(0, 0.03);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<double> xyz;
  for (int i = 0; i < 700; ++i) {
    const V3 p = i % 3 == 0 ? V3(u(rng), u(rng), 0.2 * u(rng)) : V3(0.3 * (i % 3) + g(rng), 0.5 + g(rng), g(rng));
    push(xyz, p);
    if (i % 50 == 0) push(xyz, p);  // a duplicate
  }
  const auto v = view(xyz);
  const auto n = static_cast<std::uint32_t>(v.size);
  std::vector<std::uint32_t> sel;
  for (std::uint32_t i = 0; i < n; ++i) sel.push_back(i);
  for (const double tol : {1e-9, 0.005, 0.02, 0.05, 0.1, 0.3, 100.0}) {
    std::vector<std::uint32_t> parent(n);
    std::iota(parent.begin(), parent.end(), 0u);
    auto find = [&](std::uint32_t x) {
      while (parent[x] != x) x = parent[x] = parent[parent[x]];
      return x;
    };
    for (std::uint32_t i = 0; i < n; ++i)
      for (std::uint32_t j = i + 1; j < n; ++j)
        if ((v[i] - v[j]).squaredNorm() <= tol * tol) parent[find(i)] = find(j);
    std::map<std::uint32_t, std::vector<std::uint32_t>> comps;
    for (auto i : sel) comps[find(i)].push_back(i);
    std::vector<std::vector<std::uint32_t>> expect;
    for (auto& [root, c] : comps) expect.push_back(c);
    std::sort(expect.begin(), expect.end(), [](const auto& a, const auto& b) {
      return a.size() != b.size() ? a.size() > b.size() : a.front() < b.front();
    });
    EXPECT_EQ(euclideanClusters(v, sel, tol, 1, SIZE_MAX), expect) << "tolerance " << tol;
    if (tol == 100.0) EXPECT_EQ(expect.size(), 1u);
  }
}

}  // namespace
}  // namespace scanalign

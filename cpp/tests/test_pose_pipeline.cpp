// The C++ CAD-pose pipeline: tessellated-sphere viewpoints, rendered model views against the
// analytic surface, estimatePose against a known pose, and its refusals.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <utility>

#include <Eigen/Geometry>

#include "scanalign/pose/pose_estimation.hpp"

namespace {

using scanalign::CloudView;

// A 60 x 40 x 20 mm block (corners at 0 and `size`): 8 vertices, 12 outward triangles.
struct Block {
  Eigen::Vector3d size{0.06, 0.04, 0.02};
  std::vector<double> V;
  std::vector<std::int32_t> F;
  Block() {
    for (int k = 0; k < 8; ++k) V.insert(V.end(), {k & 1 ? size.x() : 0.0, k & 2 ? size.y() : 0.0, k & 4 ? size.z() : 0.0});
    F = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4, 2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};
  }
  CloudView<double> vertices() const { return {V.data(), V.size() / 3}; }
};

TEST(ModelViews, TessellatedSphereIsClosedUnitAndWoundOutwards) {
  for (int level = 0; level <= 2; ++level) {
    const auto s = scanalign::tessellatedSphere(level);
    const std::size_t nv = 10 * (std::size_t{1} << (2 * level)) + 2, nf = 20 * (std::size_t{1} << (2 * level));
    ASSERT_EQ(s.vertices.size(), nv);
    ASSERT_EQ(s.faces.size(), nf);
    std::map<std::pair<int, int>, int> edges;
    for (const auto& f : s.faces) {
      for (int k = 0; k < 3; ++k) ++edges[{std::min(f[k], f[(k + 1) % 3]), std::max(f[k], f[(k + 1) % 3])}];
      const Eigen::Vector3d a = s.vertices[f[0]], b = s.vertices[f[1]], c = s.vertices[f[2]];
      EXPECT_GT((b - a).cross(c - a).dot(a + b + c), 0.0);  // outward
    }
    for (const auto& e : edges) EXPECT_EQ(e.second, 2);    // closed
    EXPECT_EQ(static_cast<long>(nv) - static_cast<long>(edges.size()) + static_cast<long>(nf), 2);  // Euler
    for (const auto& v : s.vertices) EXPECT_NEAR(v.norm(), 1.0, 1e-15);
  }
  EXPECT_THROW(scanalign::tessellatedSphere(-1), std::invalid_argument);
}

TEST(ModelViews, PointsLieOnTheBlockFaceTheirCameraAndReproject) {
  const Block b;
  scanalign::ModelViewSettings s;
  s.resolution = 80;
  const auto views = scanalign::renderModelViews(b.vertices(), b.F.data(), b.F.size() / 3, s);
  ASSERT_EQ(views.size(), 42u);
  for (const auto& v : views) {
    ASSERT_GT(v.size(), 100u);
    const Eigen::Vector3d eye = v.T_model_camera.topRightCorner<3, 1>();
    for (std::size_t i = 0; i < v.size(); ++i) {
      const Eigen::Vector3d p(&v.points[3 * i]), n(&v.normals[3 * i]);
      // On the block's surface: inside the box and on one of its faces (exact z-buffer, up to
      // the float32 depth buffer: 6e-8 relative at ~0.1 m).
      const Eigen::Vector3d lo = p, hi = b.size - p;
      EXPECT_GT(std::min(lo.minCoeff(), hi.minCoeff()), -1e-7);
      EXPECT_LT(std::min(lo.cwiseAbs().minCoeff(), hi.cwiseAbs().minCoeff()), 1e-7);
      EXPECT_NEAR(n.norm(), 1.0, 1e-12);
      EXPECT_GT(n.dot(eye - p), 0.0);  // towards the camera
      const Eigen::Vector3d pc = v.T_model_camera.topLeftCorner<3, 3>().transpose() * (p - eye);
      EXPECT_NEAR(v.intrinsics.fx * pc.x() / pc.z() + v.intrinsics.cx, v.pixels[2 * i], 1e-6);
      EXPECT_NEAR(v.intrinsics.fy * pc.y() / pc.z() + v.intrinsics.cy, v.pixels[2 * i + 1], 1e-6);
    }
  }
  std::vector<std::int32_t> bad = b.F;
  bad[4] = 99;
  EXPECT_THROW(scanalign::renderModelViews(b.vertices(), bad.data(), bad.size() / 3, s), std::invalid_argument);
  s.resolution = 1;
  EXPECT_THROW(scanalign::renderModelViews(b.vertices(), b.F.data(), b.F.size() / 3, s), std::invalid_argument);
}

TEST(PoseEstimation, RecoversAKnownPoseOfAViewAndRefusesBadInput) {
  // Two blocks (an L-shaped part: no rotation maps it onto itself).
  Block a;
  std::vector<double> V = a.V;
  std::vector<std::int32_t> F = a.F;
  for (int k = 0; k < 8; ++k) V.insert(V.end(), {k & 1 ? 0.02 : 0.0, k & 2 ? 0.04 : 0.0, k & 4 ? 0.05 : 0.02});
  for (std::size_t i = 0; i < a.F.size(); ++i) F.push_back(a.F[i] + 8);
  scanalign::ModelViewSettings vs;
  vs.resolution = 120;
  const auto views = scanalign::renderModelViews(CloudView<double>(V.data(), V.size() / 3), F.data(), F.size() / 3, vs);
  const Eigen::Affine3d T_true = Eigen::Translation3d(-0.05, 0.03, 0.4) * Eigen::AngleAxisd(2.1, Eigen::Vector3d(1, 1, -0.5).normalized());
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 5e-5);
  std::vector<double> scene;
  for (std::size_t i = 0; i < views[9].size(); ++i) {
    const Eigen::Vector3d p = T_true * Eigen::Vector3d(&views[9].points[3 * i]);
    scene.insert(scene.end(), {p.x() + noise(rng), p.y() + noise(rng), p.z() + noise(rng)});
  }
  const CloudView<double> sv(scene.data(), scene.size() / 3);
  const scanalign::PoseResult r = scanalign::estimatePose(views, sv, {}, {9, 20, 33});
  ASSERT_TRUE(r.found) << r.message;
  EXPECT_EQ(r.view, 9);
  ASSERT_EQ(r.candidates.size(), 3u);
  const Eigen::Matrix3d dR = r.T_scene_model.topLeftCorner<3, 3>().transpose() * T_true.linear();
  EXPECT_LT(Eigen::AngleAxisd(dR).angle(), 0.5 * M_PI / 180);
  EXPECT_LT((r.T_scene_model.topRightCorner<3, 1>() - T_true.translation()).norm(), 0.001);
  EXPECT_GT(r.fitness, 0.95);
  EXPECT_GT(r.coverage, 0.95);

  // Refusals: a tiny scene is a status, bad settings and indices are exceptions.
  const scanalign::PoseResult tiny = scanalign::estimatePose(views, CloudView<double>(scene.data(), 5), {}, {9});
  EXPECT_FALSE(tiny.found);
  EXPECT_NE(tiny.message.find("need at least 10"), std::string::npos);
  EXPECT_THROW(scanalign::estimatePose(views, sv, {}, {42}), std::invalid_argument);
  scanalign::PoseSettings bad;
  bad.inlier_threshold = -1;
  EXPECT_THROW(scanalign::estimatePose(views, sv, bad, {9}), std::invalid_argument);
  scanalign::PoseSettings external;
  external.method = scanalign::CoarseMethod::External;
  EXPECT_THROW(scanalign::estimatePose(views, sv, external, {9}), std::invalid_argument);  // no aligner
}

}  // namespace

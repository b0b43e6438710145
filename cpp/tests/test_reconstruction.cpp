// Depth images to clouds and the frame-to-model pipeline, against analytic scenes whose
// depth is ray-cast exactly in the test (independent of the library's renderer).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <Eigen/Geometry>

#include "scanalign/reconstruction/depth_image.hpp"
#include "scanalign/pose/model_views.hpp"  // lookAt
#include "scanalign/reconstruction/frame_to_model.hpp"
#include "test_support.hpp"

using namespace scanalign;
using scanalign::test::rigid;

namespace {

// Half the SR300 resolution of the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929): about 1.4 mm per pixel at 0.4 m. (Much sparser
// images -- 3 mm pixels -- leave too few points on the small spheres for 5 mm normals.)
PinholeIntrinsics smallCamera() { return PinholeIntrinsics{320, 240, 240.0, 242.0, 159.5, 119.5}; }

// Scene in the world frame: a 30 x 30 cm table (z = 0) with four spheres on it.
struct Sphere {
  Eigen::Vector3d c;
  double r;
};
const std::vector<Sphere>& spheres() {
  static const std::vector<Sphere> s = {{{0.0, 0.0, 0.03}, 0.03},
                                        {{0.04, 0.01, 0.02}, 0.02},
                                        {{-0.02, 0.04, 0.015}, 0.015},
                                        {{0.01, -0.045, 0.025}, 0.018}};
  return s;
}

// Exact depth (z in the camera frame) of the scene seen from T_world_camera.
std::vector<float> rayCast(const Eigen::Matrix4d& T_world_camera, const PinholeIntrinsics& K, double noise = 0.0,
                           std::uint32_t seed = 0) {
  std::vector<float> depth(static_cast<std::size_t>(K.width) * K.height, 0.0f);
  const Eigen::Matrix3d R = T_world_camera.topLeftCorner<3, 3>();
  const Eigen::Vector3d o = T_world_camera.topRightCorner<3, 1>();
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, noise > 0 ? noise : 1.0);
  for (int v = 0; v < K.height; ++v)
    for (int u = 0; u < K.width; ++u) {
      const Eigen::Vector3d d = R * Eigen::Vector3d((u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0);  // z_cam = 1
      double best = std::numeric_limits<double>::infinity();
      const double tp = -o.z() / d.z();
      const Eigen::Vector3d hit = o + tp * d;
      if (tp > 0 && std::abs(hit.x()) < 0.15 && std::abs(hit.y()) < 0.15) best = tp;
      for (const auto& s : spheres()) {
        const Eigen::Vector3d oc = o - s.c;
        const double a = d.dot(d), b = d.dot(oc), c = oc.dot(oc) - s.r * s.r;
        const double disc = b * b - a * c;
        if (disc <= 0) continue;
        const double t = (-b - std::sqrt(disc)) / a;
        if (t > 0 && t < best) best = t;
      }
      if (std::isfinite(best)) depth[static_cast<std::size_t>(v) * K.width + u] = float(best + (noise > 0 ? g(rng) : 0.0));
    }
  return depth;
}

// Camera on a circle of radius 0.25 m, 0.35 m above the table, looking at the object.
Eigen::Matrix4d loopPose(int i, int n) {
  const double a = 2.0 * M_PI * i / n;
  return lookAt(Eigen::Vector3d(0.25 * std::cos(a), 0.25 * std::sin(a), 0.35), Eigen::Vector3d(0, 0, 0.02));
}

DepthCloud cloudOf(const std::vector<float>& depth, const PinholeIntrinsics& K) {
  DepthToCloudSettings s;
  s.max_depth = 3.0;
  return depthToCloud(depth.data(), K, s);
}

double translationError(const Eigen::Matrix4d& A, const Eigen::Matrix4d& B) {
  return (A.topRightCorner<3, 1>() - B.topRightCorner<3, 1>()).norm();
}

}  // namespace

TEST(DepthToCloud, BackProjectsExactlyAndDropsInvalidPixels) {
  const PinholeIntrinsics K{4, 3, 100.0, 110.0, 1.5, 1.0};
  // uint16 millimetres: 0 = invalid, 50 mm below min_depth, 2500 above max_depth.
  std::vector<std::uint16_t> mm = {500, 0, 600, 700, 50, 800, 900, 1000, 2500, 1100, 1200, 1300};
  std::vector<std::uint8_t> rgb(12 * 3);
  for (std::size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<std::uint8_t>(i);
  DepthToCloudSettings s;
  s.depth_scale = 0.001;
  s.min_depth = 0.1;
  s.max_depth = 2.0;
  const DepthCloud c = depthToCloud(mm.data(), K, s, rgb.data());
  ASSERT_EQ(c.size(), 9u);
  for (std::size_t k = 0; k < c.size(); ++k) {
    const int pixel = c.pixels[k], u = pixel % 4, v = pixel / 4;
    const double z = mm[pixel] * 0.001;
    EXPECT_NEAR(c.points[3 * k + 0], z * (u - 1.5) / 100.0, 1e-7);
    EXPECT_NEAR(c.points[3 * k + 1], z * (v - 1.0) / 110.0, 1e-7);
    EXPECT_NEAR(c.points[3 * k + 2], z, 1e-7);
    EXPECT_EQ(c.colors[3 * k + 1], rgb[3 * pixel + 1]);
    EXPECT_NE(mm[pixel], 0);
    EXPECT_NE(pixel, 4);
    EXPECT_NE(pixel, 8);
  }
  // Float metres: NaN, negative and infinite are invalid; stride 2 samples every other pixel.
  std::vector<float> m(12, 1.0f);
  m[0] = std::nanf("");
  m[2] = -1.0f;
  m[8] = std::numeric_limits<float>::infinity();
  s.stride = 2;
  const DepthCloud f = depthToCloud(m.data(), K, s);
  EXPECT_EQ(f.size(), 1u);  // pixels 0, 2, 8, 10 sampled; only 10 is valid
  EXPECT_EQ(f.pixels[0], 10);
  s.stride = 1;
  EXPECT_EQ(depthToCloud(m.data(), K, s).size(), 9u);
}

TEST(DepthToCloud, RejectsBadInput) {
  std::vector<float> d(12, 1.0f);
  DepthToCloudSettings s;
  EXPECT_THROW(depthToCloud(d.data(), PinholeIntrinsics{0, 3, 1, 1, 0, 0}, s), std::invalid_argument);
  EXPECT_THROW(depthToCloud(d.data(), PinholeIntrinsics{4, 3, -1, 1, 0, 0}, s), std::invalid_argument);
  EXPECT_THROW(depthToCloud(d.data(), PinholeIntrinsics{4, 3, 1, 1, std::nan(""), 0}, s), std::invalid_argument);
  s.min_depth = 2.0;
  s.max_depth = 1.0;
  EXPECT_THROW(depthToCloud(d.data(), PinholeIntrinsics{4, 3, 1, 1, 0, 0}, s), std::invalid_argument);
  s = DepthToCloudSettings{};
  s.stride = 0;
  EXPECT_THROW(depthToCloud(d.data(), PinholeIntrinsics{4, 3, 1, 1, 0, 0}, s), std::invalid_argument);
}

TEST(FrameToModel, TracksALoopAndKeepsTheModelBounded) {
  const PinholeIntrinsics K = smallCamera();
  const int n = 24;
  FrameToModel f2m;
  f2m.reset(loopPose(0, n));  // the model lives in the world frame
  std::size_t max_model = 0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Matrix4d T_true = loopPose(i, n);
    const DepthCloud c = cloudOf(rayCast(T_true, K, 0.0003, i), K);
    const FrameReport r = f2m.integrate(CloudView<float>(c.points.data(), c.size()));
    ASSERT_TRUE(r.merged()) << i << " " << toString(r.status);
    EXPECT_EQ(r.index, i);
    EXPECT_LT(translationError(r.T_model_camera, T_true), 0.002) << "frame " << i;
    max_model = std::max(max_model, r.model_points);
  }
  EXPECT_EQ(f2m.framesMerged(), n);
  // Bounded: 1 mm voxels over a 30 x 30 cm table and the spheres' visible caps, with a
  // couple of layers of noise, are far fewer than all frames' points together.
  EXPECT_LT(max_model, 400000u);
  // Integrating the same view again does not grow the model much: the voxel grid merges it.
  const std::size_t before = f2m.model().size();
  const DepthCloud c = cloudOf(rayCast(loopPose(0, n), K), K);
  const FrameReport again = f2m.integrate(CloudView<float>(c.points.data(), c.size()), nullptr);
  ASSERT_TRUE(again.merged());
  EXPECT_LT(f2m.model().size(), before + before / 20);
}

TEST(FrameToModel, SkippedFramesLeaveTheModelUnchanged) {
  const PinholeIntrinsics K = smallCamera();
  FrameToModel f2m;
  const DepthCloud first = cloudOf(rayCast(loopPose(0, 24), K), K);
  std::vector<std::uint8_t> colors(3 * first.size(), 200);
  ASSERT_EQ(f2m.integrate(CloudView<float>(first.points.data(), first.size()), colors.data()).status,
            FrameStatus::Initialized);
  const Model before = f2m.model();
  ASSERT_EQ(before.colors.size(), before.points.size());
  // Empty frame, a frame of NaNs, a handful of points, and a frame far from the model.
  std::vector<float> nans(300, std::nanf(""));
  std::vector<float> few;  // a 10 x 5 mm patch: normals fine, but under min_frame_points
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 5; ++j) few.insert(few.end(), {0.001f * float(i), 0.001f * float(j), 0.4f});
  std::vector<float> far(3000);
  for (std::size_t i = 0; i < far.size() / 3; ++i) {
    far[3 * i] = 0.001f * float(i % 40);
    far[3 * i + 1] = 0.001f * float(i / 40);
    far[3 * i + 2] = 5.0f;
  }
  EXPECT_EQ(f2m.integrate(CloudView<float>()).status, FrameStatus::SkippedEmpty);
  EXPECT_EQ(f2m.integrate(CloudView<float>(nans.data(), 100)).status, FrameStatus::SkippedEmpty);
  EXPECT_EQ(f2m.integrate(CloudView<float>(few.data(), few.size() / 3)).status, FrameStatus::SkippedTooFewPoints);
  const FrameReport r = f2m.integrate(CloudView<float>(far.data(), far.size() / 3));
  EXPECT_FALSE(r.merged());
  EXPECT_TRUE(r.status == FrameStatus::SkippedTooFewCorrespondences || r.status == FrameStatus::SkippedLowFitness)
      << toString(r.status);
  EXPECT_EQ(f2m.model().points, before.points);
  EXPECT_EQ(f2m.model().normals.size(), before.normals.size());
  EXPECT_EQ(f2m.model().colors, before.colors);
  EXPECT_EQ(f2m.framesMerged(), 1);
  EXPECT_TRUE(f2m.lastPose().isIdentity());
}

TEST(FrameToModel, ChecksRejectJumpsAndUnconvergedResults) {
  FrameToModelSettings s;
  s.max_translation_change = 0.05;
  s.max_rotation_change = 0.2;
  FrameToModel f2m(s);
  IcpResult r;
  r.converged = true;
  r.fitness = 0.9;
  const Eigen::Matrix4d guess = rigid(0.1, 0.2, 0.3, 0.1, 0.2, 0.3);
  r.T_target_source = guess * rigid(0, 0, 0, 0.04, 0, 0);
  EXPECT_EQ(f2m.check(r, guess), FrameStatus::Registered);
  r.T_target_source = guess * rigid(0, 0, 0, 0.06, 0, 0);
  EXPECT_EQ(f2m.check(r, guess), FrameStatus::SkippedMotion);
  r.T_target_source = guess * rigid(0.0, 0.25, 0, 0, 0, 0);
  EXPECT_EQ(f2m.check(r, guess), FrameStatus::SkippedMotion);
  r.T_target_source = guess;
  r.fitness = 0.1;
  EXPECT_EQ(f2m.check(r, guess), FrameStatus::SkippedLowFitness);
  r.fitness = 0.9;
  r.converged = false;
  EXPECT_EQ(f2m.check(r, guess), FrameStatus::SkippedNoConvergence);
  f2m.settings().require_convergence = false;
  EXPECT_EQ(f2m.check(r, guess), FrameStatus::Registered);
  r.status = IcpStatus::NotEnoughCorrespondences;
  EXPECT_EQ(f2m.check(r, guess), FrameStatus::SkippedTooFewCorrespondences);
}

TEST(FrameToModel, ExternalPoseMergeAndBadSettings) {
  const PinholeIntrinsics K = smallCamera();
  FrameToModel f2m;
  const DepthCloud c = cloudOf(rayCast(loopPose(0, 24), K), K);
  const PreparedFrame p = f2m.prepare(CloudView<float>(c.points.data(), c.size()));
  ASSERT_GT(p.size(), 1000u);
  // Normals face the camera (origin of the camera frame).
  for (std::size_t i = 0; i < p.size(); ++i) {
    const Eigen::Vector3f q(&p.points[3 * i]), nn(&p.normals[3 * i]);
    ASSERT_LE(q.dot(nn), 1e-6f);
    ASSERT_NEAR(nn.norm(), 1.0f, 1e-4f);
  }
  const Eigen::Matrix4d T = rigid(0.1, -0.2, 0.3, 0.5, 0.1, -0.2);
  f2m.merge(p, T);
  EXPECT_TRUE(f2m.lastPose().isApprox(T));
  // Every model point is a merged frame point mapped by T (1 mm voxels average within 1.8 mm).
  Eigen::Vector3d mean_model = Eigen::Vector3d::Zero(), mean_frame = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < f2m.model().size(); ++i) mean_model += Eigen::Vector3f(&f2m.model().points[3 * i]).cast<double>();
  for (std::size_t i = 0; i < p.size(); ++i) mean_frame += Eigen::Vector3f(&p.points[3 * i]).cast<double>();
  mean_model /= double(f2m.model().size());
  mean_frame /= double(p.size());
  const Eigen::Vector3d mapped = T.topLeftCorner<3, 3>() * mean_frame + T.topRightCorner<3, 1>();
  EXPECT_LT((mapped - mean_model).norm(), 0.002);
  FrameToModelSettings bad;
  bad.model_voxel_size = 0.0;
  EXPECT_THROW(FrameToModel{bad}, std::invalid_argument);
  bad = FrameToModelSettings{};
  bad.min_fitness = 1.5;
  EXPECT_THROW(FrameToModel{bad}, std::invalid_argument);
  Eigen::Matrix4d not_rigid = Eigen::Matrix4d::Identity();
  not_rigid(0, 0) = 2.0;
  EXPECT_THROW(f2m.merge(p, not_rigid), std::invalid_argument);
  EXPECT_THROW(f2m.reset(not_rigid), std::invalid_argument);
}

TEST(FrameToModel, ConstantVelocityPredictsTheLastMotionAgain) {
  const PinholeIntrinsics K = smallCamera();
  FrameToModelSettings s;
  s.motion_model = MotionModel::ConstantVelocity;
  FrameToModel f2m(s);
  const Eigen::Matrix4d T0 = rigid(0.1, -0.2, 0.3, 0.5, 0.1, -0.2);
  f2m.reset(T0);
  EXPECT_EQ(f2m.predictedPose(), T0);  // nothing merged: the initial pose
  const DepthCloud c = cloudOf(rayCast(loopPose(0, 24), K), K);
  const PreparedFrame p = f2m.prepare(CloudView<float>(c.points.data(), c.size()));
  f2m.merge(p, T0);
  EXPECT_EQ(f2m.predictedPose(), T0);  // one pose: no velocity yet
  // The camera moves by M (in its own frame) between frames: the next pose is T0 M M.
  const Eigen::Matrix4d M = rigid(0.004, -0.002, 0.003, 0.02, 0.01, -0.015);
  f2m.merge(p, T0 * M);
  const Eigen::Matrix4d predicted = f2m.predictedPose();
  EXPECT_LT((predicted - T0 * M * M).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((predicted.topLeftCorner<3, 3>().transpose() * predicted.topLeftCorner<3, 3>() -
             Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-14);
  f2m.settings().motion_model = MotionModel::Previous;
  EXPECT_EQ(f2m.predictedPose(), T0 * M);
  f2m.reset();
  EXPECT_TRUE(f2m.predictedPose().isIdentity());
}

TEST(FrameToModel, ConstantVelocityTracksALoopInFewerIterations) {
  // The loop turns at a constant rate: the prediction starts each frame near its pose.
  const PinholeIntrinsics K = smallCamera();
  const int n = 24;
  int iterations[2] = {0, 0};
  for (MotionModel model : {MotionModel::Previous, MotionModel::ConstantVelocity}) {
    FrameToModelSettings s;
    s.motion_model = model;
    FrameToModel f2m(s);
    f2m.reset(loopPose(0, n));
    for (int i = 0; i < n; ++i) {
      const Eigen::Matrix4d T_true = loopPose(i, n);
      const DepthCloud c = cloudOf(rayCast(T_true, K, 0.0003, i), K);
      const FrameReport r = f2m.integrate(CloudView<float>(c.points.data(), c.size()));
      ASSERT_TRUE(r.merged()) << toString(model) << " frame " << i << " " << toString(r.status);
      EXPECT_LT(translationError(r.T_model_camera, T_true), 0.002) << toString(model) << " frame " << i;
      iterations[model == MotionModel::ConstantVelocity] += r.icp.iterations;
    }
  }
  EXPECT_LT(iterations[1], 0.7 * iterations[0]) << iterations[0] << " vs " << iterations[1];
}

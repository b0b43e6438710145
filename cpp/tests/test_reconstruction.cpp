// Depth images to clouds and the frame-to-model pipeline, against analytic scenes whose
// depth is ray-cast exactly in the test (independent of the library's renderer).
#include <gtest/gtest.h>
#include <omp.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <new>
#include <random>
#include <thread>
#include <vector>

#include <Eigen/Geometry>

#include "scanalign/common/look_at.hpp"
#include "scanalign/reconstruction/bilateral_filter.hpp"
#include "scanalign/reconstruction/depth_image.hpp"
#include "scanalign/reconstruction/depth_renderer.hpp"
#include "scanalign/reconstruction/frame_to_model.hpp"
#include "scanalign/reconstruction/reconstruction_settings.hpp"
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
    const FrameResult r = f2m.integrate(CloudView<float>(c.points.data(), c.size()));
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
  const FrameResult again = f2m.integrate(CloudView<float>(c.points.data(), c.size()), nullptr);
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
  const FrameResult r = f2m.integrate(CloudView<float>(far.data(), far.size() / 3));
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
      const FrameResult r = f2m.integrate(CloudView<float>(c.points.data(), c.size()));
      ASSERT_TRUE(r.merged()) << toString(model) << " frame " << i << " " << toString(r.status);
      EXPECT_LT(translationError(r.T_model_camera, T_true), 0.002) << toString(model) << " frame " << i;
      iterations[model == MotionModel::ConstantVelocity] += r.icp.iterations;
    }
  }
  EXPECT_LT(iterations[1], 0.7 * iterations[0]) << iterations[0] << " vs " << iterations[1];
}

// ---------------------------------------------------------------------------------------
// No lost data under faults (issue 16): whatever throws during a frame -- bad input, a
// failed allocation at any point of the registration or the merge, an interrupt -- the
// model, the poses and the frame counts are exactly as before the call.

#if defined(__SANITIZE_ADDRESS__)
#define SCANALIGN_TEST_FAULTS 0  // the sanitizer owns operator new
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SCANALIGN_TEST_FAULTS 0
#else
#define SCANALIGN_TEST_FAULTS 1
#endif
#else
#define SCANALIGN_TEST_FAULTS 1
#endif

namespace {
// Failure injection: when armed, the `countdown`-th allocation of the armed thread throws
// std::bad_alloc. Allocations inside OpenMP regions never fail here (an exception must not
// leave one: std::terminate, a known limit of OpenMP code), so the sweep covers every
// allocation of the serial steps, where an exception can arise and unwind.
std::atomic<long> fault_countdown{-1};
std::atomic<std::thread::id> fault_thread{};

struct ArmFault {
  explicit ArmFault(long countdown) {
    fault_thread = std::this_thread::get_id();
    fault_countdown = countdown;
  }
  ~ArmFault() { fault_countdown = -1; }
};

bool sameBytes(const Model& a, const Model& b) {
  auto same = [](const auto& x, const auto& y) {
    return x.size() == y.size() && (x.empty() || std::memcmp(x.data(), y.data(), x.size() * sizeof(x[0])) == 0);
  };
  return same(a.points, b.points) && same(a.normals, b.normals) && same(a.colors, b.colors);
}

struct Snapshot {
  Model model;
  Eigen::Matrix4d last_pose, predicted;
  int seen, merged;
  explicit Snapshot(const FrameToModel& f)
      : model(f.model()), last_pose(f.lastPose()), predicted(f.predictedPose()), seen(f.framesSeen()),
        merged(f.framesMerged()) {}
  void expectUnchanged(const FrameToModel& f, const std::string& what) const {
    EXPECT_TRUE(sameBytes(f.model(), model)) << what;
    EXPECT_EQ(f.lastPose(), last_pose) << what;
    EXPECT_EQ(f.predictedPose(), predicted) << what;
    EXPECT_EQ(f.framesSeen(), seen) << what;
    EXPECT_EQ(f.framesMerged(), merged) << what;
  }
};

// A first frame merged (with colours), and the second frame of the loop.
struct TwoFrames {
  FrameToModel f2m;
  DepthCloud second;
  std::vector<std::uint8_t> colors;
  TwoFrames() {
    FrameToModelSettings s;
    s.motion_model = MotionModel::ConstantVelocity;
    f2m = FrameToModel(s);
    const PinholeIntrinsics K = smallCamera();
    const DepthCloud first = cloudOf(rayCast(loopPose(0, 24), K), K);
    colors.assign(3 * first.size(), 90);
    EXPECT_EQ(f2m.integrate(CloudView<float>(first.points.data(), first.size()), colors.data()).status,
              FrameStatus::Initialized);
    second = cloudOf(rayCast(loopPose(1, 24), K), K);
    colors.assign(3 * second.size(), 200);
  }
  CloudView<float> view() const { return CloudView<float>(second.points.data(), second.size()); }
};
}  // namespace

#if SCANALIGN_TEST_FAULTS
void* operator new(std::size_t size) {
  if (fault_countdown.load(std::memory_order_relaxed) >= 0 && std::this_thread::get_id() == fault_thread.load() &&
      omp_get_level() == 0 && fault_countdown.fetch_sub(1) == 0) {
    fault_countdown = -1;
    throw std::bad_alloc();
  }
  if (void* p = std::malloc(size > 0 ? size : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#endif

/// Fails the k-th allocation of `call` for k = 0, 1, ... until a call goes through, and
/// expects the model unchanged after each failure; returns how many allocations failed.
template <typename Call>
long sweepAllocationFailures(FrameToModel& f2m, const std::string& what, Call call) {
  for (long k = 0;; ++k) {
    const Snapshot before(f2m);
    try {
      ArmFault arm(k);
      call();
      return k;
    } catch (const std::bad_alloc&) {
    }
    before.expectUnchanged(f2m, what + " " + std::to_string(k) + " failed");
    if (::testing::Test::HasFailure()) return k + 1;
  }
}

TEST(FrameToModelFaults, AFailedAllocationAnywhereInAFrameLeavesTheModelUnchanged) {
  if (!SCANALIGN_TEST_FAULTS) GTEST_SKIP() << "operator new belongs to the sanitizer";
  TwoFrames t;
  t.f2m.settings().num_threads = 1;
  // The frame as it is merged without faults: the reference.
  FrameToModel clean = t.f2m;
  const FrameResult expected = clean.integrate(t.view(), t.colors.data());
  ASSERT_EQ(expected.status, FrameStatus::Registered);
  const long failures = sweepAllocationFailures(t.f2m, "allocation", [&] { t.f2m.integrate(t.view(), t.colors.data()); });
  if (HasFailure()) return;
  // Allocations fail in preparation, registration and merge alike (dozens of them); the
  // frame then goes through as if nothing had happened: the same pose and points (after a
  // failed merge the next one re-grids, re-normalising normals to within float rounding).
  EXPECT_GT(failures, 20);
  EXPECT_EQ(t.f2m.framesMerged(), clean.framesMerged());  // the sweep's last call went through
  EXPECT_EQ(t.f2m.framesSeen(), clean.framesSeen());
  EXPECT_LT(translationError(t.f2m.lastPose(), expected.T_model_camera), 1e-9);
  EXPECT_EQ(t.f2m.model().size(), clean.model().size());
}

TEST(FrameToModelFaults, AFailedAllocationInTheMergeChangesNothing) {
  if (!SCANALIGN_TEST_FAULTS) GTEST_SKIP() << "operator new belongs to the sanitizer";
  TwoFrames t;
  const PreparedFrame frame = t.f2m.prepare(t.view(), t.colors.data());
  const Eigen::Matrix4d T = loopPose(1, 24) * rigid(0, 0, 0, 0, 0, 0);
  FrameToModel clean = t.f2m;
  clean.merge(frame, T);
  const long failures = sweepAllocationFailures(t.f2m, "merge allocation", [&] { t.f2m.merge(frame, T); });
  if (HasFailure()) return;
  EXPECT_GE(failures, 5);  // the transformed frame, keys, index, sums, the model's growth
  // The merge that finally went through re-gridded (the index was dropped by the first
  // failure): the same points and colours as the clean merge, bit for bit, up to order.
  ASSERT_EQ(t.f2m.model().size(), clean.model().size());
  EXPECT_EQ(t.f2m.lastPose(), clean.lastPose());
}

TEST(FrameToModelFaults, BadFramesThrowAndChangeNothing) {
  TwoFrames t;
  const Snapshot before(t.f2m);
  Eigen::Matrix4d nan_guess = loopPose(1, 24);
  nan_guess(0, 3) = std::nan("");
  Eigen::Matrix4d scaled = Eigen::Matrix4d::Identity();
  scaled.topLeftCorner<3, 3>() *= 2.0;
  for (const Eigen::Matrix4d* guess : {&nan_guess, &scaled}) {
    EXPECT_THROW(t.f2m.integrate(t.view(), nullptr, guess), std::invalid_argument);
    before.expectUnchanged(t.f2m, "bad guess");
  }
  PreparedFrame bad = t.f2m.prepare(t.view());
  bad.normals.pop_back();
  EXPECT_THROW(t.f2m.merge(bad, loopPose(1, 24)), std::invalid_argument);
  EXPECT_THROW(t.f2m.merge(t.f2m.prepare(t.view()), scaled), std::invalid_argument);
  // A rigid pose 1e30 m away: every point is beyond the model's range (dropped, counted);
  // as the first pose of an empty model no voxel coordinate can hold it (an error).
  Eigen::Matrix4d beyond = Eigen::Matrix4d::Identity();
  beyond(0, 3) = 1e30;
  const PreparedFrame p = t.f2m.prepare(t.view());
  std::size_t far = 0;
  EXPECT_EQ(t.f2m.merge(p, beyond, &far), before.model.size());
  EXPECT_EQ(far, p.size());
  FrameToModel empty;
  EXPECT_THROW(empty.merge(p, beyond), std::invalid_argument);
  EXPECT_EQ(empty.model().size(), 0u);
  EXPECT_EQ(empty.framesMerged(), 0);
  before.expectUnchanged(t.f2m, "bad merge");
  // Invalid settings are refused before anything happens.
  t.f2m.settings().min_fitness = std::nan("");
  EXPECT_THROW(t.f2m.integrate(t.view()), std::invalid_argument);
  before.expectUnchanged(t.f2m, "bad settings");
}

#if __has_include("scanalign/common/interrupt.hpp")
#include "scanalign/common/interrupt.hpp"

namespace {
std::atomic<long> interrupt_countdown{-1};
bool interruptAfterCountdown() { return interrupt_countdown.fetch_sub(1) == 0; }
}  // namespace

TEST(FrameToModelFaults, AnInterruptAnywhereInAFrameLeavesTheModelUnchanged) {
  TwoFrames t;
  long interrupts = 0;
  interrupt_hook.store(&interruptAfterCountdown);
  for (long k = 0;; ++k) {
    const Snapshot before(t.f2m);
    interrupt_countdown = k;
    bool threw = false;
    try {
      t.f2m.integrate(t.view(), t.colors.data());
    } catch (const Interrupted&) {
      threw = true;
    }
    if (!threw) break;
    ++interrupts;
    before.expectUnchanged(t.f2m, "interrupted at check " + std::to_string(k));
    if (HasFailure()) break;
  }
  interrupt_hook.store(nullptr);
  EXPECT_GT(interrupts, 0) << "the registration checks for interrupts between iterations";
  EXPECT_EQ(t.f2m.framesMerged(), 2);  // the uninterrupted call merged
}
#endif

TEST(FrameToModel, AFarPointIsDroppedAndCountedNotTheFrameRefused) {
  // One stray reading 1e6 m (and one at 1e30 m) away used to make the frame's voxel grid
  // refuse the whole frame (more than 2^21 voxels along an axis).
  const PinholeIntrinsics K = smallCamera();
  const DepthCloud c = cloudOf(rayCast(loopPose(0, 24), K), K);
  std::vector<float> with_far = c.points;
  with_far.insert(with_far.end(), {1e6f, 0.0f, 0.4f, 0.0f, -1e30f, 0.4f});
  FrameToModel a, b;
  const FrameResult ra = a.integrate(CloudView<float>(with_far.data(), with_far.size() / 3));
  const FrameResult rb = b.integrate(CloudView<float>(c.points.data(), c.size()));
  ASSERT_EQ(ra.status, FrameStatus::Initialized);
  EXPECT_EQ(ra.far_points, 2u);
  EXPECT_EQ(rb.far_points, 0u);
  EXPECT_TRUE(sameBytes(a.model(), b.model()));  // as if the far points had not been there
  // Model range: a frame merged 1.5 km from the first camera (beyond 2^20 model voxels of
  // 1 mm) is dropped point by point and counted; the model is unchanged.
  const PreparedFrame p = a.prepare(CloudView<float>(c.points.data(), c.size()));
  const Model before = a.model();
  std::size_t far = 0;
  EXPECT_EQ(a.merge(p, rigid(0, 0, 0, 1500.0, 0, 0), &far), before.size());
  EXPECT_EQ(far, p.size());
  EXPECT_TRUE(sameBytes(a.model(), before));
}

// --- Lens distortion: the one intrinsics type -------------------------------------------------

namespace {

PinholeIntrinsics distortedCamera() {
  PinholeIntrinsics K{320, 240, 260.5, 259.25, 161.3, 118.7};
  K.distortion = LensDistortion{0.1, -0.05, 0.001, -0.002, 0.01};
  return K;
}

/// The Brown-Conrady model written out (OpenCV's projectPoints; the header's formula), as the
/// oracle: the pixel a normalised ray (x, y) projects to.
Eigen::Vector2d distort(const PinholeIntrinsics& K, double x, double y) {
  const LensDistortion& d = K.distortion;
  const double r2 = x * x + y * y;
  const double radial = 1.0 + d.k1 * r2 + d.k2 * r2 * r2 + d.k3 * r2 * r2 * r2;
  const double xd = x * radial + 2.0 * d.p1 * x * y + d.p2 * (r2 + 2.0 * x * x);
  const double yd = y * radial + d.p1 * (r2 + 2.0 * y * y) + 2.0 * d.p2 * x * y;
  return {K.fx * xd + K.cx, K.fy * yd + K.cy};
}

}  // namespace

TEST(LensDistortion, RaysReprojectOntoTheirPixels) {
  const PinholeIntrinsics K = distortedCamera();
  const std::vector<double> rays = undistortedRays(K);
  ASSERT_EQ(rays.size(), 2u * 320 * 240);
  double worst = 0.0;
  for (int v = 0; v < K.height; ++v)
    for (int u = 0; u < K.width; ++u) {
      const std::size_t i = 2 * (static_cast<std::size_t>(v) * K.width + u);
      ASSERT_TRUE(std::isfinite(rays[i]) && std::isfinite(rays[i + 1])) << u << " " << v;
      const Eigen::Vector2d back = distort(K, rays[i], rays[i + 1]);
      worst = std::max(worst, (back - Eigen::Vector2d(u, v)).norm());
    }
  EXPECT_LT(worst, 1e-8);
  // Zero distortion: the pinhole rays, exactly as depthToCloud's pinhole formula computes them.
  PinholeIntrinsics P = K;
  P.distortion = {};
  const std::vector<double> pinhole = undistortedRays(P);
  for (int v = 0; v < P.height; v += 7)
    for (int u = 0; u < P.width; u += 5) {
      const std::size_t i = 2 * (static_cast<std::size_t>(v) * P.width + u);
      EXPECT_EQ(pinhole[i], (u - P.cx) * (1.0 / P.fx));
      EXPECT_EQ(pinhole[i + 1], (v - P.cy) * (1.0 / P.fy));
    }
}

TEST(LensDistortion, DepthToCloudBackProjectsAlongTheUndistortedRays) {
  const PinholeIntrinsics K = distortedCamera();
  std::mt19937 rng(4);
  std::uniform_real_distribution<float> z(0.3f, 1.5f);
  std::vector<float> depth(static_cast<std::size_t>(K.width) * K.height);
  for (float& d : depth) d = z(rng);
  depth[5 * 320 + 7] = 0.0f;  // invalid
  const DepthCloud c = depthToCloud(depth.data(), K, DepthToCloudSettings{});
  ASSERT_EQ(c.size(), depth.size() - 1);
  const std::vector<double> rays = undistortedRays(K);
  for (std::size_t k = 0; k < c.size(); ++k) {
    const auto pixel = static_cast<std::size_t>(c.pixels[k]);
    const double d = depth[pixel];
    // The point lies on its pixel's ray: it projects back onto the pixel.
    ASSERT_EQ(c.points[3 * k], static_cast<float>(d * rays[2 * pixel]));
    ASSERT_EQ(c.points[3 * k + 1], static_cast<float>(d * rays[2 * pixel + 1]));
    ASSERT_EQ(c.points[3 * k + 2], static_cast<float>(d));
  }
  const Eigen::Vector2d back = distort(K, c.points[300] / c.points[302], c.points[301] / c.points[302]);
  const auto pixel = c.pixels[100];
  EXPECT_LT((back - Eigen::Vector2d(pixel % 320, pixel / 320)).norm(), 1e-3);  // float32 points
  // Zero distortion is the pinhole formula, bit for bit.
  PinholeIntrinsics P = K;
  P.distortion = {};
  const DepthCloud p = depthToCloud(depth.data(), P, DepthToCloudSettings{});
  for (std::size_t k = 0; k < p.size(); k += 97) {
    const int u = p.pixels[k] % 320, v = p.pixels[k] / 320;
    const double d = depth[static_cast<std::size_t>(p.pixels[k])];
    EXPECT_EQ(p.points[3 * k], static_cast<float>(d * (u - P.cx) * (1.0 / P.fx)));
    EXPECT_EQ(p.points[3 * k + 1], static_cast<float>(d * ((v - P.cy) * (1.0 / P.fy))));
  }
}

TEST(LensDistortion, RayTablesAreCachedPerIntrinsicsAndSharedAcrossThreads) {
  const PinholeIntrinsics K = distortedCamera();
  const auto a = cachedUndistortedRays(K);
  EXPECT_EQ(cachedUndistortedRays(K), a);  // the same table, not a new one
  EXPECT_EQ(*a, undistortedRays(K));
  PinholeIntrinsics other = K;
  other.distortion.k1 = 0.2;
  EXPECT_NE(cachedUndistortedRays(other), a);
  // Beyond kRayTableCacheSize other cameras, the first is dropped (and recomputed equal).
  for (std::size_t i = 0; i < kRayTableCacheSize; ++i) {
    PinholeIntrinsics k = K;
    k.distortion.k2 = 0.001 * static_cast<double>(i + 1);
    cachedUndistortedRays(k);
  }
  const auto again = cachedUndistortedRays(K);
  EXPECT_NE(again, a);
  EXPECT_EQ(*again, *a);
  // Threads back-projecting with several cameras at once get the serial results.
  std::vector<PinholeIntrinsics> cameras;
  for (int i = 0; i < 12; ++i) {
    PinholeIntrinsics k = K;
    k.width = 64;
    k.height = 48;
    k.cx = 31.5;
    k.cy = 23.5;
    k.distortion.k1 = 0.01 * i;
    cameras.push_back(k);
  }
  std::vector<float> depth(64 * 48, 0.8f);
  std::vector<std::vector<float>> serial;
  for (const auto& k : cameras) serial.push_back(depthToCloud(depth.data(), k, DepthToCloudSettings{}).points);
  std::atomic<int> mismatches{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      for (int round = 0; round < 20; ++round) {
        const std::size_t i = static_cast<std::size_t>((round * 5 + t * 3) % 12);
        if (depthToCloud(depth.data(), cameras[i], DepthToCloudSettings{}).points != serial[i]) ++mismatches;
      }
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(mismatches.load(), 0);
}

TEST(LensDistortion, IntrinsicsValidateScaleAndCompare) {
  PinholeIntrinsics K = distortedCamera();
  EXPECT_NO_THROW(K.validate());
  EXPECT_TRUE(K.hasDistortion());
  EXPECT_FALSE(PinholeIntrinsics({64, 48, 50, 50, 31.5, 23.5}).hasDistortion());
  K.distortion.p2 = std::nan("");
  EXPECT_THROW(K.validate(), std::invalid_argument);
  K.distortion.p2 = std::numeric_limits<double>::infinity();
  EXPECT_THROW(depthToCloud(std::vector<float>(320 * 240, 1.0f).data(), K, DepthToCloudSettings{}),
               std::invalid_argument);
  // scaled: size rounded half to even, focal lengths scaled, pixel centres mapped as
  // (c + 0.5) s - 0.5, the distortion kept.
  const PinholeIntrinsics D = distortedCamera();
  const PinholeIntrinsics H = D.scaled(0.5);
  EXPECT_EQ(H.width, 160);
  EXPECT_EQ(H.height, 120);
  EXPECT_EQ(H.fx, 130.25);
  EXPECT_EQ(H.fy, 129.625);
  EXPECT_DOUBLE_EQ(H.cx, (161.3 + 0.5) * 0.5 - 0.5);
  EXPECT_DOUBLE_EQ(H.cy, (118.7 + 0.5) * 0.5 - 0.5);
  EXPECT_TRUE(H.distortion == D.distortion);
  EXPECT_EQ(PinholeIntrinsics({5, 3, 10, 10, 2, 1}).scaled(0.5).width, 2);  // 2.5 -> 2
  EXPECT_EQ(PinholeIntrinsics({7, 3, 10, 10, 2, 1}).scaled(0.5).width, 4);  // 3.5 -> 4
  EXPECT_THROW(D.scaled(0.0), std::invalid_argument);
  EXPECT_THROW(D.scaled(std::nan("")), std::invalid_argument);
  EXPECT_THROW(D.scaled(1e-9), std::invalid_argument);  // a 0 x 0 image
  // The camera matrix and equality over every field.
  Eigen::Matrix3d expected;
  expected << 260.5, 0, 161.3, 0, 259.25, 118.7, 0, 0, 1;
  EXPECT_EQ(D.K(), expected);
  EXPECT_TRUE(D == distortedCamera());
  PinholeIntrinsics E = D;
  E.distortion.k3 = 0.0;
  EXPECT_TRUE(D != E);
}

TEST(LensDistortion, TheRendererRefusesDistortedIntrinsics) {
  const std::vector<double> v{-1, -1, 2, 1, -1, 2, 0, 1, 2};
  const std::vector<std::int32_t> f{0, 1, 2};
  PinholeIntrinsics K{64, 48, 50, 50, 31.5, 23.5};
  EXPECT_NO_THROW(renderDepth(CloudView<double>(v.data(), 3), f, K, Eigen::Matrix4d::Identity()));
  K.distortion.k1 = 0.1;
  try {
    renderDepth(CloudView<double>(v.data(), 3), f, K, Eigen::Matrix4d::Identity());
    FAIL() << "a distorted camera was rendered";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("pinhole"), std::string::npos) << e.what();
  }
}

// --- Settings of the reconstruction job ------------------------------------------------------

TEST(BilateralFilterSettings, DefaultsValidationAndTheSettingsOverload) {
  const BilateralFilterSettings s;
  EXPECT_EQ(s.radius, 2);
  EXPECT_EQ(s.sigma_space, 1.5);
  EXPECT_EQ(s.sigma_depth, 0.003);
  EXPECT_NO_THROW(s.validate());
  const auto refused = [](BilateralFilterSettings b, const char* field) {
    try {
      b.validate();
      ADD_FAILURE() << field << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  for (int r : {-1, 33}) refused(BilateralFilterSettings{r, 1.5, 0.003}, "radius");
  for (double x : {1e-4, std::nan(""), std::numeric_limits<double>::infinity()})
    refused(BilateralFilterSettings{2, x, 0.003}, "sigma_space");
  for (double x : {1e-12, std::nan(""), std::numeric_limits<double>::infinity()})
    refused(BilateralFilterSettings{2, 1.5, x}, "sigma_depth");
  EXPECT_NO_THROW((BilateralFilterSettings{0, 1e-3, 1e-9}.validate()));
  EXPECT_NO_THROW((BilateralFilterSettings{32, 1.5, 0.003}.validate()));
  // The settings overload filters exactly as the explicit one.
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> z(0.4f, 0.6f);
  std::vector<float> depth(40 * 30), a(depth.size()), b(depth.size());
  for (float& d : depth) d = z(rng);
  bilateralFilterDepth(depth.data(), 40, 30, a.data(), BilateralFilterSettings{3, 2.0, 0.01});
  bilateralFilterDepth(depth.data(), 40, 30, b.data(), 3, 2.0, 0.01);
  EXPECT_EQ(a, b);
  EXPECT_THROW(bilateralFilterDepth(depth.data(), 40, 30, a.data(), BilateralFilterSettings{40, 2.0, 0.01}),
               std::invalid_argument);
}

TEST(ReconstructionSettings, DefaultsAndValidation) {
  const ReconstructionSettings s;
  EXPECT_EQ(s.min_depth, 0.1);
  EXPECT_EQ(s.max_depth, 2.0);
  EXPECT_EQ(s.pixel_stride, 1);
  EXPECT_TRUE(s.filter_depth);  // consumer sensors' noise (the paper had no filter)
  EXPECT_EQ(s.depth_filter.radius, BilateralFilterSettings{}.radius);
  EXPECT_EQ(s.frame_to_model.motion_model, MotionModel::ConstantVelocity);  // the reconstruct command's default
  EXPECT_EQ(s.frame_to_model.normal_radius, 0.01);
  ASSERT_TRUE(s.frame_to_model.icp.box.has_value());  // the paper's box rejector, a part's workspace
  EXPECT_EQ(s.frame_to_model.icp.box->max.x(), 0.1);
  EXPECT_EQ(s.min_merged_fraction, 0.5);
  EXPECT_EQ(s.model_frame, ModelFrame::Auto);
  EXPECT_EQ(s.registration, RegistrationMethod::Scanalign);
  EXPECT_NO_THROW(validate(s));
  EXPECT_STREQ(toString(ModelFrame::Base), "base");
  EXPECT_STREQ(toString(RegistrationMethod::PclPointToPlaneLls), "pcl_point_to_plane_lls");
  EXPECT_STREQ(toString(MotionModel::Reference), "reference");
  const auto refused = [](const ReconstructionSettings& r, const char* field) {
    try {
      validate(r);
      ADD_FAILURE() << field << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  ReconstructionSettings r = s;
  r.min_depth = -0.1;
  refused(r, "min_depth");
  r = s;
  r.max_depth = 0.1;
  refused(r, "max_depth");
  r.max_depth = std::nan("");
  refused(r, "max_depth");
  r = s;
  r.pixel_stride = 0;
  refused(r, "pixel_stride");
  r = s;
  r.depth_filter.sigma_depth = 0.0;  // checked even while the filter is off
  refused(r, "depth_filter");
  r = s;
  r.frame_to_model.normal_radius = -1.0;
  refused(r, "frame_to_model");
  r = s;
  r.model_frame = static_cast<ModelFrame>(7);
  refused(r, "model_frame");
  r = s;
  r.registration = static_cast<RegistrationMethod>(-1);
  refused(r, "registration");
  for (const double f : {-0.1, 1.5, std::nan("")}) {
    r = s;
    r.min_merged_fraction = f;
    refused(r, "min_merged_fraction");
  }
}

TEST(FrameToModel, ReferenceWithoutAGuessActsAsConstantVelocity) {
  const PinholeIntrinsics K = smallCamera();
  FrameToModelSettings s;
  s.motion_model = MotionModel::Reference;
  EXPECT_NO_THROW(validate(s));
  FrameToModel f2m(s);
  const Eigen::Matrix4d T0 = rigid(0.1, -0.2, 0.3, 0.5, 0.1, -0.2);
  f2m.reset(T0);
  const DepthCloud c = cloudOf(rayCast(loopPose(0, 24), K), K);
  const PreparedFrame p = f2m.prepare(CloudView<float>(c.points.data(), c.size()));
  f2m.merge(p, T0);
  EXPECT_EQ(f2m.predictedPose(), T0);
  const Eigen::Matrix4d M = rigid(0.004, -0.002, 0.003, 0.02, 0.01, -0.015);
  f2m.merge(p, T0 * M);
  EXPECT_LT((f2m.predictedPose() - T0 * M * M).cwiseAbs().maxCoeff(), 1e-12);
}

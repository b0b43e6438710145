// The ICP engine against known rigid motions (PCL-free).
#include <gtest/gtest.h>

#include <atomic>
#include <random>

#include "scanalign/common/interrupt.hpp"
#include "scanalign/registration/icp.hpp"
#include "test_support.hpp"

using scanalign::CloudView;
using scanalign::Icp;
using scanalign::IcpSettings;
using scanalign::IcpStatus;
using namespace scanalign::test;

namespace {
CloudView<float> view(const std::vector<float>& v) { return CloudView<float>(v.data(), v.size() / 3); }
}  // namespace

TEST(IcpEngine, RecoversKnownMotionNoiseFree) {
  const Surface s = wavySurfaceWithSphere();
  for (auto est : {scanalign::IcpEstimator::PointToPlane, scanalign::IcpEstimator::PointToPoint}) {
    const Eigen::Matrix4d T_true = rigid(0.04, -0.03, 0.05, 0.008, -0.006, 0.01);
    const auto src = transformed(s.points, T_true.inverse());
    IcpSettings settings;
    settings.estimator = est;
    settings.max_iterations = est == scanalign::IcpEstimator::PointToPlane ? 50 : 300;
    Icp<float> icp(settings);
    icp.setTarget(view(s.points), view(s.normals));
    const auto r = icp.align(view(src));
    EXPECT_TRUE(r.converged) << scanalign::toString(r.status);
    EXPECT_LT(rotationError(r.T_target_source, T_true), 1e-5) << scanalign::toString(est);
    EXPECT_LT(translationError(r.T_target_source, T_true), 1e-5) << scanalign::toString(est);
    EXPECT_DOUBLE_EQ(r.fitness, 1.0);
    EXPECT_LT(r.inlier_rmse, 1e-5);
    EXPECT_TRUE(r.exact_search);
    EXPECT_FALSE(r.degenerate);
  }
}

TEST(IcpEngine, DoublePrecisionCloudsAndInitialGuess) {
  const Surface s = wavySurfaceWithSphere();
  std::vector<double> tgt(s.points.begin(), s.points.end()), nrm(s.normals.begin(), s.normals.end());
  const Eigen::Matrix4d T_true = rigid(0.3, -0.2, 0.5, 0.1, -0.05, 0.08);
  const auto srcf = transformed(s.points, T_true.inverse());
  std::vector<double> src(srcf.begin(), srcf.end());
  Icp<double> icp;
  icp.setTarget(CloudView<double>(tgt.data(), tgt.size() / 3), CloudView<double>(nrm.data(), nrm.size() / 3));
  // A large motion, with an initial guess close to it (as frame-to-model uses the previous pose).
  const Eigen::Matrix4d guess = T_true * rigid(0.01, 0.01, -0.01, 0.003, 0.002, -0.002);
  const auto r = icp.align(CloudView<double>(src.data(), src.size() / 3), guess);
  EXPECT_TRUE(r.converged);
  EXPECT_LT(rotationError(r.T_target_source, T_true), 1e-5);
  EXPECT_LT(translationError(r.T_target_source, T_true), 1e-5);
}

TEST(IcpEngine, ResultDoesNotDependOnThreadsOrWarmStart) {
  const Surface s = wavySurfaceWithSphere();
  const auto src = transformed(s.points, rigid(0.02, 0.01, -0.02, 0.004, 0.002, 0.003));
  Eigen::Matrix4d reference;
  for (int threads : {1, 2, 3}) {
    for (bool warm : {true, false}) {
      IcpSettings settings;
      settings.num_threads = threads;
      settings.warm_start = warm;
      Icp<float> icp(settings);
      icp.setTarget(view(s.points), view(s.normals));
      const auto r = icp.align(view(src));
      if (threads == 1 && warm) reference = r.T_target_source;
      // The summing tree has a fixed shape: bit-identical across thread counts.
      EXPECT_EQ((r.T_target_source - reference).cwiseAbs().maxCoeff(), 0.0) << threads << " " << warm;
    }
  }
}

TEST(IcpEngine, PartialOverlapWithBoxAndDistanceRejection) {
  const Surface s = wavySurfaceWithSphere(120, 0.2, 4);
  const Eigen::Matrix4d T_true = rigid(0.02, -0.02, 0.03, 0.006, 0.004, -0.005);
  // Source: only half of the model (x > -0.02 in the source frame) plus clutter far behind.
  auto all = transformed(s.points, T_true.inverse());
  std::vector<float> src;
  for (std::size_t i = 0; i < all.size() / 3; ++i)
    if (all[3 * i] > -0.02f) src.insert(src.end(), {all[3 * i], all[3 * i + 1], all[3 * i + 2]});
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-0.3f, 0.3f);
  for (int i = 0; i < 5000; ++i) src.insert(src.end(), {u(rng), u(rng), 1.0f + 0.05f * u(rng)});
  IcpSettings settings;
  settings.max_correspondence_distance = 0.5;  // so large that only the box keeps the clutter out
  settings.box = scanalign::Box(-0.3, 0.3, -0.3, 0.3, 1e-4, 0.8);
  Icp<float> icp(settings);
  icp.setTarget(view(s.points), view(s.normals));
  auto r = icp.align(view(src));
  EXPECT_TRUE(r.converged);
  EXPECT_LT(rotationError(r.T_target_source, T_true), 1e-5);
  EXPECT_LT(translationError(r.T_target_source, T_true), 1e-5);
  EXPECT_EQ(r.source_points_used, src.size() / 3 - 5000);  // the clutter is outside the box
  // Without the box the clutter wins; distance rejection alone (5 cm) also recovers.
  settings.box.reset();
  icp.settings() = settings;
  r = icp.align(view(src));
  EXPECT_GT(translationError(r.T_target_source, T_true), 1e-3);
  icp.settings().max_correspondence_distance = 0.05;
  r = icp.align(view(src));
  EXPECT_LT(translationError(r.T_target_source, T_true), 1e-5);
  EXPECT_LT(r.fitness, 0.9);  // the clutter has no partner within 5 cm
}

TEST(IcpEngine, StatusesForFailures) {
  const Surface s = wavySurfaceWithSphere(40);
  Icp<float> icp;
  icp.setTarget(view(s.points), view(s.normals));
  // Source far away: no correspondence within 5 cm.
  const auto far = transformed(s.points, rigid(0, 0, 0, 5.0, 0, 0));
  auto r = icp.align(view(far));
  EXPECT_EQ(r.status, IcpStatus::NotEnoughCorrespondences);
  EXPECT_FALSE(r.converged);
  EXPECT_TRUE(r.T_target_source.isIdentity());
  // Five points are fewer than the 6 unknowns.
  std::vector<float> five(s.points.begin(), s.points.begin() + 15);
  r = icp.align(view(five));
  EXPECT_EQ(r.status, IcpStatus::NotEnoughCorrespondences);
  // One iteration cap on a real motion: stopped, not converged.
  icp.settings().max_iterations = 1;
  r = icp.align(view(transformed(s.points, rigid(0.05, 0, 0, 0.01, 0, 0))));
  EXPECT_EQ(r.status, IcpStatus::MaxIterations);
  EXPECT_FALSE(r.converged);
}

TEST(IcpEngine, PlanarTargetIsFlaggedDegenerate) {
  std::vector<float> plane, normals;
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> u(-0.1f, 0.1f);
  for (int i = 0; i < 5000; ++i) {
    plane.insert(plane.end(), {u(rng), u(rng), 0.5f});
    normals.insert(normals.end(), {0.f, 0.f, -1.f});
  }
  Icp<float> icp;
  icp.setTarget(view(plane), view(normals));
  const auto r = icp.align(view(transformed(plane, rigid(0, 0, 0, 0.002, 0.001, 0.004))));
  EXPECT_TRUE(r.degenerate);
  EXPECT_EQ(r.min_rank, 3);
  EXPECT_NEAR(r.T_target_source(2, 3), -0.004, 1e-6);  // the constrained motion is recovered
  EXPECT_TRUE(r.T_target_source.allFinite());
}

TEST(IcpEngine, BadInputThrows) {
  const Surface s = wavySurfaceWithSphere(20);
  Icp<float> icp;
  EXPECT_THROW(icp.align(view(s.points)), std::invalid_argument);  // no target
  EXPECT_THROW(icp.setTarget(CloudView<float>()), std::invalid_argument);
  std::vector<float> short_normals(s.normals.begin(), s.normals.end() - 3);
  EXPECT_THROW(icp.setTarget(view(s.points), view(short_normals)), std::invalid_argument);
  std::vector<float> nan(30, std::numeric_limits<float>::quiet_NaN());
  EXPECT_THROW(icp.setTarget(view(nan)), std::invalid_argument);
  icp.setTarget(view(s.points));  // no normals
  EXPECT_THROW(icp.align(view(s.points)), std::invalid_argument);  // point-to-plane needs them
  icp.setTarget(view(s.points), view(s.normals));
  EXPECT_THROW(icp.align(CloudView<float>()), std::invalid_argument);
  Eigen::Matrix4d scaled = Eigen::Matrix4d::Identity() * 2.0;
  scaled(3, 3) = 1.0;
  EXPECT_THROW(icp.align(view(s.points), scaled), std::invalid_argument);
  icp.settings().max_correspondence_distance = -1;
  EXPECT_THROW(icp.align(view(s.points)), std::invalid_argument);
}

TEST(IcpEngine, CoarseToFineReachesTheAnswerWithFewerFullIterations) {
  // 18400 points (a 120 x 120 sheet and a sphere): a stride of 4 leaves 4600 for the
  // coarse phase. The full-resolution phase then starts near its fixed point.
  const Surface s = wavySurfaceWithSphere();
  const Eigen::Matrix4d T_true = rigid(0.04, -0.03, 0.05, 0.008, -0.006, 0.01);
  const auto src = transformed(s.points, T_true.inverse());
  IcpSettings settings;
  Icp<float> seed(settings);
  seed.setTarget(view(s.points), view(s.normals));
  const auto full = seed.align(view(src));
  ASSERT_TRUE(full.converged);
  EXPECT_EQ(full.coarse_iterations, 0);
  settings.coarse_stride = 4;
  Icp<float> icp(settings);
  icp.setTarget(view(s.points), view(s.normals));
  const auto r = icp.align(view(src));
  EXPECT_TRUE(r.converged) << scanalign::toString(r.status);
  EXPECT_GT(r.coarse_iterations, 0);
  EXPECT_LT(r.iterations, full.iterations);
  EXPECT_LT(rotationError(r.T_target_source, T_true), 1e-5);
  EXPECT_LT(translationError(r.T_target_source, T_true), 1e-5);
  // Quality figures are those of all points at the final pose.
  EXPECT_EQ(r.source_points_used, src.size() / 3);
  EXPECT_DOUBLE_EQ(r.fitness, 1.0);
  EXPECT_FALSE(r.degenerate);
  // A stride leaving fewer than 500 points skips the coarse phase: the run of the eye-in-hand paper
  // (Comput. Electron. Agric. 180 (2021) 105929) exactly.
  icp.settings().coarse_stride = 100;
  const auto skipped = icp.align(view(src));
  EXPECT_EQ(skipped.coarse_iterations, 0);
  EXPECT_EQ(skipped.iterations, full.iterations);
  EXPECT_EQ((skipped.T_target_source - full.T_target_source).cwiseAbs().maxCoeff(), 0.0);
  icp.settings().coarse_stride = 0;
  EXPECT_THROW(icp.align(view(src)), std::invalid_argument);
}

namespace {
/// An interrupt hook that asks to stop on its `stop_at`-th call, counting its calls.
std::atomic<int> hook_calls{0};
int hook_stop_at = 0;
bool stopOnNthCall() { return ++hook_calls >= hook_stop_at; }
/// Installs stopOnNthCall for one scope; the hook is process-wide.
struct ScopedHook {
  explicit ScopedHook(int stop_at) {
    hook_calls = 0;
    hook_stop_at = stop_at;
    scanalign::interrupt_hook.store(&stopOnNthCall);
  }
  ~ScopedHook() { scanalign::interrupt_hook.store(nullptr); }
};
}  // namespace

TEST(IcpEngine, InterruptHookStopsAlignBetweenIterationsAndLeavesTheEngineUsable) {
  const Surface s = wavySurfaceWithSphere(40);
  const Eigen::Matrix4d T_true = rigid(0.03, -0.02, 0.01, 0.004, 0.002, -0.003);
  const auto src = transformed(s.points, T_true.inverse());
  IcpSettings settings;
  settings.max_iterations = 1000000;  // zero epsilons: only the cap (or the hook) stops it
  settings.transformation_epsilon = settings.fitness_epsilon = settings.absolute_mse_epsilon = 0.0;
  Icp<float> icp(settings);
  icp.setTarget(view(s.points), view(s.normals));
  {
    ScopedHook hook(5);
    EXPECT_THROW(icp.align(view(src)), scanalign::Interrupted);
    EXPECT_EQ(hook_calls.load(), 5);  // once per iteration: stopped before the 5th
  }
  // Nothing was corrupted: the same engine gives a fresh engine's answer.
  icp.settings().max_iterations = 60;
  Icp<float> fresh(icp.settings());
  fresh.setTarget(view(s.points), view(s.normals));
  const auto a = icp.align(view(src)), b = fresh.align(view(src));
  EXPECT_EQ(a.iterations, 60);
  EXPECT_TRUE(a.T_target_source == b.T_target_source);
  EXPECT_LT(rotationError(a.T_target_source, T_true), 1e-5);
  EXPECT_LT(translationError(a.T_target_source, T_true), 1e-5);
}

TEST(IcpEngine, PointToPointOnCoincidentOrCollinearSourceIsDegenerateNotConverged) {
  const Surface s = wavySurfaceWithSphere(40);
  std::vector<float> same, line;
  for (int i = 0; i < 100; ++i) {
    same.insert(same.end(), s.points.begin(), s.points.begin() + 3);
    line.insert(line.end(), {-0.05f + 0.001f * i, 0.0f, s.points[2]});
  }
  for (auto est : {scanalign::IcpEstimator::PointToPoint, scanalign::IcpEstimator::DualQuaternion}) {
    for (const auto* cloud : {&same, &line}) {
      IcpSettings settings;
      settings.estimator = est;
      Icp<float> icp(settings);
      icp.setTarget(view(s.points));
      const auto r = icp.align(view(*cloud));
      EXPECT_EQ(r.status, IcpStatus::Degenerate) << scanalign::toString(est);
      EXPECT_STREQ(scanalign::toString(r.status), "degenerate");
      EXPECT_FALSE(r.converged);
      EXPECT_TRUE(r.degenerate);
      EXPECT_LE(r.min_rank, 2);
      EXPECT_TRUE(r.T_target_source.isIdentity());  // the undetermined step is not applied
    }
  }
}

// The CUDA ICP backend. On any machine: the device's search capacity against the CPU's full
// stack, the shared per-correspondence arithmetic against independent formulas, and the error a
// build without CUDA or a machine without a device gives. On a machine with a CUDA device: the
// CUDA engine against the CPU engine on the same inputs (poses to 1e-6, the same statuses),
// and its determinism.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "scanalign/common/build_info.hpp"
#include "scanalign/registration/correspondence_terms.hpp"
#include "scanalign/registration/cuda/icp_device.hpp"
#include "scanalign/registration/icp.hpp"
#include "scanalign/registration/kdtree.hpp"
#include "test_support.hpp"

using namespace scanalign;

namespace {

bool haveDevice() { return builtWithCuda() && !cuda::deviceNames().empty(); }

/// The capacity the CUDA kernel instantiates the search with (icp_device.cu).
constexpr int kDeviceStack = 32;

std::vector<float> randomCloud(std::size_t n, std::uint32_t seed, float extent) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-extent, extent);
  std::vector<float> p(3 * n);
  for (float& v : p) v = u(rng);
  return p;
}

}  // namespace

TEST(DeviceSearch, ThirtyTwoEntriesGiveTheFullStacksAnswer) {
  // 300k points: a tree 18 levels high. At every requested depth the device's instantiation
  // (capacity 32) must answer exactly as the CPU's (capacity 64), exactness flag included.
  const auto pts = randomCloud(300000, 3, 0.2f);
  LeftBalancedKdTree<float> tree(CloudView<float>(pts.data(), pts.size() / 3));
  ASSERT_EQ(tree.height(), 18);
  const auto queries = randomCloud(3000, 4, 0.25f);
  int inexact_at_4 = 0;
  for (int depth : {4, 20, 64})
    for (std::size_t k = 0; k < queries.size() / 3; ++k) {
      const float* q = &queries[3 * k];
      const auto cpu = tree.nearest(q, 0.01f, depth);
      const auto dev = leftBalancedNearest<float, kDeviceStack>(tree.nodes().data(), tree.bounds().data(),
                                                                 static_cast<std::uint32_t>(tree.size()), q, 0.01f,
                                                                 depth, NearestNeighbor<float>::kNone);
      ASSERT_EQ(cpu.node, dev.node);
      ASSERT_EQ(cpu.squared_distance, dev.squared_distance);
      ASSERT_EQ(cpu.exact, dev.exact);
      if (depth == 4 && !dev.exact) ++inexact_at_4;
    }
  EXPECT_GT(inexact_at_4, 0) << "a 4-entry stack should drop branches on an 18-level tree";
}

TEST(CorrespondenceTerms, PointToPlaneTermsEqualTheExplicitNormalEquations) {
  // Independent: build A and b row by row with Eigen (A_i = [(s x n)^T, n^T], b_i = n.(d - s)).
  std::mt19937 rng(7);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd A(50, 6);
  Eigen::VectorXd b(50), w(50);
  double ata[21] = {}, atb[6] = {}, btb = 0.0;
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d s(g(rng), g(rng), g(rng)), d(g(rng), g(rng), g(rng));
    const Eigen::Vector3d n = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    w(i) = 0.5 + 0.01 * i;
    A.row(i) << s.cross(n).transpose(), n.transpose();
    b(i) = n.dot(d - s);
    detail::addPointToPlaneTerms(ata, atb, btb, s.data(), d.data(), n.data(), w(i));
  }
  const Eigen::MatrixXd AtA = A.transpose() * w.asDiagonal() * A;
  const Eigen::VectorXd Atb = A.transpose() * w.asDiagonal() * b;
  int k = 0;
  for (int r = 0; r < 6; ++r) {
    for (int c = r; c < 6; ++c) EXPECT_NEAR(ata[k++], AtA(r, c), 1e-12 * (1 + std::abs(AtA(r, c))));
    EXPECT_NEAR(atb[r], Atb(r), 1e-12 * (1 + std::abs(Atb(r))));
  }
  EXPECT_NEAR(btb, b.dot(w.asDiagonal() * b), 1e-12 * (1 + btb));
}

TEST(CorrespondenceTerms, RobustWeightsTakeTheirAnalyticValues) {
  const double s[3] = {0, 0, 0}, n[3] = {0, 0, 1};
  const double d_k[3] = {0.3, -0.2, 0.01}, d_2k[3] = {0, 0, -0.02};  // residuals k and -2k for k = 0.01
  EXPECT_EQ(detail::robustWeight(RobustKernel::None, 0.01, s, d_2k, n), 1.0);
  EXPECT_DOUBLE_EQ(detail::robustWeight(RobustKernel::Huber, 0.01, s, d_k, n), 1.0);
  EXPECT_DOUBLE_EQ(detail::robustWeight(RobustKernel::Huber, 0.01, s, d_2k, n), 0.5);
  EXPECT_DOUBLE_EQ(detail::robustWeight(RobustKernel::Cauchy, 0.01, s, d_k, n), 0.5);
  EXPECT_DOUBLE_EQ(detail::robustWeight(RobustKernel::Cauchy, 0.01, s, d_2k, n), 0.2);
}

TEST(CorrespondenceTerms, BoxIsClosedAndNonFinitePointsAreNotUsed) {
  IcpPassRules<float> rules;
  rules.has_box = true;
  for (int k = 0; k < 3; ++k) {
    rules.box_lo[k] = -0.1;
    rules.box_hi[k] = 0.1;
  }
  const float edge[3] = {0.1f, -0.1f, 0.0f}, out[3] = {0.0f, 0.0f, 0.1001f}, nan[3] = {0.0f, NAN, 0.0f};
  // float 0.1f is just above the double 0.1: outside, as the CPU engine's Box::contains says.
  EXPECT_EQ(detail::sourcePointUsed(rules, edge), Box(-0.1, 0.1, -0.1, 0.1, -0.1, 0.1).contains(edge));
  const float inside[3] = {0.0999f, -0.0999f, 0.0f};
  EXPECT_TRUE(detail::sourcePointUsed(rules, inside));
  EXPECT_FALSE(detail::sourcePointUsed(rules, out));
  EXPECT_FALSE(detail::sourcePointUsed(rules, nan));
  rules.has_box = false;
  EXPECT_TRUE(detail::sourcePointUsed(rules, out));
  EXPECT_FALSE(detail::sourcePointUsed(rules, nan));
}

TEST(CudaBackend, WithoutABuildOrADeviceTheErrorSaysWhy) {
  if (haveDevice()) GTEST_SKIP() << "a CUDA device is present: CudaBackend.MatchesTheCpuEngine runs instead";
  const auto s = test::wavySurfaceWithSphere(40);
  IcpSettings settings;
  settings.backend = IcpBackend::Cuda;
  Icp<float> icp(settings);
  try {
    icp.setTarget(CloudView<float>(s.points.data(), s.size()), CloudView<float>(s.normals.data(), s.size()));
    FAIL() << "the CUDA backend ran without a build or a device";
  } catch (const NotBuiltError& e) {
    EXPECT_FALSE(builtWithCuda());
    EXPECT_NE(std::string(e.what()).find("SCANALIGN_WITH_CUDA=ON"), std::string::npos) << e.what();
  } catch (const std::runtime_error& e) {
    EXPECT_TRUE(builtWithCuda());
    EXPECT_NE(std::string(e.what()).find("no usable CUDA device"), std::string::npos) << e.what();
  }
  // The engine stays usable on the CPU.
  icp.settings().backend = IcpBackend::Cpu;
  icp.setTarget(CloudView<float>(s.points.data(), s.size()), CloudView<float>(s.normals.data(), s.size()));
  const auto r = icp.align(CloudView<float>(s.points.data(), s.size()));
  EXPECT_TRUE(r.converged);
  EXPECT_LT(test::translationError(r.T_target_source, Eigen::Matrix4d::Identity()), 1e-6);
}

namespace {

template <typename Scalar>
IcpResult alignOn(IcpBackend backend, IcpSettings settings, const std::vector<Scalar>& target,
                  const std::vector<Scalar>& normals, const std::vector<Scalar>& source, const Eigen::Matrix4d& init) {
  settings.backend = backend;
  Icp<Scalar> icp(settings);
  icp.setTarget(CloudView<Scalar>(target.data(), target.size() / 3),
                CloudView<Scalar>(normals.data(), normals.size() / 3));
  return icp.align(CloudView<Scalar>(source.data(), source.size() / 3), init);
}

template <typename Scalar>
std::vector<Scalar> as(const std::vector<float>& v) {
  return std::vector<Scalar>(v.begin(), v.end());
}

}  // namespace

TEST(CudaBackend, MatchesTheCpuEngine) {
  if (!haveDevice()) GTEST_SKIP() << "no CUDA device (or a build without CUDA)";
  const auto s = test::wavySurfaceWithSphere(150);
  const Eigen::Matrix4d truth = test::rigid(0.03, -0.02, 0.04, 0.006, -0.004, 0.005);
  auto source = test::transformed(s.points, truth.inverse());
  std::mt19937 rng(5);
  std::normal_distribution<float> noise(0.0f, 0.0005f);
  for (float& v : source) v += noise(rng);
  source[30] = NAN;  // a non-finite point is skipped by both
  struct Case {
    const char* name;
    IcpSettings settings;
  };
  std::vector<Case> cases;
  IcpSettings base;
  base.max_correspondence_distance = 0.03;
  cases.push_back({"point_to_plane", base});
  IcpSettings box = base;
  box.box = Box(-0.08, 0.08, -0.08, 0.08, 0.0001, 10.0);
  cases.push_back({"box", box});
  IcpSettings huber = base;
  huber.robust_kernel = RobustKernel::Huber;
  huber.robust_scale = 0.002;
  cases.push_back({"huber", huber});
  IcpSettings p2p = base;
  p2p.estimator = IcpEstimator::PointToPoint;
  cases.push_back({"point_to_point", p2p});
  IcpSettings dq = base;
  dq.estimator = IcpEstimator::DualQuaternion;
  cases.push_back({"dual_quaternion", dq});
  IcpSettings coarse = base;
  coarse.coarse_stride = 8;
  cases.push_back({"coarse", coarse});
  IcpSettings shallow = base;
  shallow.search = IcpSearch::LeftBalancedKdTree;
  shallow.search_stack_depth = 3;  // approximate search: both must approximate alike
  cases.push_back({"stack_3", shallow});
  for (const auto& c : cases) {
    SCOPED_TRACE(c.name);
    const auto cpu = alignOn<float>(IcpBackend::Cpu, c.settings, s.points, s.normals, source, Eigen::Matrix4d::Identity());
    const auto gpu = alignOn<float>(IcpBackend::Cuda, c.settings, s.points, s.normals, source, Eigen::Matrix4d::Identity());
    EXPECT_EQ(toString(cpu.status), std::string(toString(gpu.status)));
    EXPECT_EQ(cpu.iterations, gpu.iterations);
    EXPECT_LT((cpu.T_target_source - gpu.T_target_source).cwiseAbs().maxCoeff(), 1e-6);
    EXPECT_EQ(cpu.correspondence_count, gpu.correspondence_count);
    EXPECT_EQ(cpu.source_points_used, gpu.source_points_used);
    EXPECT_EQ(cpu.exact_search, gpu.exact_search);
    EXPECT_NEAR(cpu.inlier_rmse, gpu.inlier_rmse, 1e-9);
    if (std::string(c.name) != "stack_3") EXPECT_LT(test::translationError(gpu.T_target_source, truth), 1e-3);
  }
  // Double clouds run on the device in double.
  const auto cpu = alignOn<double>(IcpBackend::Cpu, base, as<double>(s.points), as<double>(s.normals),
                                   as<double>(source), Eigen::Matrix4d::Identity());
  const auto gpu = alignOn<double>(IcpBackend::Cuda, base, as<double>(s.points), as<double>(s.normals),
                                   as<double>(source), Eigen::Matrix4d::Identity());
  EXPECT_LT((cpu.T_target_source - gpu.T_target_source).cwiseAbs().maxCoeff(), 1e-6);
}

TEST(CudaBackend, IsDeterministicAndKeepsTheModelAcrossAlignments) {
  if (!haveDevice()) GTEST_SKIP() << "no CUDA device (or a build without CUDA)";
  const auto s = test::wavySurfaceWithSphere(300);
  IcpSettings settings;
  settings.backend = IcpBackend::Cuda;
  Icp<float> icp(settings);
  icp.setTarget(CloudView<float>(s.points.data(), s.size()), CloudView<float>(s.normals.data(), s.size()));
  const auto source = test::transformed(s.points, test::rigid(0.02, 0.01, -0.03, 0.004, 0.003, -0.002));
  const auto first = icp.align(CloudView<float>(source.data(), s.size()));
  for (int run = 0; run < 5; ++run) {
    const auto again = icp.align(CloudView<float>(source.data(), s.size()));
    EXPECT_EQ(first.iterations, again.iterations);
    EXPECT_TRUE(first.T_target_source == again.T_target_source) << "run " << run;  // bit for bit
  }
  // A copy uploads its own model and gives the same answer.
  Icp<float> copy = icp;
  const auto copied = copy.align(CloudView<float>(source.data(), s.size()));
  EXPECT_TRUE(first.T_target_source == copied.T_target_source);
}

TEST(CudaBackend, GivesTheCpuStatusesOnBadInput) {
  if (!haveDevice()) GTEST_SKIP() << "no CUDA device (or a build without CUDA)";
  const auto s = test::wavySurfaceWithSphere(60);
  auto far = s.points;
  for (std::size_t i = 2; i < far.size(); i += 3) far[i] += 5.0f;  // nothing within range
  std::vector<float> nan(s.points.size(), NAN);
  std::vector<float> plane;  // a flat patch: point-to-plane leaves 3 motions free
  for (int i = 0; i < 50; ++i)
    for (int j = 0; j < 50; ++j) plane.insert(plane.end(), {0.004f * i, 0.004f * j, 0.5f});
  std::vector<float> plane_normals(plane.size());
  for (std::size_t i = 0; i < plane_normals.size(); i += 3) plane_normals[i + 2] = -1.0f;
  for (auto backend : {IcpBackend::Cpu, IcpBackend::Cuda}) {
    IcpSettings settings;
    const auto a = alignOn<float>(backend, settings, s.points, s.normals, far, Eigen::Matrix4d::Identity());
    EXPECT_EQ(a.status, IcpStatus::NotEnoughCorrespondences);
    const auto b = alignOn<float>(backend, settings, s.points, s.normals, nan, Eigen::Matrix4d::Identity());
    EXPECT_EQ(b.status, IcpStatus::NotEnoughCorrespondences);
    EXPECT_EQ(b.source_points_used, 0u);
    const auto c = alignOn<float>(backend, settings, plane, plane_normals, plane, Eigen::Matrix4d::Identity());
    EXPECT_TRUE(c.degenerate);
    EXPECT_EQ(c.min_rank, 3);
  }
  // Settings changed after setTarget: refused, as on the CPU.
  IcpSettings settings;
  settings.backend = IcpBackend::Cuda;
  Icp<float> icp(settings);
  icp.setTarget(CloudView<float>(s.points.data(), s.size()), CloudView<float>(s.normals.data(), s.size()));
  icp.settings().backend = IcpBackend::Cpu;
  EXPECT_THROW(icp.align(CloudView<float>(s.points.data(), s.size())), std::invalid_argument);
}

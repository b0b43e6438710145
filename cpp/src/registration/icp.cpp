// ICP engine implementation (Algorithm 1 and §3.1-3.4 of the eye-in-hand paper
// (Comput. Electron. Agric. 180 (2021) 105929)), explicitly instantiated
// for float and double clouds.
#include "scanalign/registration/icp.hpp"
#include "scanalign/common/interrupt.hpp"
#include "scanalign/common/threads.hpp"

#include "scanalign/common/block_reduce.hpp"
#include "scanalign/common/morton_order.hpp"
#include "scanalign/common/rigid.hpp"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <type_traits>

#include "scanalign/registration/cuda/icp_device.hpp"
#include "scanalign/registration/dual_quaternion.hpp"
#include "scanalign/registration/point_to_plane_lls.hpp"
#include "scanalign/registration/point_to_point.hpp"

namespace scanalign {

const char* toString(IcpStatus status) {
  switch (status) {
    case IcpStatus::ConvergedTransform: return "converged_transform";
    case IcpStatus::ConvergedAbsoluteMse: return "converged_absolute_mse";
    case IcpStatus::ConvergedRelativeMse: return "converged_relative_mse";
    case IcpStatus::MaxIterations: return "max_iterations";
    case IcpStatus::NotEnoughCorrespondences: return "not_enough_correspondences";
    case IcpStatus::Degenerate: return "degenerate";
  }
  return "unknown";
}

const char* toString(IcpSearch search) {
  return search == IcpSearch::BucketKdTree ? "bucket_kdtree" : "left_balanced_kdtree";
}

const char* toString(RobustKernel kernel) {
  switch (kernel) {
    case RobustKernel::None: return "none";
    case RobustKernel::Huber: return "huber";
    case RobustKernel::Cauchy: return "cauchy";
  }
  return "unknown";
}

const char* toString(IcpBackend backend) { return backend == IcpBackend::Cuda ? "cuda" : "cpu"; }

const char* toString(IcpEstimator estimator) {
  switch (estimator) {
    case IcpEstimator::PointToPlane: return "point_to_plane";
    case IcpEstimator::PointToPoint: return "point_to_point";
    case IcpEstimator::DualQuaternion: return "dual_quaternion";
  }
  return "unknown";
}

void validate(const IcpSettings& s) {
  auto fail = [](const std::string& what) { throw std::invalid_argument("ICP settings: " + what); };
  if (!(s.max_correspondence_distance > 0.0) || !std::isfinite(s.max_correspondence_distance))
    fail("max_correspondence_distance must be a finite positive distance in metres");
  if (s.max_iterations < 0) fail("max_iterations must be >= 0");
  if (!(s.transformation_epsilon >= 0.0)) fail("transformation_epsilon must be >= 0");
  if (!(s.transformation_rotation_epsilon >= 0.0) || s.transformation_rotation_epsilon > 1.0)
    fail("transformation_rotation_epsilon is a cosine in [0, 1] (0 = derive from transformation_epsilon)");
  if (!(s.fitness_epsilon >= 0.0)) fail("fitness_epsilon must be >= 0");
  if (!(s.absolute_mse_epsilon >= 0.0)) fail("absolute_mse_epsilon must be >= 0");
  if (s.search_stack_depth < 1 || s.search_stack_depth > LeftBalancedKdTree<float>::kMaxStack)
    fail("search_stack_depth must be in [1, 64]");
  if (s.min_correspondences < 1) fail("min_correspondences must be >= 1");
  if (!(s.degeneracy_threshold >= 0.0) || s.degeneracy_threshold >= 1.0)
    fail("degeneracy_threshold must be in [0, 1)");
  if (s.num_threads < 0) fail("num_threads must be >= 0 (0 = all cores)");
  if (s.coarse_stride < 1) fail("coarse_stride must be >= 1 (1 = off)");
  if (!(s.robust_scale > 0.0) || !std::isfinite(s.robust_scale)) fail("robust_scale must be a finite positive length in metres");
  if (s.robust_kernel != RobustKernel::None && s.estimator != IcpEstimator::PointToPlane)
    fail("robust_kernel applies to the point_to_plane estimator only");
  if (s.box && !s.box->valid()) fail("box bounds must be finite with min <= max on every axis");
}

namespace {

/// One block's share of an iteration: the estimator's sums plus correspondence statistics.
template <typename System>
struct Partial {
  System system;
  std::size_t used = 0;     ///< finite source points inside the box
  std::size_t inliers = 0;  ///< of those, with a neighbour within range
  double sum_d2 = 0.0;      ///< sum of squared correspondence distances (m^2)
  bool exact = true;
  /// Neighbour of the previous point of this block: a search hint, not a sum.
  std::uint32_t last_node = NearestNeighbor<float>::kNone;

  void merge(const Partial& o) {
    system.merge(o.system);
    used += o.used;
    inliers += o.inliers;
    sum_d2 += o.sum_d2;
    exact = exact && o.exact;
  }
};

/// Bucket size of the ICP's tree. Larger than the tree's generic default: ICP queries
/// start from their last neighbour's leaf, and a wider leaf holds more of them whole
/// (measured: 32 fastest on the 1 mm frame-to-model workload, see bench/bench_peers.py).
constexpr int kIcpLeafSize = 32;

/// Smallest coarse subset worth a coarse phase (fewer: straight to all points).
constexpr std::size_t kMinCoarsePoints = 500;

/// The two target structures behind one interface, so the ICP pass is compiled once per
/// structure with no virtual call in the loop. Positions are in the tree's own order.
template <typename Scalar>
struct BucketSearch {
  const BucketKdTree<Scalar>& tree;
  NearestNeighbor<Scalar> nearest(const Scalar* q, Scalar max_d2, std::uint32_t hint) const {
    return tree.nearest(q, max_d2, hint);
  }
  Scalar squaredDistance(const Scalar* q, std::uint32_t pos) const { return tree.squaredDistance(q, pos); }
  void point(std::uint32_t pos, double out[3]) const {
    out[0] = tree.x(pos);
    out[1] = tree.y(pos);
    out[2] = tree.z(pos);
  }
};

template <typename Scalar>
struct LeftBalancedSearch {
  const LeftBalancedKdTree<Scalar>& tree;
  int stack_depth;
  NearestNeighbor<Scalar> nearest(const Scalar* q, Scalar max_d2, std::uint32_t hint) const {
    return tree.nearest(q, max_d2, stack_depth, hint);
  }
  Scalar squaredDistance(const Scalar* q, std::uint32_t pos) const {
    return detail::squaredDistance(q, tree.node(pos).p);
  }
  void point(std::uint32_t pos, double out[3]) const {
    const Scalar* p = tree.node(pos).p;
    out[0] = p[0];
    out[1] = p[1];
    out[2] = p[2];
  }
};

/// The GPU backend as a third "structure": its passes run whole on the device.
template <typename Scalar>
struct DeviceSearch {
  cuda::IcpDevice<Scalar>& device;
};

template <typename T>
struct IsDeviceSearch : std::false_type {};
template <typename Scalar>
struct IsDeviceSearch<DeviceSearch<Scalar>> : std::true_type {};

/// The per-pass rules at transform T (the same on both backends).
template <typename Scalar>
IcpPassRules<Scalar> passRules(const IcpSettings& s, const Eigen::Matrix4d& T) {
  IcpPassRules<Scalar> r;
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 3; ++col) r.R[3 * row + col] = static_cast<Scalar>(T(row, col));
    r.t[row] = static_cast<Scalar>(T(row, 3));
  }
  r.has_box = s.box.has_value();
  if (s.box)
    for (int k = 0; k < 3; ++k) {
      r.box_lo[k] = s.box->min[k];
      r.box_hi[k] = s.box->max[k];
    }
  r.max_squared_distance = static_cast<Scalar>(s.max_correspondence_distance * s.max_correspondence_distance);
  r.stack_depth = s.search_stack_depth;
  r.warm_start = s.warm_start;
  r.kernel = s.robust_kernel;
  r.robust_scale = s.robust_scale;
  return r;
}

/// A device pass's sums as the CPU pass's partial.
template <typename System>
Partial<System> fromDevice(const cuda::PassSums& sums, bool accumulate) {
  Partial<System> p;
  p.used = static_cast<std::size_t>(sums.used);
  p.inliers = static_cast<std::size_t>(sums.inliers);
  p.sum_d2 = sums.sum_d2;
  p.exact = sums.inexact == 0.0;
  if (!accumulate) return p;
  p.system.count = sums.inliers;
  if constexpr (std::is_same_v<System, PointToPlaneSystem>) {
    std::copy(sums.ata, sums.ata + 21, p.system.ata.begin());
    std::copy(sums.atb, sums.atb + 6, p.system.atb.begin());
    p.system.btb = sums.btb;
  } else {
    std::copy(sums.sum_s, sums.sum_s + 3, p.system.sum_s.begin());
    std::copy(sums.sum_d, sums.sum_d + 3, p.system.sum_d.begin());
    std::copy(sums.sum_sd, sums.sum_sd + 9, p.system.sum_sd.begin());
    p.system.sum_ss = sums.sum_ss;
    p.system.sum_dd = sums.sum_dd;
  }
  return p;
}

}  // namespace

template <typename Scalar>
cuda::IcpDevice<Scalar>& Icp<Scalar>::device() {
  if (!device_.device) {
    device_.device = std::make_shared<cuda::IcpDevice<Scalar>>();
    device_.uploaded = false;
  }
  if (!device_.uploaded) {
    device_.device->setTarget(lb_tree_.nodes().data(), lb_tree_.bounds().data(),
                              static_cast<std::uint32_t>(lb_tree_.size()), normals_.empty() ? nullptr : normals_.data());
    device_.uploaded = true;
  }
  return *device_.device;
}

template <typename Scalar>
void Icp<Scalar>::setTarget(const CloudView<Scalar>& points, const CloudView<Scalar>& normals) {
  if (points.empty()) throw std::invalid_argument("ICP target: empty point cloud");
  if (!normals.empty() && normals.size != points.size)
    throw std::invalid_argument("ICP target: " + std::to_string(normals.size) + " normals for " +
                                std::to_string(points.size) + " points");
  const auto t0 = std::chrono::steady_clock::now();
  const bool with_normals = !normals.empty();
  auto keep = [&](std::size_t i) {
    if (!with_normals) return true;
    const Scalar* n = normals.ptr(i);
    if (!(std::isfinite(n[0]) && std::isfinite(n[1]) && std::isfinite(n[2]))) return false;
    return double(n[0]) * n[0] + double(n[1]) * n[1] + double(n[2]) * n[2] > 1e-20;
  };
  // Only one structure is kept: the other is released. The GPU searches the left-balanced tree.
  target_backend_ = settings_.backend;
  target_search_ = target_backend_ == IcpBackend::Cuda ? IcpSearch::LeftBalancedKdTree : settings_.search;
  device_.uploaded = false;  // the device buffers stay allocated for the next model
  lb_tree_ = LeftBalancedKdTree<Scalar>();
  bucket_tree_ = BucketKdTree<Scalar>();
  if (target_search_ == IcpSearch::BucketKdTree)
    bucket_tree_.build(points, keep, kIcpLeafSize, settings_.num_threads);
  else
    lb_tree_.build(points, keep);
  const std::size_t m = targetSize();
  if (m == 0)
    throw std::invalid_argument(with_normals ? "ICP target: no point with finite coordinates and a valid normal"
                                             : "ICP target: no finite point");
  normals_.clear();
  if (with_normals) {
    normals_.resize(3 * m);
    const bool bucket = target_search_ == IcpSearch::BucketKdTree;
    for (std::size_t k = 0; k < m; ++k) {
      const Scalar* n = normals.ptr(bucket ? bucket_tree_.index(k) : lb_tree_.node(k).index());
      const double len = std::sqrt(double(n[0]) * n[0] + double(n[1]) * n[1] + double(n[2]) * n[2]);
      for (int c = 0; c < 3; ++c) normals_[3 * k + c] = static_cast<Scalar>(n[c] / len);
    }
  }
  if (target_backend_ == IcpBackend::Cuda) device();  // upload now: errors and time belong here
  tree_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

template <typename Scalar>
std::size_t Icp<Scalar>::targetSize() const {
  return target_search_ == IcpSearch::BucketKdTree ? bucket_tree_.size() : lb_tree_.size();
}

template <typename Scalar>
int Icp<Scalar>::treeHeight() const {
  return target_search_ == IcpSearch::BucketKdTree ? bucket_tree_.height() : lb_tree_.height();
}

template <typename Scalar>
IcpResult Icp<Scalar>::align(const CloudView<Scalar>& source, const Eigen::Matrix4d& T_init) {
  validate(settings_);
  if (targetSize() == 0) throw std::invalid_argument("ICP: no target set (call setTarget first)");
  if (settings_.backend != target_backend_)
    throw std::invalid_argument(std::string("ICP: settings.backend is '") + toString(settings_.backend) +
                                "' but the target was prepared for '" + toString(target_backend_) +
                                "'; call setTarget again");
  const bool on_device = target_backend_ == IcpBackend::Cuda;
  if (!on_device && settings_.search != target_search_)
    throw std::invalid_argument(std::string("ICP: settings.search is '") + toString(settings_.search) +
                                "' but the target was built for '" + toString(target_search_) +
                                "'; call setTarget again");
  if (source.empty()) throw std::invalid_argument("ICP source: empty point cloud");
  const bool plane = settings_.estimator == IcpEstimator::PointToPlane;
  if (plane && normals_.empty())
    throw std::invalid_argument("ICP: point-to-plane needs target_normals (setTarget(points, normals)), or use the point-to-point estimator");
  requireRigid(T_init, "ICP initial transform");

  const auto t0 = std::chrono::steady_clock::now();
  const std::size_t n = source.size;
  const std::size_t nblocks = (n + kReduceBlock - 1) / kReduceBlock;
  if (on_device && n > std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument("ICP source: the CUDA backend takes at most 2^32 - 1 points");
  const int threads = resolveThreads(settings_.num_threads);
  const std::size_t min_corr =
      static_cast<std::size_t>(std::max(settings_.min_correspondences, plane ? 6 : 3));
  mortonOrder(source, order_, keyed_);
  if (on_device) {
    packed_.resize(3 * n);
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) packed_[3 * i + c] = source.ptr(i)[c];
    device().setSource(packed_.data(), static_cast<std::uint32_t>(n), order_.data());
  } else {
    neighbor_.assign(n, NearestNeighbor<Scalar>::kNone);
  }

  IcpResult result;
  Eigen::Matrix4d T = T_init;
  // A coarse phase only when its subset is big enough to constrain the pose.
  const bool coarse = settings_.coarse_stride > 1 && n / static_cast<std::size_t>(settings_.coarse_stride) >= kMinCoarsePoints;
  // Per-block partial sums, allocated once here: the iteration loop allocates nothing.
  std::vector<Partial<PointToPlaneSystem>> plane_parts;
  std::vector<Partial<PointToPointSystem>> point_parts(nblocks);
  if (plane) plane_parts.resize(nblocks);

  // One pass over the source at transform T. With System = void-like accumulation off
  // (accumulate == false) it only evaluates correspondences (for the final fitness).
  // The points a pass visits: order_[0, count) with a stride (coarse phase) or all.
  std::size_t stride = 1, count = n;
  auto run = [&](const auto& search, auto system_tag, bool accumulate) {
    using System = decltype(system_tag);
    auto& parts = [&]() -> std::vector<Partial<System>>& {
      if constexpr (std::is_same_v<System, PointToPlaneSystem>)
        return plane_parts;
      else
        return point_parts;
    }();
    const IcpPassRules<Scalar> rules = passRules<Scalar>(settings_, T);
    if constexpr (IsDeviceSearch<std::decay_t<decltype(search)>>::value) {
      const auto mode = !accumulate ? cuda::PassMode::Evaluate
                                    : (std::is_same_v<System, PointToPlaneSystem> ? cuda::PassMode::PointToPlane
                                                                                  : cuda::PassMode::PointToPoint);
      return fromDevice<System>(
          search.device.pass(rules, mode, static_cast<std::uint32_t>(stride), static_cast<std::uint32_t>(count)),
          accumulate);
    } else {
      return blockReduce(count, threads, parts, [&](std::size_t k, Partial<System>& part) {
        const std::size_t i = order_[k * stride];
        const Scalar* s = source.ptr(i);
        if (!detail::sourcePointUsed(rules, s)) return;
        ++part.used;
        Scalar q[3];
        detail::transformPoint(rules, s, q);
        // Hints (exact: they only tighten the initial bound): this point's neighbour in the
        // last iteration, and the previous point's neighbour in this pass.
        std::uint32_t hint = NearestNeighbor<Scalar>::kNone;
        if (rules.warm_start) {
          hint = neighbor_[i];
          const std::uint32_t other = part.last_node;
          if (other != NearestNeighbor<Scalar>::kNone &&
              (hint == NearestNeighbor<Scalar>::kNone ||
               search.squaredDistance(q, other) < search.squaredDistance(q, hint)))
            hint = other;
        }
        const auto nn = search.nearest(q, rules.max_squared_distance, hint);
        part.exact = part.exact && nn.exact;
        if (!nn.found()) return;
        neighbor_[i] = nn.node;
        part.last_node = nn.node;
        ++part.inliers;
        part.sum_d2 += nn.squared_distance;
        if (!accumulate) return;
        const double sq[3] = {double(q[0]), double(q[1]), double(q[2])};
        double dq[3];
        search.point(nn.node, dq);
        if constexpr (std::is_same_v<System, PointToPlaneSystem>) {
          const Scalar* np = &normals_[3 * static_cast<std::size_t>(nn.node)];
          const double nq[3] = {double(np[0]), double(np[1]), double(np[2])};
          part.system.add(sq, dq, nq, detail::robustWeight(rules.kernel, rules.robust_scale, sq, dq, nq));
        } else {
          part.system.add(sq, dq);
        }
      });
    }
  };

  auto iterate = [&](const auto& search, auto system_tag, int& iterations) {
    double prev_mse = std::numeric_limits<double>::max();
    const double rot_threshold = settings_.transformation_rotation_epsilon > 0.0
                                     ? settings_.transformation_rotation_epsilon
                                     : 1.0 - settings_.transformation_epsilon;
    for (int it = 0; it < settings_.max_iterations; ++it) {
      checkInterrupt();  // between iterations, outside the parallel pass (interrupt.hpp)
      const auto total = run(search, system_tag, true);
      result.exact_search = result.exact_search && total.exact;
      if (total.inliers < min_corr) {
        result.status = IcpStatus::NotEnoughCorrespondences;
        return;
      }
      Eigen::Matrix4d delta;
      if constexpr (std::is_same_v<decltype(system_tag), PointToPlaneSystem>) {
        const PointToPlaneSolve sol =
            solvePointToPlane(total.system.AtA(), total.system.Atb(), settings_.degeneracy_threshold);
        result.min_rank = std::min(result.min_rank, sol.rank);
        result.degenerate = result.degenerate || sol.degenerate;
        delta = transformFromParameters(sol.x);
      } else {
        const PointToPointSolve sol = settings_.estimator == IcpEstimator::DualQuaternion
                                          ? solveDualQuaternion(total.system, settings_.degeneracy_threshold)
                                          : solvePointToPoint(total.system, settings_.degeneracy_threshold);
        result.min_rank = std::min(result.min_rank, sol.rank == 3 ? 6 : sol.rank * 2);
        result.degenerate = result.degenerate || sol.degenerate;
        if (sol.degenerate) {  // the rotation is not determined: no answer to converge to
          result.status = IcpStatus::Degenerate;
          result.converged = false;
          return;
        }
        delta = sol.T;
      }
      T = delta * T;
      ++iterations;
      const double mse = total.sum_d2 / static_cast<double>(total.inliers);
      result.mse = mse;
      // Convergence as pcl::DefaultConvergenceCriteria, on the increment `delta`.
      const double cos_angle = 0.5 * (delta(0, 0) + delta(1, 1) + delta(2, 2) - 1.0);
      const double trans2 = delta.topRightCorner<3, 1>().squaredNorm();
      if (cos_angle >= rot_threshold && trans2 <= settings_.transformation_epsilon) {
        result.status = IcpStatus::ConvergedTransform;
        result.converged = true;
        return;
      }
      if (std::abs(mse - prev_mse) < settings_.absolute_mse_epsilon) {
        result.status = IcpStatus::ConvergedAbsoluteMse;
        result.converged = true;
        return;
      }
      if (std::abs(mse - prev_mse) / prev_mse < settings_.fitness_epsilon) {
        result.status = IcpStatus::ConvergedRelativeMse;
        result.converged = true;
        return;
      }
      prev_mse = mse;
    }
    result.status = IcpStatus::MaxIterations;
  };

  auto solve = [&](const auto& search) {
    if (coarse) {
      stride = static_cast<std::size_t>(settings_.coarse_stride);
      count = (n + stride - 1) / stride;
      if (plane)
        iterate(search, PointToPlaneSystem{}, result.coarse_iterations);
      else
        iterate(search, PointToPointSystem{}, result.coarse_iterations);
      stride = 1;
      count = n;
      // The full-resolution loop decides the outcome on its own: a subset may be
      // degenerate (or short of correspondences) where all points are not.
      result.status = IcpStatus::MaxIterations;
      result.converged = false;
      result.mse = 0.0;
      result.min_rank = 6;
      result.degenerate = false;
    }
    if (plane)
      iterate(search, PointToPlaneSystem{}, result.iterations);
    else
      iterate(search, PointToPointSystem{}, result.iterations);
    // Quality at the final transform (one more search, no estimation).
    return run(search, PointToPointSystem{}, false);
  };
  const auto final_pass = on_device ? solve(DeviceSearch<Scalar>{device()})
                          : target_search_ == IcpSearch::BucketKdTree
                              ? solve(BucketSearch<Scalar>{bucket_tree_})
                              : solve(LeftBalancedSearch<Scalar>{lb_tree_, settings_.search_stack_depth});
  result.exact_search = result.exact_search && final_pass.exact;
  result.T_target_source = T;
  result.source_points_used = final_pass.used;
  result.correspondence_count = final_pass.inliers;
  result.fitness = final_pass.used ? double(final_pass.inliers) / double(final_pass.used) : 0.0;
  result.inlier_rmse = final_pass.inliers ? std::sqrt(final_pass.sum_d2 / double(final_pass.inliers)) : 0.0;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

template class Icp<float>;
template class Icp<double>;

}  // namespace scanalign

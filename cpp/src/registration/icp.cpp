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

}  // namespace

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
  // Only one structure is kept: the other is released.
  target_search_ = settings_.search;
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
  if (settings_.search != target_search_)
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
  const Scalar max_d2 = static_cast<Scalar>(settings_.max_correspondence_distance * settings_.max_correspondence_distance);
  const bool warm = settings_.warm_start;
  const std::optional<Box> box = settings_.box;
  const RobustKernel kernel = settings_.robust_kernel;
  const double robust_k = settings_.robust_scale;
  const int threads = resolveThreads(settings_.num_threads);
  const std::size_t min_corr =
      static_cast<std::size_t>(std::max(settings_.min_correspondences, plane ? 6 : 3));
  neighbor_.assign(n, NearestNeighbor<Scalar>::kNone);
  mortonOrder(source, order_, keyed_);

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
    const Eigen::Matrix<Scalar, 3, 3> R = T.topLeftCorner<3, 3>().cast<Scalar>();
    const Eigen::Matrix<Scalar, 3, 1> t = T.topRightCorner<3, 1>().cast<Scalar>();
    return blockReduce(count, threads, parts, [&](std::size_t k, Partial<System>& part) {
      const std::size_t i = order_[k * stride];
      const Scalar* s = source.ptr(i);
      if (!(std::isfinite(s[0]) && std::isfinite(s[1]) && std::isfinite(s[2]))) return;
      if (box && !box->contains(s)) return;
      ++part.used;
      const Eigen::Matrix<Scalar, 3, 1> q = R * Eigen::Map<const Eigen::Matrix<Scalar, 3, 1>>(s) + t;
      // Hints (exact: they only tighten the initial bound): this point's neighbour in the
      // last iteration, and the previous point's neighbour in this pass.
      std::uint32_t hint = NearestNeighbor<Scalar>::kNone;
      if (warm) {
        hint = neighbor_[i];
        const std::uint32_t other = part.last_node;
        if (other != NearestNeighbor<Scalar>::kNone &&
            (hint == NearestNeighbor<Scalar>::kNone ||
             search.squaredDistance(q.data(), other) < search.squaredDistance(q.data(), hint)))
          hint = other;
      }
      const auto nn = search.nearest(q.data(), max_d2, hint);
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
        double w = 1.0;
        if (kernel != RobustKernel::None) {
          const double r = std::abs(nq[0] * (dq[0] - sq[0]) + nq[1] * (dq[1] - sq[1]) + nq[2] * (dq[2] - sq[2]));
          w = kernel == RobustKernel::Huber ? (r <= robust_k ? 1.0 : robust_k / r)
                                            : 1.0 / (1.0 + (r / robust_k) * (r / robust_k));
        }
        part.system.add(sq, dq, nq, w);
      } else {
        part.system.add(sq, dq);
      }
    });
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
  const auto final_pass = target_search_ == IcpSearch::BucketKdTree
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

// The fast ICP engine: Algorithm 1 of the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929)
// written for CPU cores.
//
// One parallel pass per iteration transforms each source point, finds its nearest model
// point in the left-balanced k-d tree, rejects it by box and distance, and adds its
// terms to the estimator's normal equations. Points are processed in fixed blocks whose
// partial sums are reduced by a pairwise tree in a fixed order, so the result does not
// depend on the number of threads. All buffers are sized before the iteration loop.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "scanalign/common/cloud_view.hpp"
#include "scanalign/registration/box.hpp"
#include "scanalign/registration/bucket_kdtree.hpp"
#include "scanalign/registration/correspondence_terms.hpp"
#include "scanalign/registration/kdtree.hpp"

namespace scanalign {

enum class IcpEstimator {
  PointToPlane,  ///< Low (2004) linear least squares, eye-in-hand paper §3.2 (needs target normals)
  PointToPoint,  ///< closed form (Horn / Umeyama): the SVD of the cross-covariance, for comparison
  /// Point-to-point by dual number quaternions (Walker, Shao & Volz 1991): the eye-in-hand
  /// paper's variant (b) and PCL's TransformationEstimationDualQuaternion. The same
  /// least-squares answer as PointToPoint from the same sums (registration/dual_quaternion.hpp).
  DualQuaternion,
};

/// The nearest-neighbour structure over the target.
enum class IcpSearch {
  /// K-d tree with 8-point leaf buckets and tight node boxes (bucket_kdtree.hpp): the
  /// fastest on CPU cores. Always exact.
  BucketKdTree,
  /// Eye-in-hand paper §3.1: the left-balanced tree, one point per node, searched with a fixed
  /// stack of search_stack_depth entries (the layout the eye-in-hand paper copies to a GPU).
  LeftBalancedKdTree,
};

/// Where the ICP passes run.
enum class IcpBackend {
  Cpu,   ///< the CPU cores (OpenMP), either search structure
  /// An NVIDIA GPU (Algorithm 1 of the eye-in-hand paper): the model's left-balanced tree
  /// (built on the CPU) stays on the device; per iteration one kernel pass and the 6x6 solve
  /// on the CPU. Needs a build with SCANALIGN_WITH_CUDA (NotBuiltError otherwise) and a device.
  Cuda,
};

/// Why the ICP loop stopped.
enum class IcpStatus {
  ConvergedTransform,        ///< the last increment was below the transformation epsilon
  ConvergedAbsoluteMse,      ///< |MSE change| below absolute_mse_epsilon
  ConvergedRelativeMse,      ///< |MSE change| / MSE below the fitness epsilon
  MaxIterations,             ///< max_iterations reached first: not converged
  NotEnoughCorrespondences,  ///< fewer than min_correspondences survived rejection
  /// Point-to-point (either closed form) only: the correspondences do not determine the
  /// rotation (the source points, or the target points they matched, coincide or lie on one
  /// line; rank < 2).
  /// Not converged; the transform is the estimate before that iteration. (Point-to-plane
  /// solves rank-deficient systems in their constrained directions and reports it through
  /// IcpResult::degenerate / min_rank: a plane constrains 3 of the 6 motions.)
  Degenerate,
};

const char* toString(IcpStatus status);
const char* toString(IcpEstimator estimator);
const char* toString(IcpSearch search);
const char* toString(RobustKernel kernel);
const char* toString(IcpBackend backend);

/// ICP settings. Defaults are the eye-in-hand paper's (§3.3) where it gives one. PCL semantics.
struct IcpSettings {
  IcpEstimator estimator = IcpEstimator::PointToPlane;
  /// Correspondences farther apart than this are rejected (m). Also bounds the search.
  double max_correspondence_distance = 0.05;
  /// Stop after this many iterations (status MaxIterations, not converged). Eye-in-hand paper §3.3: 50.
  int max_iterations = 50;
  /// Converged when the increment's squared translation is <= this (m^2) and its rotation
  /// satisfies cos(angle) >= 1 - this, as pcl::IterativeClosestPoint. Eye-in-hand paper §3.3: 1e-8.
  double transformation_epsilon = 1e-8;
  /// If > 0, the rotation test uses cos(angle) >= this value instead (PCL's
  /// setTransformationRotationEpsilon; a cosine, e.g. 0.99999).
  double transformation_rotation_epsilon = 0.0;
  /// Converged when |MSE_k - MSE_{k-1}| / MSE_{k-1} < this (PCL's Euclidean fitness
  /// epsilon; MSE of correspondence distances, m^2). Eye-in-hand paper §3.3: 1e-8.
  double fitness_epsilon = 1e-8;
  /// Converged when |MSE_k - MSE_{k-1}| < this (m^2). PCL's default 1e-12.
  double absolute_mse_epsilon = 1e-12;
  /// Robust kernel on the point-to-plane residual (point-to-plane only). Default: none,
  /// as the eye-in-hand paper.
  RobustKernel robust_kernel = RobustKernel::None;
  /// The kernel's scale k (m): residuals up to about k count fully. Set it near the
  /// residual noise after convergence (a few voxel sizes; 0.1 m on a 0.25 m LiDAR grid).
  double robust_scale = 0.01;
  /// Optional box in the source camera frame (eye-in-hand paper §3.4).
  std::optional<Box> box;
  /// Nearest-neighbour structure built by setTarget (changing it needs a new setTarget).
  IcpSearch search = IcpSearch::BucketKdTree;
  /// Depth of the fixed search stack of the left-balanced tree (eye-in-hand paper §3.1: 20).
  /// Exact while the tree's height is <= this, i.e. up to 2^21 - 1 model points at depth
  /// 20; deeper trees may approximate, which IcpResult::exact_search reports. The bucket
  /// tree's search is always exact and ignores this.
  int search_stack_depth = 20;
  /// Seed each search with last iteration's neighbour and the previous query's (exact:
  /// a hint only tightens the search bound, so results equal a cold search up to ties).
  bool warm_start = true;
  /// Fewer correspondences than this stop ICP (status NotEnoughCorrespondences).
  /// 6 unknowns for point-to-plane; at least 3 is enforced for the point-to-point estimators.
  int min_correspondences = 6;
  /// lambda_min / lambda_max of the balanced normal matrix below which a direction
  /// counts as unconstrained (see solvePointToPlane); such directions are not updated.
  /// Kept low on purpose: a small object on a large table legitimately gives ratios near
  /// 1e-7 (the table's points dominate lambda_max), and freezing those motions would be
  /// a silent wrong answer; only (numerically) exact rank loss is treated as degenerate.
  /// Point-to-point and dual quaternion: the same bound on the cross-covariance's singular
  /// values relative to the spreads of the matched points (solvePointToPoint); rank < 2 ends
  /// the run with status Degenerate.
  double degeneracy_threshold = 1e-10;
  /// Coarse-to-fine: when > 1, ICP first iterates on every coarse_stride-th source point
  /// (in the Z-order the engine visits points in, so an even spatial subset) until that
  /// converges by the criteria above, then on all points until they converge. The coarse
  /// phase only moves the start of the full-resolution iterations closer to their fixed
  /// point, which is the answer either way; each coarse iteration costs 1/coarse_stride
  /// of a full one. 1 = off (the eye-in-hand paper: every iteration on all points). Skipped when the
  /// subset would have fewer than 500 points.
  int coarse_stride = 1;
  /// OpenMP threads; 0 = OpenMP's default (all cores).
  int num_threads = 0;
  /// Where the passes run. Cuda always searches the left-balanced tree (the layout the
  /// device receives; `search` is ignored) with a stack of search_stack_depth entries, and
  /// gives the CPU engine's poses on the same input (the same per-point arithmetic; only the
  /// order of the final sums differs). Changing it needs a new setTarget.
  IcpBackend backend = IcpBackend::Cpu;
};

/// ICP outcome. Quality figures are evaluated at the final transform.
struct IcpResult {
  /// Maps source-frame coordinates into the target frame: p_target = T * p_source.
  Eigen::Matrix4d T_target_source = Eigen::Matrix4d::Identity();
  bool converged = false;   ///< a convergence criterion (transform or MSE) was met
  IcpStatus status = IcpStatus::MaxIterations;
  int iterations = 0;       ///< full-resolution iterations run (each: search + estimate + update)
  int coarse_iterations = 0;  ///< iterations of the coarse phase (IcpSettings::coarse_stride)
  double fitness = 0.0;     ///< inliers / usable source points (finite, inside the box)
  double inlier_rmse = 0.0; ///< RMS point-to-point distance of the inliers (m)
  std::size_t correspondence_count = 0;  ///< inlier correspondences at the final transform
  std::size_t source_points_used = 0;    ///< finite source points inside the box
  double mse = 0.0;         ///< mean squared correspondence distance of the last iteration (m^2)
  bool degenerate = false;  ///< some iteration had an unconstrained direction (rank < 6)
  int min_rank = 6;         ///< smallest rank seen over the iterations
  bool exact_search = true; ///< every nearest-neighbour search was exact
  double seconds = 0.0;     ///< wall time of align() (tree build excluded)
};

namespace cuda {
template <typename Scalar>
class IcpDevice;
}

/// Reusable ICP: build the target's k-d tree once (setTarget), align many sources.
/// Not thread-safe for concurrent align() on one object (it owns scratch buffers).
/// With IcpBackend::Cuda the tree is also uploaded to the GPU, where it stays until the next
/// setTarget; a copy of the object uploads its own on first use.
template <typename Scalar>
class Icp {
 public:
  explicit Icp(IcpSettings settings = {}) : settings_(std::move(settings)) {}

  /// Sets the model: points (and unit normals, required for point-to-plane) in the target
  /// frame, and builds the search structure settings().search names. Non-finite points or
  /// normals, and zero normals, are left out of the tree. Normals are re-normalised.
  /// Throws std::invalid_argument on size mismatch / no points.
  void setTarget(const CloudView<Scalar>& points, const CloudView<Scalar>& normals = {});

  /// Aligns `source` (points in the source camera frame) to the target starting from
  /// T_target_source_init. Throws std::invalid_argument for an empty source, no target,
  /// invalid settings or a non-rigid/non-finite initial transform, and Interrupted
  /// (common/interrupt.hpp; KeyboardInterrupt in Python) when the installed interrupt hook
  /// asks to stop between iterations; the engine and its target stay usable.
  IcpResult align(const CloudView<Scalar>& source,
                  const Eigen::Matrix4d& T_target_source_init = Eigen::Matrix4d::Identity());

  const IcpSettings& settings() const { return settings_; }
  IcpSettings& settings() { return settings_; }
  /// Target points in the search structure (finite, with a valid normal if normals were given).
  std::size_t targetSize() const;
  /// Levels of the target's tree below its root.
  int treeHeight() const;
  /// The structure setTarget built (align() requires settings().search to match on the CPU).
  IcpSearch targetSearch() const { return target_search_; }
  /// The backend setTarget prepared (align() requires settings().backend to match).
  IcpBackend targetBackend() const { return target_backend_; }
  const LeftBalancedKdTree<Scalar>& leftBalancedTree() const { return lb_tree_; }
  const BucketKdTree<Scalar>& bucketTree() const { return bucket_tree_; }
  bool hasNormals() const { return !normals_.empty(); }
  double treeBuildSeconds() const { return tree_seconds_; }

 private:
  IcpSettings settings_;
  LeftBalancedKdTree<Scalar> lb_tree_;
  BucketKdTree<Scalar> bucket_tree_;
  IcpSearch target_search_ = IcpSearch::BucketKdTree;
  IcpBackend target_backend_ = IcpBackend::Cpu;
  /// The GPU copy of the target (backend Cuda): a cache of lb_tree_ and normals_, which a
  /// copy of the Icp object does not share (it uploads its own when it first aligns). A new
  /// setTarget re-uploads into the same device buffers (the frame loop's model grows slowly).
  struct DeviceCache {
    std::shared_ptr<cuda::IcpDevice<Scalar>> device;
    bool uploaded = false;  ///< the device holds the current lb_tree_ and normals_
    DeviceCache() = default;
    DeviceCache(const DeviceCache&) {}
    DeviceCache& operator=(const DeviceCache&) {
      device.reset();
      uploaded = false;
      return *this;
    }
    DeviceCache(DeviceCache&&) = default;
    DeviceCache& operator=(DeviceCache&&) = default;
  };
  DeviceCache device_;
  cuda::IcpDevice<Scalar>& device();  ///< creates the device object and uploads the target when needed
  std::vector<Scalar> packed_;  ///< the source packed as x, y, z for the upload (backend Cuda)
  std::vector<Scalar> normals_;           ///< 3 per target point, in the built tree's order
  std::vector<std::uint32_t> neighbor_;   ///< last neighbour (node) per source point
  std::vector<std::uint32_t> order_;      ///< processing order of the source (Morton)
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed_;  ///< scratch for the order
  double tree_seconds_ = 0.0;
};

/// Throws std::invalid_argument when the settings cannot be used.
void validate(const IcpSettings& settings);

extern template class Icp<float>;
extern template class Icp<double>;

}  // namespace scanalign

// PointToPointDualQuaternion: scanalign's dual-quaternion point-to-point estimator (Walker,
// Shao & Volz, CVGIP: Image Understanding 54(3) (1991) 358-367; registration/dual_quaternion.hpp)
// as a drop-in pcl::registration::TransformationEstimation, e.g. for pcl::IterativeClosestPoint:
//
//   auto est = pcl::make_shared<scanalign::PointToPointDualQuaternion<pcl::PointXYZ, pcl::PointXYZ>>();
//   icp.setTransformationEstimation(est);
//
// Differences from pcl::registration::TransformationEstimationDualQuaternion: the coordinates
// are multiplied in double (PCL forms the products in float), the sums are accumulated in
// parallel blocks and reduced by a fixed summing tree (deterministic), non-finite pairs are
// skipped, and coincident or collinear correspondences are detected (lastSolve()) and give the
// translation of the means only.
#pragma once

#include <cmath>

#include "scanalign/registration/dual_quaternion.hpp"
#include "scanalign/registration/pcl/pairwise_estimator.hpp"

namespace scanalign {

template <typename PointSource, typename PointTarget, typename Scalar = float>
class PointToPointDualQuaternion
    : public PairwiseEstimator<PointToPointDualQuaternion<PointSource, PointTarget, Scalar>, PointSource, PointTarget,
                               Scalar> {
  using Estimator = PairwiseEstimator<PointToPointDualQuaternion, PointSource, PointTarget, Scalar>;
  friend Estimator;

 public:
  using Ptr = pcl::shared_ptr<PointToPointDualQuaternion>;
  using ConstPtr = pcl::shared_ptr<const PointToPointDualQuaternion>;

  explicit PointToPointDualQuaternion(double degeneracy_threshold = 1e-10, int num_threads = 0)
      : Estimator(degeneracy_threshold, num_threads) {}

  /// The last solve: rank and degenerate flag (not thread-safe across concurrent estimates
  /// on one object, like PCL's estimators' state).
  const PointToPointSolve& lastSolve() const { return last_; }

 private:
  using System = PointToPointSystem;
  static constexpr const char* kName = "PointToPointDualQuaternion";

  static void addPair(const PointSource& s, const PointTarget& d, System& system) {
    const double sv[3] = {s.x, s.y, s.z};
    const double dv[3] = {d.x, d.y, d.z};
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(sv[k]) || !std::isfinite(dv[k])) return;
    system.add(sv, dv);
  }

  Eigen::Matrix4d solve(const System& system) const {
    last_ = solveDualQuaternion(system, this->degeneracy_threshold_);
    if (last_.degenerate)
      PCL_DEBUG("[scanalign::PointToPointDualQuaternion] coincident or collinear correspondences (rank %d of 3, "
                "%g pairs): translation of the means only\n",
                last_.rank, system.count);
    return last_.T;
  }

  void reset() const { last_ = PointToPointSolve{}; }

  mutable PointToPointSolve last_;
};

}  // namespace scanalign

// The common instantiations are compiled once into scanalign::pcl.
#include <pcl/point_types.h>
extern template class scanalign::PointToPointDualQuaternion<pcl::PointXYZ, pcl::PointXYZ, float>;
extern template class scanalign::PointToPointDualQuaternion<pcl::PointXYZ, pcl::PointXYZ, double>;
extern template class scanalign::PointToPointDualQuaternion<pcl::PointNormal, pcl::PointNormal, float>;
extern template class scanalign::PointToPointDualQuaternion<pcl::PointNormal, pcl::PointNormal, double>;

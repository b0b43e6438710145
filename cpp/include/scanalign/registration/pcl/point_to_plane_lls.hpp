// PointToPlaneLLS: Low's point-to-plane linear least squares (the eye-in-hand paper, Comput. Electron. Agric. 180 (2021) 105929, §3.2) as a drop-in
// pcl::registration::TransformationEstimation, e.g. for pcl::IterativeClosestPointWithNormals:
//
//   auto est = pcl::make_shared<scanalign::PointToPlaneLLS<pcl::PointNormal, pcl::PointNormal>>();
//   icp.setTransformationEstimation(est);
//
// Differences from pcl::registration::TransformationEstimationPointToPlaneLLS: the sums are
// accumulated in parallel blocks and reduced by a fixed summing tree (deterministic), the
// 6x6 system is solved by LDLT instead of an explicit inverse, and a rank-deficient system
// is detected (lastSolve()) and solved only along its constrained directions.
#pragma once

#include <cmath>

#include "scanalign/registration/pcl/pairwise_estimator.hpp"
#include "scanalign/registration/point_to_plane_lls.hpp"

namespace scanalign {

template <typename PointSource, typename PointTarget, typename Scalar = float>
class PointToPlaneLLS
    : public PairwiseEstimator<PointToPlaneLLS<PointSource, PointTarget, Scalar>, PointSource, PointTarget, Scalar> {
  using Estimator = PairwiseEstimator<PointToPlaneLLS, PointSource, PointTarget, Scalar>;
  friend Estimator;

 public:
  using Ptr = pcl::shared_ptr<PointToPlaneLLS>;
  using ConstPtr = pcl::shared_ptr<const PointToPlaneLLS>;

  explicit PointToPlaneLLS(double degeneracy_threshold = 1e-10, int num_threads = 0)
      : Estimator(degeneracy_threshold, num_threads) {}

  /// The last solve: rank, conditioning, degenerate flag (not thread-safe across
  /// concurrent estimates on one object, like PCL's estimators' state).
  const PointToPlaneSolve& lastSolve() const { return last_; }

 private:
  using System = PointToPlaneSystem;
  static constexpr const char* kName = "PointToPlaneLLS";

  static void addPair(const PointSource& s, const PointTarget& d, System& system) {
    const double sv[3] = {s.x, s.y, s.z};
    const double dv[3] = {d.x, d.y, d.z};
    const double nv[3] = {d.normal_x, d.normal_y, d.normal_z};
    for (int k = 0; k < 3; ++k)
      if (!std::isfinite(sv[k]) || !std::isfinite(dv[k]) || !std::isfinite(nv[k])) return;  // as PCL: skip
    system.add(sv, dv, nv);
  }

  Eigen::Matrix4d solve(const System& system) const {
    last_ = solvePointToPlane(system.AtA(), system.Atb(), this->degeneracy_threshold_);
    if (last_.degenerate)
      PCL_DEBUG("[scanalign::PointToPlaneLLS] rank-deficient system (rank %d of 6, %g correspondences): "
                "unconstrained directions left unchanged\n",
                last_.rank, system.count);
    return transformFromParameters(last_.x);
  }

  void reset() const { last_ = PointToPlaneSolve{}; }

  mutable PointToPlaneSolve last_;
};

}  // namespace scanalign

// The common instantiations are compiled once into scanalign::pcl.
#include <pcl/point_types.h>
extern template class scanalign::PointToPlaneLLS<pcl::PointNormal, pcl::PointNormal, float>;
extern template class scanalign::PointToPlaneLLS<pcl::PointNormal, pcl::PointNormal, double>;
extern template class scanalign::PointToPlaneLLS<pcl::PointXYZ, pcl::PointNormal, float>;
extern template class scanalign::PointToPlaneLLS<pcl::PointXYZ, pcl::PointNormal, double>;
extern template class scanalign::PointToPlaneLLS<pcl::PointXYZRGBNormal, pcl::PointXYZRGBNormal, float>;

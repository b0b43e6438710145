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
#include <vector>

#include <pcl/correspondence.h>
#include <pcl/point_cloud.h>
#include <pcl/registration/transformation_estimation.h>

#include "scanalign/common/block_reduce.hpp"
#include "scanalign/registration/dual_quaternion.hpp"

namespace scanalign {

template <typename PointSource, typename PointTarget, typename Scalar = float>
class PointToPointDualQuaternion : public pcl::registration::TransformationEstimation<PointSource, PointTarget, Scalar> {
 public:
  using Base = pcl::registration::TransformationEstimation<PointSource, PointTarget, Scalar>;
  using Matrix4 = typename Base::Matrix4;
  using Ptr = pcl::shared_ptr<PointToPointDualQuaternion>;
  using ConstPtr = pcl::shared_ptr<const PointToPointDualQuaternion>;

  explicit PointToPointDualQuaternion(double degeneracy_threshold = 1e-10, int num_threads = 0)
      : degeneracy_threshold_(degeneracy_threshold), num_threads_(num_threads) {}

  /// Pairs cloud_src[i] with cloud_tgt[i]; the clouds must have equal sizes.
  void estimateRigidTransformation(const pcl::PointCloud<PointSource>& cloud_src,
                                   const pcl::PointCloud<PointTarget>& cloud_tgt,
                                   Matrix4& transformation_matrix) const override {
    if (cloud_src.size() != cloud_tgt.size()) return sizeError(cloud_src.size(), cloud_tgt.size(), transformation_matrix);
    estimate(cloud_src.size(), [&](std::size_t i) -> const PointSource& { return cloud_src[i]; },
             [&](std::size_t i) -> const PointTarget& { return cloud_tgt[i]; }, transformation_matrix);
  }

  /// Pairs cloud_src[indices_src[i]] with cloud_tgt[i].
  void estimateRigidTransformation(const pcl::PointCloud<PointSource>& cloud_src, const pcl::Indices& indices_src,
                                   const pcl::PointCloud<PointTarget>& cloud_tgt,
                                   Matrix4& transformation_matrix) const override {
    if (indices_src.size() != cloud_tgt.size())
      return sizeError(indices_src.size(), cloud_tgt.size(), transformation_matrix);
    estimate(indices_src.size(), [&](std::size_t i) -> const PointSource& { return cloud_src[indices_src[i]]; },
             [&](std::size_t i) -> const PointTarget& { return cloud_tgt[i]; }, transformation_matrix);
  }

  /// Pairs cloud_src[indices_src[i]] with cloud_tgt[indices_tgt[i]].
  void estimateRigidTransformation(const pcl::PointCloud<PointSource>& cloud_src, const pcl::Indices& indices_src,
                                   const pcl::PointCloud<PointTarget>& cloud_tgt, const pcl::Indices& indices_tgt,
                                   Matrix4& transformation_matrix) const override {
    if (indices_src.size() != indices_tgt.size())
      return sizeError(indices_src.size(), indices_tgt.size(), transformation_matrix);
    estimate(indices_src.size(), [&](std::size_t i) -> const PointSource& { return cloud_src[indices_src[i]]; },
             [&](std::size_t i) -> const PointTarget& { return cloud_tgt[indices_tgt[i]]; }, transformation_matrix);
  }

  /// Pairs cloud_src[c.index_query] with cloud_tgt[c.index_match] for each correspondence c.
  void estimateRigidTransformation(const pcl::PointCloud<PointSource>& cloud_src,
                                   const pcl::PointCloud<PointTarget>& cloud_tgt,
                                   const pcl::Correspondences& correspondences,
                                   Matrix4& transformation_matrix) const override {
    estimate(correspondences.size(),
             [&](std::size_t i) -> const PointSource& { return cloud_src[correspondences[i].index_query]; },
             [&](std::size_t i) -> const PointTarget& { return cloud_tgt[correspondences[i].index_match]; },
             transformation_matrix);
  }

  /// The last solve: rank and degenerate flag (not thread-safe across concurrent estimates
  /// on one object, like PCL's estimators' state).
  const PointToPointSolve& lastSolve() const { return last_; }
  void setDegeneracyThreshold(double t) { degeneracy_threshold_ = t; }
  double getDegeneracyThreshold() const { return degeneracy_threshold_; }
  void setNumberOfThreads(int n) { num_threads_ = n; }

 private:
  struct Partial {
    PointToPointSystem system;
    void merge(const Partial& o) { system.merge(o.system); }
  };

  template <typename SrcAt, typename TgtAt>
  void estimate(std::size_t n, SrcAt&& src, TgtAt&& tgt, Matrix4& transformation_matrix) const {
    std::vector<Partial> scratch;
    const Partial total = blockReduce(n, num_threads_, scratch, [&](std::size_t i, Partial& part) {
      const PointSource& s = src(i);
      const PointTarget& d = tgt(i);
      const double sv[3] = {s.x, s.y, s.z};
      const double dv[3] = {d.x, d.y, d.z};
      for (int k = 0; k < 3; ++k)
        if (!std::isfinite(sv[k]) || !std::isfinite(dv[k])) return;
      part.system.add(sv, dv);
    });
    last_ = solveDualQuaternion(total.system, degeneracy_threshold_);
    if (last_.degenerate)
      PCL_DEBUG("[scanalign::PointToPointDualQuaternion] coincident or collinear correspondences (rank %d of 3, "
                "%g pairs): translation of the means only\n",
                last_.rank, total.system.count);
    transformation_matrix = last_.T.template cast<Scalar>();
  }

  void sizeError(std::size_t a, std::size_t b, Matrix4& transformation_matrix) const {
    PCL_ERROR("[scanalign::PointToPointDualQuaternion::estimateRigidTransformation] source (%zu) and target (%zu) "
              "sizes differ\n",
              a, b);
    last_ = PointToPointSolve{};
    transformation_matrix.setIdentity();
  }

  double degeneracy_threshold_;
  int num_threads_;
  mutable PointToPointSolve last_;
};

}  // namespace scanalign

// The common instantiations are compiled once into scanalign::pcl.
#include <pcl/point_types.h>
extern template class scanalign::PointToPointDualQuaternion<pcl::PointXYZ, pcl::PointXYZ, float>;
extern template class scanalign::PointToPointDualQuaternion<pcl::PointXYZ, pcl::PointXYZ, double>;
extern template class scanalign::PointToPointDualQuaternion<pcl::PointNormal, pcl::PointNormal, float>;
extern template class scanalign::PointToPointDualQuaternion<pcl::PointNormal, pcl::PointNormal, double>;

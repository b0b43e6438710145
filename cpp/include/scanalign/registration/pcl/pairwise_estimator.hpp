// What scanalign's PCL transformation estimators share: PCL's four ways of pairing source and
// target points (whole clouds, source indices, both indices, correspondences), the parallel
// accumulation of the per-pair sums in blocks reduced by a fixed summing tree (deterministic for
// any thread count), and the size check. An estimator (CRTP) gives its normal equations
// (`System`: add, merge), how one pair enters them (`addPair`), and its solve (`solve`).
#pragma once

#include <vector>

#include <Eigen/Core>
#include <pcl/correspondence.h>
#include <pcl/point_cloud.h>
#include <pcl/registration/transformation_estimation.h>

#include "scanalign/common/block_reduce.hpp"

namespace scanalign {

template <typename Derived, typename PointSource, typename PointTarget, typename Scalar>
class PairwiseEstimator : public pcl::registration::TransformationEstimation<PointSource, PointTarget, Scalar> {
 public:
  using Base = pcl::registration::TransformationEstimation<PointSource, PointTarget, Scalar>;
  using Matrix4 = typename Base::Matrix4;

  PairwiseEstimator(double degeneracy_threshold, int num_threads)
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

  void setDegeneracyThreshold(double t) { degeneracy_threshold_ = t; }
  double getDegeneracyThreshold() const { return degeneracy_threshold_; }
  void setNumberOfThreads(int n) { num_threads_ = n; }

 protected:
  double degeneracy_threshold_;
  int num_threads_;

 private:
  const Derived& self() const { return static_cast<const Derived&>(*this); }

  template <typename SrcAt, typename TgtAt>
  void estimate(std::size_t n, SrcAt&& src, TgtAt&& tgt, Matrix4& transformation_matrix) const {
    struct Partial {
      typename Derived::System system;
      void merge(const Partial& o) { system.merge(o.system); }
    };
    std::vector<Partial> scratch;
    const Partial total = blockReduce(n, num_threads_, scratch,
                                      [&](std::size_t i, Partial& part) { Derived::addPair(src(i), tgt(i), part.system); });
    transformation_matrix = self().solve(total.system).template cast<Scalar>();
  }

  void sizeError(std::size_t a, std::size_t b, Matrix4& transformation_matrix) const {
    PCL_ERROR("[scanalign::%s::estimateRigidTransformation] source (%zu) and target (%zu) sizes differ\n",
              Derived::kName, a, b);
    self().reset();
    transformation_matrix.setIdentity();
  }
};

}  // namespace scanalign

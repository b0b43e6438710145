// BoxRejector: the box correspondence rejector of the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929, §3.4) as a drop-in
// pcl::registration::CorrespondenceRejector.
//
// The box is given in the source camera frame. A correspondence is rejected when its
// source point lies outside the box. ICP moves the source cloud by its current estimate
// each iteration; the box moves with it, so the test is made on the source point in its
// own camera frame -- which is why the rejector keeps the untransformed source cloud
// (setInputSource) and looks points up by Correspondence::index_query:
//
//   auto box = pcl::make_shared<scanalign::BoxRejector>(scanalign::Box(-0.2, 0.2, -0.2, 0.2, 1e-4, 10));
//   box->setInputSource<pcl::PointNormal>(source);
//   icp.addCorrespondenceRejector(box);
#pragma once

#include <vector>

#include <pcl/point_cloud.h>
#include <pcl/registration/correspondence_rejection.h>

#include "scanalign/registration/box.hpp"

namespace scanalign {

class BoxRejector : public pcl::registration::CorrespondenceRejector {
 public:
  using Ptr = pcl::shared_ptr<BoxRejector>;
  using ConstPtr = pcl::shared_ptr<const BoxRejector>;

  BoxRejector();
  explicit BoxRejector(const Box& box);

  void setBox(const Box& box);
  const Box& getBox() const { return box_; }

  /// The source cloud in its camera frame, untransformed (the cloud given to
  /// Registration::setInputSource). Its x, y, z are copied.
  template <typename PointT>
  void setInputSource(const typename pcl::PointCloud<PointT>::ConstPtr& cloud) {
    source_.clear();
    if (!cloud) return;
    source_.reserve(3 * cloud->size());
    for (const auto& p : cloud->points) {
      source_.push_back(p.x);
      source_.push_back(p.y);
      source_.push_back(p.z);
    }
  }
  bool hasInputSource() const { return !source_.empty(); }

  /// Keeps the correspondences whose source point is inside the box. Throws
  /// std::logic_error if no source cloud was set, std::out_of_range for an index_query
  /// beyond it.
  void getRemainingCorrespondences(const pcl::Correspondences& original_correspondences,
                                   pcl::Correspondences& remaining_correspondences) override;

 protected:
  void applyRejection(pcl::Correspondences& correspondences) override;

 private:
  Box box_;
  std::vector<float> source_;
};

}  // namespace scanalign

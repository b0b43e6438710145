// Compiled PCL plug-ins: BoxRejector and the common PointToPlaneLLS and
// PointToPointDualQuaternion instantiations.
#include "scanalign/registration/pcl/box_rejector.hpp"
#include "scanalign/registration/pcl/dual_quaternion.hpp"
#include "scanalign/registration/pcl/point_to_plane_lls.hpp"

#include <stdexcept>
#include <string>

template class scanalign::PointToPlaneLLS<pcl::PointNormal, pcl::PointNormal, float>;
template class scanalign::PointToPlaneLLS<pcl::PointNormal, pcl::PointNormal, double>;
template class scanalign::PointToPlaneLLS<pcl::PointXYZ, pcl::PointNormal, float>;
template class scanalign::PointToPlaneLLS<pcl::PointXYZ, pcl::PointNormal, double>;
template class scanalign::PointToPlaneLLS<pcl::PointXYZRGBNormal, pcl::PointXYZRGBNormal, float>;
template class scanalign::PointToPointDualQuaternion<pcl::PointXYZ, pcl::PointXYZ, float>;
template class scanalign::PointToPointDualQuaternion<pcl::PointXYZ, pcl::PointXYZ, double>;
template class scanalign::PointToPointDualQuaternion<pcl::PointNormal, pcl::PointNormal, float>;
template class scanalign::PointToPointDualQuaternion<pcl::PointNormal, pcl::PointNormal, double>;

namespace scanalign {

BoxRejector::BoxRejector() { rejection_name_ = "BoxRejector"; }

BoxRejector::BoxRejector(const Box& box) : BoxRejector() { setBox(box); }

void BoxRejector::setBox(const Box& box) {
  if (!box.valid()) throw std::invalid_argument("BoxRejector: box bounds must be finite with min <= max");
  box_ = box;
}

void BoxRejector::getRemainingCorrespondences(const pcl::Correspondences& original,
                                              pcl::Correspondences& remaining) {
  if (source_.empty())
    throw std::logic_error("BoxRejector: call setInputSource(source cloud) before use: the box is tested on the "
                           "untransformed source points");
  const std::size_t n = source_.size() / 3;
  pcl::Correspondences kept;
  kept.reserve(original.size());
  for (const pcl::Correspondence& c : original) {
    if (c.index_query < 0 || static_cast<std::size_t>(c.index_query) >= n)
      throw std::out_of_range("BoxRejector: correspondence index_query " + std::to_string(c.index_query) +
                              " outside the source cloud of " + std::to_string(n) + " points");
    if (box_.contains(&source_[3 * static_cast<std::size_t>(c.index_query)])) kept.push_back(c);
  }
  remaining.swap(kept);  // safe when &original == &remaining
}

void BoxRejector::applyRejection(pcl::Correspondences& correspondences) {
  getRemainingCorrespondences(*input_correspondences_, correspondences);
}

}  // namespace scanalign

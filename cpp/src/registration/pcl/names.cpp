// Names of the stock PCL baselines. PCL-free: the names are part of the API (settings, reports,
// pickles) in every build, with or without PCL.
#include "scanalign/pose/pcl/feature_alignment.hpp"
#include "scanalign/registration/pcl/baselines.hpp"

namespace scanalign {

const char* toString(PclIcpVariant variant) {
  switch (variant) {
    case PclIcpVariant::Svd: return "svd";
    case PclIcpVariant::DualQuaternion: return "dual_quaternion";
    case PclIcpVariant::PointToPlaneLLS: return "point_to_plane_lls";
    case PclIcpVariant::ScanalignPointToPlaneLLS: return "scanalign_point_to_plane_lls";
  }
  return "unknown";
}

const char* toString(PclDescriptor descriptor) {
  switch (descriptor) {
    case PclDescriptor::FPFH: return "fpfh";
    case PclDescriptor::SHOT: return "shot";
    case PclDescriptor::ShapeContext3D: return "3dsc";
    case PclDescriptor::PPF: return "ppf";
    case PclDescriptor::PFH: return "pfh";
    case PclDescriptor::RSD: return "rsd";
    case PclDescriptor::GASD: return "gasd";
    case PclDescriptor::VFH: return "vfh";
  }
  return "unknown";
}

const char* toString(PclMatcher matcher) {
  switch (matcher) {
    case PclMatcher::Prerejective: return "prerejective";
    case PclMatcher::SacIA: return "sac_ia";
  }
  return "unknown";
}

}  // namespace scanalign

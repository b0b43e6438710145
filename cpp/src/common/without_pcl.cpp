// The PCL baselines in a build without PCL (SCANALIGN_WITH_PCL=OFF, or AUTO without PCL
// installed): the same functions, each refusing with NotBuiltError, so every API that names a
// PCL baseline exists in both builds and says what to rebuild instead of failing to link.
#include "scanalign/common/build_info.hpp"
#include "scanalign/pose/pcl/feature_alignment.hpp"
#include "scanalign/registration/pcl/baselines.hpp"

namespace scanalign {

namespace {
[[noreturn]] void notBuilt(const char* what) {
  throw NotBuiltError(what, "PCL (CMake -DSCANALIGN_WITH_PCL=ON, or pip install . -Ccmake.define.SCANALIGN_WITH_PCL=ON)",
                      "Debian/Ubuntu: apt-get install libpcl-dev");
}
}  // namespace

IcpResult pclIcp(const CloudView<float>&, const CloudView<float>&, const CloudView<float>&, const Eigen::Matrix4d&,
                 const IcpSettings&, PclIcpVariant variant) {
  notBuilt((std::string("the stock PCL ICP baseline '") + toString(variant) + "'").c_str());
}

Eigen::Matrix4d pclPointToPlaneLLS(const CloudView<float>&, const CloudView<float>&, const CloudView<float>&, double*) {
  notBuilt("PCL's TransformationEstimationPointToPlaneLLS");
}

Eigen::Matrix4d scanalignPointToPlaneLLS(const CloudView<float>&, const CloudView<float>&, const CloudView<float>&,
                                         PointToPlaneSolve*, double, double*) {
  notBuilt("the PointToPlaneLLS PCL plug-in");
}

std::vector<int> boxRejectorKeep(const CloudView<float>&, const std::vector<int>&, const Box&) {
  notBuilt("the BoxRejector PCL plug-in");
}

PclFeatureAlignmentResult pclFeatureAlignment(const CloudView<float>&, const CloudView<float>&,
                                              const PclFeatureAlignmentSettings& settings) {
  notBuilt((std::string("the stock PCL feature alignment '") + toString(settings.descriptor) + "'").c_str());
}

}  // namespace scanalign

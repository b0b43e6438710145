// pclFeatureAlignment for a program that links scanalign::core alone from a build with PCL
// (compiled into the core of such builds only; a build without PCL has the stub of
// common/without_pcl.cpp). estimatePose refers to it for CoarseMethod::Pcl, so without this a
// core-only program (a CBD pose, examples/cpp/05) would not link. The definition is weak:
// scanalign::pcl's own (feature_alignment.cpp) replaces it, and scanalign::pcl's interface
// link option (-u scanalign_link_pcl_feature_alignment, CMakeLists.txt) makes every program
// that links scanalign::pcl take that one, whatever it calls.
#include <stdexcept>
#include <string>

#include "scanalign/pose/pcl/feature_alignment.hpp"

namespace scanalign {

__attribute__((weak)) PclFeatureAlignmentResult pclFeatureAlignment(const CloudView<float>&, const CloudView<float>&,
                                                                    const PclFeatureAlignmentSettings& settings) {
  throw std::runtime_error(std::string("the stock PCL feature alignment '") + toString(settings.descriptor) +
                           "' is in scanalign::pcl, which this program does not link (link scanalign::pcl: "
                           "find_package(scanalign COMPONENTS pcl))");
}

}  // namespace scanalign

// scanalign._core.pose: the bindings of cpp/include/scanalign/pose/ (Kleppe, PhD thesis, NTNU
// 2018, ch. 6-7), one file per concept (pose.hpp lists them). Settings and results are the C++
// structs, each documented once in its field table (fields.hpp).
#include "pose.hpp"

namespace scanalign::python {

void definePose(py::module_& m) {
  // In dependency order: a struct's nested settings are bound before it.
  bindPoseCbd(m);
  bindPoseAlignment(m);
  bindPoseViews(m);
  bindPosePcl(m);
  bindPoseEstimation(m);
  bindPoseSymmetry(m);
  bindPoseParts(m);
  bindPoseHomography(m);
}

}  // namespace scanalign::python

// Shared by the bindings of the pose area (cpp/python/pose_*.cpp, scanalign._core.pose): the
// functions each file defines, called in order by definePose (pose.cpp), and small helpers.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "fields.hpp"
#include "pickle.hpp"
#include "scanalign/pose/cbd.hpp"
#include "scanalign/pose/pose_estimation.hpp"

namespace scanalign::python {

namespace py = pybind11;

using F64 = py::array_t<double, py::array::c_style | py::array::forcecast>;
using U32 = py::array_t<std::uint32_t, py::array::c_style | py::array::forcecast>;

void bindPoseCbd(py::module_& m);        // pose_cbd.cpp: descriptor, keypoints, matching
void bindPoseAlignment(py::module_& m);  // pose_alignment.cpp: motors, correspondence RANSAC, CBD and flag alignment
void bindPoseViews(py::module_& m);      // pose_views.cpp: tessellated sphere, model views
void bindPosePcl(py::module_& m);        // pose_pcl.cpp: the stock PCL baselines
void bindPoseEstimation(py::module_& m); // pose_estimation.cpp: estimate_pose, find_objects, describe_model_views
void bindPoseSymmetry(py::module_& m);   // pose_symmetry.cpp: PartSymmetry, symmetric_pose_error
void bindPoseParts(py::module_& m);      // pose_parts.cpp: find_parts
void bindPoseHomography(py::module_& m); // pose_homography.cpp: the 2D step of the two-step pose

/// (n,) copy of a vector, as dtype Out.
template <typename Out, typename In>
py::array_t<Out> vec(const std::vector<In>& v) {
  py::array_t<Out> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

/// Field-table accessors of an index vector shown as int64 (what NumPy indexing and the
/// Python code expect), whatever the member's integer type: the getter, and the checked setter.
template <typename T, typename I>
auto int64Getter(std::vector<I> T::*member) {
  return [member](const T& t) { return std::vector<std::int64_t>((t.*member).begin(), (t.*member).end()); };
}
template <typename T, typename I>
auto int64Setter(std::vector<I> T::*member) {
  return [member](T& t, const std::vector<std::int64_t>& v) {
    for (std::int64_t x : v)
      if (x < static_cast<std::int64_t>(std::numeric_limits<I>::lowest()) ||
          x > static_cast<std::int64_t>(std::numeric_limits<I>::max()))
        throw py::value_error("index " + std::to_string(x) + " out of range of the member's integer type");
    (t.*member).assign(v.begin(), v.end());
  };
}

/// Field-table accessors of an index stored as int with -1 for none, shown as None.
template <typename T>
auto optionalIndexGetter(int T::*member) {
  return [member](const T& t) { return t.*member < 0 ? std::optional<int>() : std::optional<int>(t.*member); };
}
template <typename T>
auto optionalIndexSetter(int T::*member) {
  return [member](T& t, const std::optional<int>& v) {
    if (v && *v < 0) throw py::value_error("an index must be >= 0 (None: none)");
    t.*member = v ? *v : -1;
  };
}

/// Replaces the pickling a field table gave `cls` by a hand-written state (ModelView and
/// CbdFeatures: the part library's flat npz layout).
template <typename T, typename Get, typename Set>
void replacePickle(py::class_<T>& cls, Get get, Set set) {
  py::delattr(cls, "__getstate__");
  py::delattr(cls, "__setstate__");
  cls.def(py::pickle(get, set));
}

/// CbdSettings and CbdFeatures as flat fields (arrays and scalars; pose_cbd.cpp), which
/// ModelView's state (pose_views.cpp) holds under the prefixes cbd_settings/ and cbd/.
std::vector<PickleField<CbdSettings>> cbdSettingsFields();
std::vector<PickleField<CbdFeatures>> cbdFeatureFields();
/// ValueError unless every per-keypoint array of `f` has one entry per keypoint.
void checkCbdFeatures(const CbdFeatures& f, const std::string& cls);

/// A progress callback (done, total) from Python (None: none), called with the GIL taken.
PoseProgress progressOf(const py::object& callback);

}  // namespace scanalign::python

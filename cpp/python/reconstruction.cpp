// scanalign._core.reconstruction: depth images (reconstruction_depth.cpp), the frame-to-model
// pipeline (reconstruction_frame_to_model.cpp) and the voxel grid (here).
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <string>

#include "arrays.hpp"
#include "scanalign/reconstruction/voxel_grid.hpp"

namespace scanalign::python {

namespace {

/// NotRealError: values that are not real numbers (strings, complex) where real ones belong.
/// A TypeError, and also a ValueError, which voxel_grid raised for them before: callers
/// catching that keep working (as NumPy's AxisError is both a ValueError and an IndexError).
py::handle notRealError() {
  static py::handle cls = PyErr_NewExceptionWithDoc(
      "scanalign._core.reconstruction.NotRealError",
      "Values that are not real numbers (strings, complex) where real ones belong: a TypeError (and a ValueError)",
      py::make_tuple(py::handle(PyExc_TypeError), py::handle(PyExc_ValueError)).release().ptr(), nullptr);
  return cls;
}

template <typename Scalar>
py::tuple voxel(const CloudView<Scalar>& view, double leaf_size, const py::object& attributes,
                const py::object& min_points_arg) {
  const auto min_points = intArg(min_points_arg, "min_points_per_voxel", 1, 0xFFFFFFFFLL);
  py::array_t<double, py::array::c_style> attrs;
  std::size_t dim = 0;
  if (!attributes.is_none()) {
    // Real numbers only: a string or complex array must not be parsed or lose its
    // imaginary part on the way to float64.
    const py::array given = py::array::ensure(attributes);
    if (!given || std::string("biuf").find(given.dtype().kind()) == std::string::npos) {
      const std::string message = "attributes: expected real numbers (bool, integer or float), got " +
                                  (given ? "dtype " + std::string(py::str(given.dtype())) : std::string("a non-array"));
      PyErr_SetString(notRealError().ptr(), message.c_str());
      throw py::error_already_set();
    }
    attrs = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(given);
    if (!attrs || attrs.ndim() != 2 || static_cast<std::size_t>(attrs.shape(0)) != view.size)
      throw py::value_error("attributes: expected an (N, k) array with one row per point");
    dim = static_cast<std::size_t>(attrs.shape(1));
  }
  VoxelGridResult r;
  {
    py::gil_scoped_release release;
    r = voxelGrid(view, leaf_size, dim ? attrs.data() : nullptr, dim, static_cast<std::uint32_t>(min_points));
  }
  const auto m = static_cast<py::ssize_t>(r.size());
  py::array_t<Scalar> pts({m, py::ssize_t{3}});
  std::copy(r.points.begin(), r.points.end(), pts.mutable_data());
  py::array_t<double> att({m, static_cast<py::ssize_t>(dim)});
  std::copy(r.attributes.begin(), r.attributes.end(), att.mutable_data());
  py::array_t<std::uint32_t> counts(m);
  std::copy(r.counts.begin(), r.counts.end(), counts.mutable_data());
  return py::make_tuple(pts, att, counts);
}

}  // namespace

void defineReconstructionDepth(py::module_& m);
void defineReconstructionFrameToModel(py::module_& m);

void defineReconstruction(py::module_& m) {
  m.attr("NotRealError") = notRealError();
  defineReconstructionDepth(m);
  defineReconstructionFrameToModel(m);
  m.def(
      "voxel_grid",
      [](const py::array& points, double leaf_size, const py::object& attributes,
         const py::object& min_points_per_voxel) {
        if (holds<float>(points))
          return voxel(cloudView<float>(points, "points"), leaf_size, attributes, min_points_per_voxel);
        return voxel(cloudView<double>(points, "points"), leaf_size, attributes, min_points_per_voxel);
      },
      py::arg("points"), py::arg("leaf_size"), py::arg("attributes"), py::arg("min_points_per_voxel"),
      "(centroids (M, 3) in the points' dtype, m; attribute means (M, k) float64; counts (M,)): pcl::VoxelGrid "
      "voxel for voxel. ValueError for a leaf that is not finite and positive or gives over 2^21 voxels along an "
      "axis; TypeError for attributes that are not real numbers (strings, complex)");
}

}  // namespace scanalign::python

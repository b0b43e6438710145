// _core.features: normal estimation (the eye-in-hand paper (Comput. Electron. Agric. 180
// (2021) 105929), §3.5) and PCA shape factors (Kleppe, PhD thesis, NTNU 2018, (6.1)-(6.3)).
#include <pybind11/eigen.h>

#include <cmath>

#include "arrays.hpp"
#include "fields.hpp"
#include "scanalign/features/normals.hpp"
#include "scanalign/features/shape_factors.hpp"

namespace scanalign::python {

namespace {
using F64 = py::array_t<double, py::array::c_style | py::array::forcecast>;

template <typename Scalar>
py::tuple normals(const CloudView<Scalar>& view, const NormalEstimationSettings& s) {
  py::array_t<Scalar> out({static_cast<py::ssize_t>(view.size), py::ssize_t{3}});
  py::array_t<Scalar> curvature(static_cast<py::ssize_t>(view.size));
  {
    py::gil_scoped_release release;
    estimateNormals(view, s, out.mutable_data(), curvature.mutable_data());
  }
  return py::make_tuple(out, curvature);
}

py::tuple estimate(const py::array& points, const NormalEstimationSettings& s) {
  if (holds<float>(points)) return normals(cloudView<float>(points, "points"), s);
  return normals(cloudView<double>(points, "points"), s);
}
}  // namespace

void defineFeatures(py::module_& m) {
  using N = NormalEstimationSettings;
  fieldsOf(py::class_<N>(m, "NormalEstimationSettings",
                         "PCA normals over a radius neighbourhood, oriented towards a viewpoint (the eye-in-hand "
                         "paper, §3.5, after Rusu 2009). validate() raises ValueError naming a bad field."))
      .field("radius", &N::radius, "m", "neighbourhood radius (eye-in-hand paper §3.5: 5 mm)")
      .field("viewpoint", &N::viewpoint, "m",
             "(3,) normals are flipped to point towards it, in the cloud's frame (the camera centre for a "
             "camera-frame cloud), as pcl::flipNormalTowardsViewpoint")
      .field("min_neighbors", &N::min_neighbors, "", "fewer neighbours (the point included) give a NaN normal; >= 3")
      .field("num_threads", &N::num_threads, "", "OpenMP threads, 0 = all cores")
      .field("grid_subdivisions", &N::grid_subdivisions, "",
             "cells per radius of the grid neighbourhood search, in [1, 16]; 0 = chosen from the cloud's density. "
             "Only the speed depends on it")
      .settings()
      .def("validate", [](const N& s) { validate(s); });
  // The field-by-field overload first: a bad argument is named after its signature.
  m.def(
      "estimate_normals",
      [](const py::array& points, double radius, const F64& viewpoint, int min_neighbors, int num_threads) {
        if (viewpoint.size() != 3) throw py::value_error("viewpoint: expected 3 finite coordinates, metres");
        NormalEstimationSettings s;
        s.radius = radius;
        s.viewpoint = Eigen::Vector3d(viewpoint.data()[0], viewpoint.data()[1], viewpoint.data()[2]);
        s.min_neighbors = min_neighbors;
        s.num_threads = num_threads;
        return estimate(points, s);
      },
      py::arg("points"), py::arg("radius"), py::arg("viewpoint"), py::arg("min_neighbors"), py::arg("num_threads"),
      "(normals (N, 3), curvature (N,)) in the points' dtype: NormalEstimationSettings' radius (m), viewpoint (m), "
      "min_neighbors and num_threads given one by one; ValueError names a bad one");
  m.def("estimate_normals", &estimate, py::arg("points"), py::arg("settings"),
        "The same with a NormalEstimationSettings; ValueError names a bad field");
  m.def(
      "shape_factors",
      [](const F64& ev) {
        if (!((ev.ndim() == 1 && ev.shape(0) == 3) || (ev.ndim() == 2 && ev.shape(1) == 3)))
          throw py::value_error("eigenvalues: expected shape (3,) or (N, 3)");
        py::array_t<double> out(std::vector<py::ssize_t>(ev.shape(), ev.shape() + ev.ndim()));
        for (py::ssize_t i = 0; i < ev.size() / 3; ++i) {
          const ShapeFactors c = shapeFactors(ev.data()[3 * i], ev.data()[3 * i + 1], ev.data()[3 * i + 2]);
          out.mutable_data()[3 * i] = c.linear;
          out.mutable_data()[3 * i + 1] = c.planar;
          out.mutable_data()[3 * i + 2] = c.spherical;
        }
        return out;
      },
      py::arg("eigenvalues"),
      "Shape factors (C_l, C_p, C_s), same shape as the (3,) or (N, 3) covariance eigenvalues in any order (thesis "
      "(6.1)-(6.3)); ValueError for NaN/Inf, negative values or a zero sum");
}

}  // namespace scanalign::python

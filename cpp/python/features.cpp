#include <pybind11/eigen.h>

#include "arrays.hpp"
#include "scanalign/features/normals.hpp"
#include "scanalign/features/shape_factors.hpp"

namespace scanalign::python {

namespace {
template <typename Scalar>
py::tuple normals(const py::array& points, double radius, const Eigen::Vector3d& viewpoint, int min_neighbors,
                  int num_threads) {
  const CloudView<Scalar> view = cloudView<Scalar>(points, "points");
  NormalEstimationSettings s;
  s.radius = radius;
  s.viewpoint = viewpoint;
  s.min_neighbors = min_neighbors;
  s.num_threads = num_threads;
  py::array_t<Scalar> out({static_cast<py::ssize_t>(view.size), py::ssize_t{3}});
  py::array_t<Scalar> curvature(static_cast<py::ssize_t>(view.size));
  {
    py::gil_scoped_release release;
    estimateNormals(view, s, out.mutable_data(), curvature.mutable_data());
  }
  return py::make_tuple(out, curvature);
}
}  // namespace

void defineFeatures(py::module_& m) {
  m.def("estimate_normals_f32", &normals<float>, py::arg("points"), py::arg("radius"), py::arg("viewpoint"),
        py::arg("min_neighbors"), py::arg("num_threads"));
  m.def("estimate_normals_f64", &normals<double>, py::arg("points"), py::arg("radius"), py::arg("viewpoint"),
        py::arg("min_neighbors"), py::arg("num_threads"));
  m.def(
      "shape_factors",
      [](const py::array_t<double, py::array::c_style | py::array::forcecast>& ev) {
        if (ev.ndim() != 2 || ev.shape(1) != 3) throw py::value_error("eigenvalues: expected shape (3,) or (N, 3)");
        py::array_t<double> out({ev.shape(0), py::ssize_t{3}});
        for (py::ssize_t i = 0; i < ev.shape(0); ++i) {
          const features::ShapeFactors c = features::shapeFactors(ev.data()[3 * i], ev.data()[3 * i + 1], ev.data()[3 * i + 2]);
          out.mutable_data()[3 * i] = c.linear;
          out.mutable_data()[3 * i + 1] = c.planar;
          out.mutable_data()[3 * i + 2] = c.spherical;
        }
        return out;
      },
      py::arg("eigenvalues"),
      "(N, 3) shape factors (C_l, C_p, C_s) of (N, 3) covariance eigenvalues in any order (thesis (6.1)-(6.3)); "
      "ValueError for NaN/Inf, negative values or a zero sum");
}

}  // namespace scanalign::python

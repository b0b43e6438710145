#include <pybind11/eigen.h>

#include "arrays.hpp"
#include "scanalign/features/normals.hpp"

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
}

}  // namespace scanalign::python

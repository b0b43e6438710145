// Bindings of scanalign/fitting/sphere_fit.hpp. Input validation with clear messages happens
// first in python/scanalign/fitting.py; the checks here are the last line of defence.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <stdexcept>

#include "arrays.hpp"
#include "scanalign/fitting/sphere_fit.hpp"

namespace scanalign::python {

namespace {

py::dict toDict(const SphereFit& f) {
  py::dict d;
  d["dual"] = Eigen::VectorXd(f.dual);
  d["is_plane"] = f.is_plane;
  d["center"] = Eigen::Vector3d(f.center);
  d["radius"] = f.radius;
  d["imaginary"] = f.imaginary;
  d["normal"] = Eigen::Vector3d(f.normal);
  d["distance"] = f.distance;
  d["rms"] = f.rms;
  d["objective"] = f.objective;
  d["count"] = f.count;
  return d;
}

template <typename Scalar>
py::dict fitSpherePy(const py::array& points, const py::object& weights, double plane_tolerance) {
  const CloudView<Scalar> view = cloudView<Scalar>(points, "points");
  SphereFitOptions o;
  o.plane_tolerance = plane_tolerance;
  py::array_t<double, py::array::c_style | py::array::forcecast> w;
  const double* wp = nullptr;
  if (!weights.is_none()) {
    w = py::cast<py::array_t<double, py::array::c_style | py::array::forcecast>>(weights);
    if (w.ndim() != 1 || static_cast<std::size_t>(w.shape(0)) != view.size)
      throw py::value_error("weights: expected shape (N,) matching points");
    wp = w.data();
  }
  SphereFit f;
  {
    py::gil_scoped_release release;
    f = fitSphere(view, wp, o);
  }
  return toDict(f);
}

// Batched fits: returns arrays (G,5) dual, (G,3) center, (G,) radius, (G,) is_plane,
// (G,3) normal, (G,) distance, (G,) rms, (G,) count.
template <typename Scalar>
py::dict fitSpheresPy(const py::array& points, const py::array_t<std::int64_t, py::array::c_style>& offsets,
                      double plane_tolerance, int num_threads) {
  const CloudView<Scalar> view = cloudView<Scalar>(points, "points");
  if (offsets.ndim() != 1 || offsets.shape(0) < 1) throw py::value_error("offsets: expected shape (G + 1,)");
  SphereFitOptions o;
  o.plane_tolerance = plane_tolerance;
  const std::size_t g = static_cast<std::size_t>(offsets.shape(0) - 1);
  std::vector<SphereFit> fits;
  {
    py::gil_scoped_release release;
    fits = fitSpheres(view, offsets.data(), g, o, num_threads);
  }
  const auto G = static_cast<py::ssize_t>(g);
  py::array_t<double> dual({G, py::ssize_t{5}}), center({G, py::ssize_t{3}}), normal({G, py::ssize_t{3}});
  py::array_t<double> radius(G), distance(G), rms(G);
  py::array_t<bool> is_plane(G), imaginary(G);
  py::array_t<std::int64_t> count(G);
  auto du = dual.mutable_unchecked<2>();
  auto ce = center.mutable_unchecked<2>();
  auto no = normal.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < G; ++i) {
    const SphereFit& f = fits[static_cast<std::size_t>(i)];
    for (int k = 0; k < 5; ++k) du(i, k) = f.dual(k);
    for (int k = 0; k < 3; ++k) ce(i, k) = f.center(k), no(i, k) = f.normal(k);
    radius.mutable_data()[i] = f.radius;
    distance.mutable_data()[i] = f.distance;
    rms.mutable_data()[i] = f.rms;
    is_plane.mutable_data()[i] = f.is_plane;
    imaginary.mutable_data()[i] = f.imaginary;
    count.mutable_data()[i] = static_cast<std::int64_t>(f.count);
  }
  py::dict d;
  d["dual"] = dual, d["center"] = center, d["radius"] = radius, d["is_plane"] = is_plane;
  d["imaginary"] = imaginary, d["normal"] = normal, d["distance"] = distance, d["rms"] = rms, d["count"] = count;
  return d;
}

py::dict fitCirclePy(const py::array_t<double, py::array::c_style | py::array::forcecast>& xy) {
  if (xy.ndim() != 2 || xy.shape(1) != 2) throw py::value_error("points: expected an (N, 2) array");
  CircleFit f;
  {
    py::gil_scoped_release release;
    f = fitCirclePratt(xy.data(), static_cast<std::size_t>(xy.shape(0)));
  }
  py::dict d;
  d["center"] = Eigen::Vector2d(f.center);
  d["radius"] = f.radius;
  d["rms"] = f.rms;
  d["coefficients"] = Eigen::Vector4d(f.coefficients);
  d["count"] = f.count;
  return d;
}

}  // namespace

void defineFitting(py::module_& m) {
  // std::invalid_argument is translated to ValueError by pybind11.
  m.def("fit_sphere_f32", &fitSpherePy<float>, py::arg("points"), py::arg("weights"), py::arg("plane_tolerance"));
  m.def("fit_sphere_f64", &fitSpherePy<double>, py::arg("points"), py::arg("weights"), py::arg("plane_tolerance"));
  m.def("fit_spheres_f32", &fitSpheresPy<float>, py::arg("points"), py::arg("offsets"), py::arg("plane_tolerance"),
        py::arg("num_threads"));
  m.def("fit_spheres_f64", &fitSpheresPy<double>, py::arg("points"), py::arg("offsets"), py::arg("plane_tolerance"),
        py::arg("num_threads"));
  m.def("fit_circle_pratt", &fitCirclePy, py::arg("points"));
}

}  // namespace scanalign::python

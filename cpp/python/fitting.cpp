// Bindings of scanalign/fitting/sphere_fit.hpp: the result structs are bound directly (their
// Python docs are written here, once); python/scanalign/fitting.py only converts inputs.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <stdexcept>
#include <string>

#include "arrays.hpp"
#include "scanalign/fitting/sphere_fit.hpp"

namespace scanalign::python {

namespace {

template <typename Scalar>
SphereFit fitSpherePy(const py::array& points, const py::object& weights, double plane_tolerance) {
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
  return f;
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

CircleFit fitCirclePy(const py::array_t<double, py::array::c_style | py::array::forcecast>& xy) {
  if (xy.ndim() != 2 || xy.shape(1) != 2) throw py::value_error("points: expected an (N, 2) array");
  py::gil_scoped_release release;
  return fitCirclePratt(xy.data(), static_cast<std::size_t>(xy.shape(0)));
}

}  // namespace

void defineFitting(py::module_& m) {
  // Results are read-only; array fields come back as new numpy arrays.
  py::class_<SphereFit>(m, "SphereFitResult",
                        "Result of fit_sphere: a sphere, or the plane normal . p = distance when the data is "
                        "(nearly) flat (thesis 5.26-5.34). Metres.")
      .def_property_readonly(
          "center", [](const SphereFit& f) { return Eigen::Vector3d(f.center); }, "(3,) sphere centre, m (NaN for a plane)")
      .def_readonly("radius", &SphereFit::radius, "sphere radius, m (NaN for a plane; |r| when imaginary)")
      .def_readonly("is_plane", &SphereFit::is_plane,
                    "the fitted e0 coefficient vanished relative to scale: the data is flat and the result is "
                    "the plane normal . p = distance")
      .def_property_readonly(
          "normal", [](const SphereFit& f) { return Eigen::Vector3d(f.normal); },
          "(3,) unit plane normal (NaN for a sphere), oriented so that distance >= 0")
      .def_readonly("distance", &SphereFit::distance, "plane offset from the origin along normal, m (NaN for a sphere)")
      .def_readonly("imaginary", &SphereFit::imaginary, "the fitted sphere has r^2 < 0 (not expected for real data)")
      .def_readonly("rms", &SphereFit::rms,
                    "(weighted) RMS geometric residual, m: | |p - c| - r | for a sphere, |normal . p - distance| "
                    "for a plane")
      .def_readonly("objective", &SphereFit::objective,
                    "the weighted mean of (S.P)^2 / S^2 at the optimum (thesis 5.27), the chosen eigenvalue "
                    "(5.31), m^2")
      .def_readonly("count", &SphereFit::count, "points used (those with positive weight)")
      .def_property_readonly(
          "dual", [](const SphereFit& f) { return Eigen::Matrix<double, 5, 1>(f.dual); },
          "(5,) the dual sphere [c, (|c|^2 - r^2)/2, 1] (4.60) or plane [n, distance, 0] (4.66) on "
          "(e1, e2, e3, e_inf, e0)")
      .def("__repr__", [](const SphereFit& f) {
        return f.is_plane ? "SphereFitResult(plane, normal=(" + std::to_string(f.normal.x()) + ", " +
                                std::to_string(f.normal.y()) + ", " + std::to_string(f.normal.z()) +
                                "), distance=" + std::to_string(f.distance) + ", rms=" + std::to_string(f.rms) + ")"
                          : "SphereFitResult(center=(" + std::to_string(f.center.x()) + ", " +
                                std::to_string(f.center.y()) + ", " + std::to_string(f.center.z()) +
                                "), radius=" + std::to_string(f.radius) + ", rms=" + std::to_string(f.rms) + ")";
      });
  py::class_<CircleFit>(m, "CircleFitResult", "Result of fit_circle_2d (Pratt 1987; thesis 5.21-5.25). Metres.")
      .def_property_readonly(
          "center", [](const CircleFit& f) { return Eigen::Vector2d(f.center); }, "(2,) circle centre, m")
      .def_readonly("radius", &CircleFit::radius, "circle radius, m")
      .def_readonly("rms", &CircleFit::rms, "RMS geometric residual | |p - c| - r |, m")
      .def_property_readonly(
          "coefficients", [](const CircleFit& f) { return Eigen::Vector4d(f.coefficients); },
          "(4,) (a, d, e, f) of a(x^2 + y^2) + d x + e y + f = 0 with Pratt's normalization "
          "d^2 + e^2 - 4 a f = 1 (thesis 5.21)")
      .def_readonly("count", &CircleFit::count, "number of points")
      .def("__repr__", [](const CircleFit& f) {
        return "CircleFitResult(center=(" + std::to_string(f.center.x()) + ", " + std::to_string(f.center.y()) +
               "), radius=" + std::to_string(f.radius) + ", rms=" + std::to_string(f.rms) + ")";
      });
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

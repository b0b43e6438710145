// Bindings of scanalign/fitting/sphere_fit.hpp: the fits take NumPy input directly and the
// result structs are bound as they are, their Python docs written here once.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <cmath>
#include <string>
#include <type_traits>

#include "arrays.hpp"
#include "fields.hpp"
#include "scanalign/fitting/sphere_fit.hpp"

namespace scanalign::python {

namespace {


/// One column of a batch: (G,) or (G, K) of `get(fit)`, as an Eigen array (the field table
/// shows it as a NumPy array of T).
template <typename T, int K = 1, typename Get>
auto column(const SphereFitBatchResult& b, Get get) {
  using Out = std::conditional_t<K == 1, Eigen::Matrix<T, Eigen::Dynamic, 1>,
                                 Eigen::Matrix<T, Eigen::Dynamic, K, Eigen::RowMajor>>;
  Out out(static_cast<Eigen::Index>(b.fits.size()), K);
  for (std::size_t g = 0; g < b.fits.size(); ++g) {
    if constexpr (K == 1) {
      out(static_cast<Eigen::Index>(g)) = static_cast<T>(get(b.fits[g]));
    } else {
      const auto v = get(b.fits[g]);
      for (int k = 0; k < K; ++k) out(static_cast<Eigen::Index>(g), k) = v(k);
    }
  }
  return out;
}

}  // namespace

void defineFitting(py::module_& m) {
  // Results are read-only; array fields come back as new numpy arrays.
  using S = SphereFitResult;
  fieldsOf(py::class_<S>(m, "SphereFitResult",
                         "Result of fit_sphere: a sphere, or the plane normal . p = distance when the data is "
                         "(nearly) flat (thesis 5.26-5.34). Metres.")
               .def("__repr__", [](const S& f) {
                 return f.is_plane ? "SphereFitResult(plane, normal=(" + std::to_string(f.normal.x()) + ", " +
                                         std::to_string(f.normal.y()) + ", " + std::to_string(f.normal.z()) +
                                         "), distance=" + std::to_string(f.distance) + ", rms=" + std::to_string(f.rms) +
                                         ")"
                                   : "SphereFitResult(center=(" + std::to_string(f.center.x()) + ", " +
                                         std::to_string(f.center.y()) + ", " + std::to_string(f.center.z()) +
                                         "), radius=" + std::to_string(f.radius) + ", rms=" + std::to_string(f.rms) + ")";
               }))
      .output("center", &S::center, "m", "(3,) sphere centre (NaN for a plane)")
      .output("radius", &S::radius, "m", "sphere radius (NaN for a plane; |r| when imaginary)")
      .output("is_plane", &S::is_plane, "",
              "the fitted e0 coefficient vanished relative to scale: the data is flat and the result is the plane "
              "normal . p = distance")
      .output("normal", &S::normal, "", "(3,) unit plane normal (NaN for a sphere), oriented so that distance >= 0")
      .output("distance", &S::distance, "m", "plane offset from the origin along normal (NaN for a sphere)")
      .output("imaginary", &S::imaginary, "", "the fitted sphere has r^2 < 0 (not expected for real data)")
      .output("rms", &S::rms, "m",
              "(weighted) RMS geometric residual: | |p - c| - r | for a sphere, |normal . p - distance| for a plane")
      .output("objective", &S::objective, "m^2",
              "the weighted mean of (S.P)^2 / S^2 at the optimum (thesis 5.27), the chosen eigenvalue (5.31)")
      .output("count", &S::count, "", "points used (those with positive weight)")
      .output("dual", &S::dual, "",
              "(5,) the dual sphere [c, (|c|^2 - r^2)/2, 1] (4.60) or plane [n, distance, 0] (4.66) on "
              "(e1, e2, e3, e_inf, e0)")
      .result();
  using C = CircleFitResult;
  fieldsOf(py::class_<C>(m, "CircleFitResult", "Result of fit_circle_2d (Pratt 1987; thesis 5.21-5.25). Metres.")
               .def("__repr__", [](const C& f) {
                 return "CircleFitResult(center=(" + std::to_string(f.center.x()) + ", " + std::to_string(f.center.y()) +
                        "), radius=" + std::to_string(f.radius) + ", rms=" + std::to_string(f.rms) + ")";
               }))
      .output("center", &C::center, "m", "(2,) circle centre")
      .output("radius", &C::radius, "m", "circle radius")
      .output("rms", &C::rms, "m", "RMS geometric residual | |p - c| - r |")
      .output("coefficients", &C::coefficients, "",
              "(4,) (a, d, e, f) of a(x^2 + y^2) + d x + e y + f = 0 with Pratt's normalization d^2 + e^2 - 4 a f = 1 "
              "(thesis 5.21)")
      .output("count", &C::count, "", "number of points")
      .result();
  using B = SphereFitBatchResult;
  fieldsOf(py::class_<B>(m, "SphereFitBatchResult",
                         "Result of fit_spheres: the fields of SphereFitResult as arrays with one row per group; a "
                         "group that cannot be fitted has count 0 and NaN values. Metres.")
               .def("__len__", &B::size)
               .def(
                   "__getitem__",
                   [](const B& b, py::ssize_t g) {
                     const auto n = static_cast<py::ssize_t>(b.fits.size());
                     if (g < -n || g >= n) throw py::index_error("group " + std::to_string(g) + " out of range");
                     return b.fits[static_cast<std::size_t>(g < 0 ? g + n : g)];
                   },
                   py::arg("group"), "the SphereFitResult of one group"))
      .output("fits", &B::fits, "", "the SphereFitResult of every group, in order")
      .derived("center", [](const B& b) { return column<double, 3>(b, [](auto& f) { return f.center; }); }, "m",
               "(G, 3) sphere centres (NaN rows for planes)")
      .derived("radius", [](const B& b) { return column<double>(b, [](auto& f) { return f.radius; }); }, "m",
               "(G,) radii")
      .derived("is_plane", [](const B& b) { return column<bool>(b, [](auto& f) { return f.is_plane; }); }, "",
               "(G,) the group is flat: normal . p = distance")
      .derived("normal", [](const B& b) { return column<double, 3>(b, [](auto& f) { return f.normal; }); }, "",
               "(G, 3) unit plane normals (NaN rows for spheres)")
      .derived("distance", [](const B& b) { return column<double>(b, [](auto& f) { return f.distance; }); }, "m",
               "(G,) plane offsets along normal")
      .derived("imaginary", [](const B& b) { return column<bool>(b, [](auto& f) { return f.imaginary; }); }, "",
               "(G,) r^2 < 0")
      .derived("rms", [](const B& b) { return column<double>(b, [](auto& f) { return f.rms; }); }, "m",
               "(G,) RMS geometric residuals")
      .derived("count", [](const B& b) { return column<std::int64_t>(b, [](auto& f) { return f.count; }); }, "",
               "(G,) points used (0: the group could not be fitted)")
      .derived("dual", [](const B& b) { return column<double, 5>(b, [](auto& f) { return f.dual; }); }, "",
               "(G, 5) dual spheres / planes on (e1, e2, e3, e_inf, e0), as SphereFitResult.dual")
      .result();

  m.attr("MIN_SPHERE_POINTS") = kMinSpherePoints;
  // std::invalid_argument reaches Python as ValueError (pybind11 default).
  m.def(
      "fit_sphere",
      [](const py::object& points, const py::object& weights, double plane_tolerance) {
        return withCloud(points, "points", [&](auto view) {
          py::array_t<double, py::array::c_style | py::array::forcecast> w;
          if (!weights.is_none()) {
            w = checkedAs<double>(weights, "weights", kReals | kBools);
            if (w.ndim() != 1 || static_cast<std::size_t>(w.shape(0)) != view.size)
              throw py::value_error("weights: expected shape (" + std::to_string(view.size) + ",)");
          }
          SphereFitOptions o;
          o.plane_tolerance = plane_tolerance;
          py::gil_scoped_release release;
          return fitSphere(view, weights.is_none() ? nullptr : w.data(), o);
        });
      },
      py::arg("points"), py::arg("weights") = py::none(), py::kw_only(), py::arg("plane_tolerance") = 1e-6,
      R"(Fits a sphere (or a plane) to 3-D points with the CGA sphere fit (Kleppe, PhD thesis, NTNU 2018).

Minimises sum_i w_i (S.P_i)^2 / S^2 / sum_i w_i over dual spheres S (5.27; per point
(S.P)^2/S^2 ~ delta^2, delta the geometric distance), solved as the eigenvector of the
smallest positive eigenvalue of Q = sum_i w_i [P_i][P_i]^T M / sum_i w_i (5.31, 6.6) in a
numerically stable symmetric form. Exact points give the exact sphere; exactly coplanar
points give a plane.

Args:
    points: (N, 3) float32/float64 points, metres.
    weights: optional (N,) non-negative finite weights. A point with weight 0 is removed
        (it may even be NaN); integer weights act as duplicated points; only ratios matter.
    plane_tolerance: return a plane when the fitted radius exceeds about
        1 / plane_tolerance times the extent of the data (finite, >= 0).

Returns:
    SphereFitResult.

Raises:
    TypeError: points not a float array, or weights not a real array.
    ValueError: wrong shapes; non-finite points (with positive weight); negative or
        non-finite weights; all weights zero; fewer than MIN_SPHERE_POINTS (5) points with
        positive weight; degenerate data (coincident or collinear points, points on one
        circle).)");
  m.def(
      "fit_spheres",
      [](const py::object& points, const py::object& offsets, double plane_tolerance, int num_threads) {
        const auto o = checkedAs<std::int64_t>(offsets, "offsets", kIntegers);
        if (o.ndim() != 1 || o.shape(0) < 1) throw py::value_error("offsets: expected shape (G + 1,)");
        // Checked here: fitSpheres turns each group's error into a NaN group, which would
        // hide a bad argument behind G "unfittable" groups.
        if (!(plane_tolerance >= 0.0) || !std::isfinite(plane_tolerance))
          throw py::value_error("plane_tolerance must be finite and >= 0");
        return withCloud(points, "points", [&](auto view) {
          SphereFitOptions opt;
          opt.plane_tolerance = plane_tolerance;
          py::gil_scoped_release release;
          return fitSpheres(view, o.data(), static_cast<std::size_t>(o.shape(0) - 1), opt, num_threads);
        });
      },
      py::arg("points"), py::arg("offsets"), py::kw_only(), py::arg("plane_tolerance") = 1e-6,
      py::arg("num_threads") = 0,
      R"(Many unweighted fit_sphere fits in one call (parallel, OpenMP).

Args:
    points: (N, 3) float32/float64 points, metres; group g is points[offsets[g]:offsets[g + 1]].
    offsets: (G + 1,) non-decreasing integer offsets into points (>= 0, <= N).
    plane_tolerance: as in fit_sphere.
    num_threads: OpenMP threads, 0 = all cores.

Returns:
    SphereFitBatchResult; groups that cannot be fitted get count == 0 and NaNs.

Raises:
    TypeError: points not float, offsets not integer. ValueError: shapes, offsets out of order
    or range, plane_tolerance.)");
  m.def(
      "fit_circle_2d",
      [](const py::object& points) {
        const auto xy = checkedAs<double>(points, "points");
        if (xy.ndim() != 2 || xy.shape(1) != 2) throw py::value_error("points: expected an (N, 2) array");
        py::gil_scoped_release release;
        return fitCirclePratt(xy.data(), static_cast<std::size_t>(xy.shape(0)));
      },
      py::arg("points"),
      R"(Pratt's algebraic circle fit of 2-D points (Kleppe, PhD thesis, NTNU 2018, (5.21)-(5.25)).

Minimises sum g(p_i)^2 / (d^2 + e^2 - 4af) for the circle g(p) = a|p|^2 + d x + e y + f = 0
(the Sampson approximation of the geometric distance, 5.9), as the eigenvector of the
smallest positive eigenvalue of Mc = lambda Nc.

Args:
    points: (N, 2) float points, metres; N >= 3.

Returns:
    CircleFitResult.

Raises:
    TypeError: not a float array. ValueError: wrong shape, fewer than 3 points, non-finite
    values, collinear or coincident points.)");
}

}  // namespace scanalign::python

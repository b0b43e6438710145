// Bindings of the CGA core G(4,1) (scanalign/cga/*.hpp; Kleppe, PhD thesis, NTNU 2018, ch. 4), exported as they are by
// python/scanalign/cga.py (whose docstring describes the conventions). std::invalid_argument and std::domain_error
// reach Python as ValueError (pybind11 defaults).
#include <cmath>
#include <sstream>
#include <type_traits>
#include <utility>
#include <vector>

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/operators.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "fields.hpp"
#include "scanalign/cga/multivector.hpp"
#include "scanalign/cga/objects.hpp"

namespace py = pybind11;

namespace scanalign::python::cga_args {
/// A Python argument that holds 3 coordinates, converted by coords3() with the argument's name
/// (pybind11's Eigen caster would drop a complex array's imaginary part with only a warning,
/// and a failed conversion answers with a signature dump that names no argument).
struct Coords {
  py::object o;
};
}  // namespace scanalign::python::cga_args

namespace pybind11::detail {
template <>
struct type_caster<scanalign::python::cga_args::Coords> {
  PYBIND11_TYPE_CASTER(scanalign::python::cga_args::Coords,
                       const_name("typing.Annotated[numpy.typing.ArrayLike, numpy.float64, \"[3, 1]\"]"));
  bool load(handle src, bool) {
    value.o = reinterpret_borrow<object>(src);
    return true;
  }
};
}  // namespace pybind11::detail

namespace scanalign::python {

namespace {
using cga::Multivector;
using Coeffs = Multivector::Coeffs;
using RowArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

std::string fmt(double v) {
  if (v == 0) v = 0.0;  // no "-0"
  std::ostringstream s;
  s.precision(6);
  s << v;
  return s.str();
}
std::string fmt(const Eigen::Vector3d& v) { return "[" + fmt(v.x()) + ", " + fmt(v.y()) + ", " + fmt(v.z()) + "]"; }

std::string mvRepr(const Multivector& m) {
  const Coeffs n = m.nullCoefficients();
  const double scale = std::max(1.0, n.cwiseAbs().maxCoeff());
  std::string s;
  // order blades by grade, then bits
  for (int g = 0; g <= 5; ++g)
    for (unsigned b = 0; b < 32; ++b) {
      if (cga::detail::popcount(b) != g || std::abs(n[b]) <= 1e-13 * scale) continue;
      const double v = n[b];
      if (!s.empty()) s += v < 0 ? " - " : " + ";
      else if (v < 0) s += "-";
      s += fmt(std::abs(v));
      if (b) s += "*" + Multivector::nullBladeName(b);
    }
  return "Multivector(" + (s.empty() ? std::string("0") : s) + ")";
}

py::array_t<double> fromCoeffs(const Coeffs& c) {
  py::array_t<double> out(32);
  for (int i = 0; i < 32; ++i) out.mutable_data()[i] = c[i];
  return out;
}
/// An (N, cols) float array of finite values as C-contiguous float64; TypeError / ValueError naming `what`.
RowArray finiteRows(const py::object& o, py::ssize_t cols, const char* what) {
  const py::array a = checkedArray(o, what);
  if (a.ndim() != 2 || a.shape(1) != cols)
    throw py::value_error(std::string(what) + ": expected an (N, " + std::to_string(cols) + ") array");
  RowArray r = RowArray::ensure(a);
  const double* d = r.data();
  for (py::ssize_t i = 0; i < r.size(); ++i)
    if (!std::isfinite(d[i])) throw py::value_error(std::string(what) + ": contains NaN or Inf");
  return r;
}

std::string shapeOf(const py::array& a) {
  std::string s = "(";
  for (py::ssize_t k = 0; k < a.ndim(); ++k) s += (k ? ", " : "") + std::to_string(a.shape(k));
  return s + (a.ndim() == 1 ? ",)" : ")");
}
/// An array of `n` real numbers (any real dtype, shape (n,) or (n, 1)) as float64, finite.
/// TypeError for complex, string or object input; ValueError for another size or NaN/Inf.
RowArray realValues(const py::object& o, py::ssize_t n, const std::string& what) {
  const py::array a = py::array::ensure(o);
  if (a && a.dtype().kind() == 'c')
    throw py::type_error(what + ": complex values are refused (the imaginary part would be dropped)");
  checkedArray(o, what, kReals);
  if (a.size() != n || a.ndim() < 1 || a.ndim() > 2)
    throw py::value_error(what + ": expected " + std::to_string(n) + " values, got shape " + shapeOf(a));
  RowArray r = RowArray::ensure(a);
  for (py::ssize_t i = 0; i < n; ++i)
    if (!std::isfinite(r.data()[i])) throw py::value_error(what + ": contains NaN or Inf");
  return r;
}
Eigen::Vector3d coords3(const py::object& o, const std::string& what) {
  const RowArray r = realValues(o, 3, what);
  return Eigen::Vector3d(r.data()[0], r.data()[1], r.data()[2]);
}

/// Whether every coefficient, coordinate or length of a result is finite.
template <class T>
bool finite(const T& x) {
  if constexpr (std::is_same_v<T, Multivector>) return x.allFinite();
  else if constexpr (std::is_base_of_v<Eigen::DenseBase<T>, T>) return x.allFinite();
  else if constexpr (std::is_floating_point_v<T>) return std::isfinite(x);
  else if constexpr (std::is_same_v<T, cga::Sphere>) return x.center.allFinite() && std::isfinite(x.radius2);
  else if constexpr (std::is_same_v<T, cga::Plane>) return x.normal.allFinite() && std::isfinite(x.distance);
  else if constexpr (std::is_same_v<T, cga::Line>) return x.point.allFinite() && x.direction.allFinite();
  else if constexpr (std::is_same_v<T, cga::Circle>)
    return x.center.allFinite() && x.normal.allFinite() && std::isfinite(x.radius);
  else if constexpr (std::is_same_v<T, cga::Point>) return x.position.allFinite();
  else if constexpr (std::is_same_v<T, cga::PointPair> || std::is_same_v<T, cga::FlatPoint>) return x.direct.allFinite();
  else if constexpr (std::is_same_v<T, cga::Motor>) return x.multivector().allFinite();
  else if constexpr (std::is_same_v<T, std::pair<Eigen::Vector3d, Eigen::Vector3d>>)
    return x.first.allFinite() && x.second.allFinite();
  else return true;  // enums, names
}
/// x, or ValueError when it is not finite: finite input beyond ~1e150 m overflows once squared
/// (up(x) holds 1/2 |x|^2, products multiply coefficients), and an inf/NaN object must never be
/// handed back as if it were an answer.
template <class T>
const T& checked(const T& x) {
  if (!finite(x))
    throw py::value_error("overflow: the result is not finite (coordinates beyond ~1e150 m, or products of "
                          "such values)");
  return x;
}

/// How a bound argument of C++ type A arrives from Python and is checked under its name.
template <class A>
struct Arg {
  using type = A;
  static A get(A a, const char*) { return a; }
};
template <>
struct Arg<const Eigen::Vector3d&> {
  using type = cga_args::Coords;
  static Eigen::Vector3d get(const cga_args::Coords& c, const char* what) { return coords3(c.o, what); }
};
template <>
struct Arg<double> {
  using type = double;
  static double get(double a, const char* what) {
    if (!std::isfinite(a)) throw py::value_error(std::string(what) + ": NaN or Inf");
    return a;
  }
};
inline const char* nameAt(const std::vector<const char*>& names, std::size_t i) {
  return i < names.size() ? names[i] : "argument";
}
template <class R, class... A, std::size_t... I>
auto checkedFree(R (*f)(A...), std::vector<const char*> names, std::index_sequence<I...>) {
  return [f, names](typename Arg<A>::type... a) -> R { return checked(f(Arg<A>::get(a, nameAt(names, I))...)); };
}
template <class R, class C, class... A, std::size_t... I>
auto checkedMember(R (C::*f)(A...) const, std::vector<const char*> names, std::index_sequence<I...>) {
  return [f, names](const C& self, typename Arg<A>::type... a) -> R {
    return checked((self.*f)(Arg<A>::get(a, nameAt(names, I))...));
  };
}
/// f with its 3-vector arguments read by coords3() under `names` (in order), its double
/// arguments required finite, and its result required finite (checked()).
/// A constructor as a function, for chk().
template <class T, class... A>
T make(A... a) {
  return T(a...);
}
template <class R, class... A>
auto chk(R (*f)(A...), std::vector<const char*> names = {}) {
  return checkedFree(f, std::move(names), std::index_sequence_for<A...>{});
}
template <class R, class C, class... A>
auto chk(R (C::*f)(A...) const, std::vector<const char*> names = {}) {
  return checkedMember(f, std::move(names), std::index_sequence_for<A...>{});
}
}  // namespace

void defineCga(py::module_& m) {
  py::class_<Multivector> mv(m, "Multivector", "General multivector of G(4,1) (32 blades)");
  // Every coefficient that enters is finite and real (ValueError / TypeError naming the argument)
  // and every result is checked(): an overflowing product is a ValueError, not an inf/NaN object.
  const auto coeffs = [](const py::object& a) {
    return Coeffs(Eigen::Map<const Coeffs>(realValues(a, 32, "coefficients").data()));
  };
  mv.def(py::init<>())
      .def(py::init([](double s) { return Multivector(Arg<double>::get(s, "scalar")); }), py::arg("scalar"))
      .def_static("from_null", [coeffs](const py::object& a) { return checked(Multivector::fromNull(coeffs(a))); },
                  py::arg("coefficients"))
      .def_static("from_orthonormal",
                  [coeffs](const py::object& a) { return Multivector::fromOrthonormal(coeffs(a)); },
                  py::arg("coefficients"))
      .def_static("blade", chk(&Multivector::named, {"name", "value"}), py::arg("name"), py::arg("value") = 1.0)
      .def_static(
          "blade_name",
          [](long long index) {
            if (index < 0 || index > 31)
              throw py::value_error("index: expected a blade index in 0..31, got " + std::to_string(index));
            return Multivector::nullBladeName(static_cast<unsigned>(index));
          },
          py::arg("index"), "name of null-basis blade `index` (0..31, the order of null_coefficients())")
      .def_static("e0", &Multivector::e0)
      .def_static("e1", &Multivector::e1)
      .def_static("e2", &Multivector::e2)
      .def_static("e3", &Multivector::e3)
      .def_static("einf", &Multivector::eInf)
      .def_static("e_plus", &Multivector::ePlus)
      .def_static("e_minus", &Multivector::eMinus)
      .def_static("ic", &Multivector::pseudoscalar)
      .def_static("i3", &Multivector::pseudoscalar3)
      .def_static("vector", chk(&Multivector::vector, {"v"}), py::arg("v"))
      .def("null_coefficients", [](const Multivector& a) { return fromCoeffs(a.nullCoefficients()); })
      .def("orthonormal_coefficients", [](const Multivector& a) { return fromCoeffs(a.orthonormal()); })
      .def("__getitem__", &Multivector::get, py::arg("blade"))
      .def("grade", &Multivector::grade, py::arg("k"))
      .def("reverse", &Multivector::reverse)
      .def("involute", &Multivector::involute)
      .def("dual", chk(&Multivector::dual))
      .def("undual", chk(&Multivector::undual))
      .def("inverse",
           [](const Multivector& a) {
             try {
               return checked(a.inverse());
             } catch (const std::domain_error& e) {
               throw py::value_error(e.what());
             }
           })
      .def("norm", chk(&Multivector::norm))
      .def("scalar", &Multivector::scalar)
      .def("scalar_product", chk(&Multivector::scalarProduct))
      .def("left_contraction", chk(&Multivector::leftContraction))
      .def("outer", chk(&Multivector::outer))
      .def("inner", chk(&Multivector::inner))
      .def("__mul__", [](const Multivector& a, const Multivector& b) { return checked(a * b); }, py::is_operator())
      .def("__mul__", [](const Multivector& a, double s) { return checked(a * Arg<double>::get(s, "scalar")); },
           py::is_operator())
      .def("__rmul__", [](const Multivector& a, double s) { return checked(a * Arg<double>::get(s, "scalar")); },
           py::is_operator())
      .def("__truediv__",
           [](const Multivector& a, double s) {
             if (!(s != 0)) throw py::value_error("divisor: division of a multivector by 0");
             return checked(a / Arg<double>::get(s, "divisor"));
           },
           py::is_operator())
      .def("__add__", [](const Multivector& a, const Multivector& b) { return checked(a + b); }, py::is_operator())
      .def("__add__", [](const Multivector& a, double s) { return checked(a + Multivector(Arg<double>::get(s, "scalar"))); },
           py::is_operator())
      .def("__radd__", [](const Multivector& a, double s) { return checked(a + Multivector(Arg<double>::get(s, "scalar"))); },
           py::is_operator())
      .def("__sub__", [](const Multivector& a, const Multivector& b) { return checked(a - b); }, py::is_operator())
      .def("__sub__", [](const Multivector& a, double s) { return checked(a - Multivector(Arg<double>::get(s, "scalar"))); },
           py::is_operator())
      .def("__rsub__", [](const Multivector& a, double s) { return checked(Multivector(Arg<double>::get(s, "scalar")) - a); },
           py::is_operator())
      .def("__neg__", [](const Multivector& a) { return -a; })
      .def("__xor__", [](const Multivector& a, const Multivector& b) { return checked(a.outer(b)); }, py::is_operator())
      .def("__or__", [](const Multivector& a, const Multivector& b) { return checked(a.inner(b)); }, py::is_operator())
      .def("__invert__", &Multivector::reverse)
      .def("__repr__", &mvRepr);

  // ----- points, vectorised -----
  m.def(
      "up",
      [](const py::object& x_in) -> py::object {
        const py::array x = py::array::ensure(x_in);
        if (!x || x.ndim() != 2) return py::cast(chk(&cga::up, {"x"})(cga_args::Coords{x_in}));
        const RowArray p = finiteRows(x_in, 3, "points");
        const py::ssize_t n = p.shape(0);
        py::array_t<double> out({n, py::ssize_t{5}});
        double* o = out.mutable_data();
        for (const double* q = p.data(); q != p.data() + 3 * n; q += 3, o += 5) {
          if (std::max({std::abs(q[0]), std::abs(q[1]), std::abs(q[2])}) > cga::kMaxCoordinate)
            throw py::value_error("points: row " + std::to_string((q - p.data()) / 3) +
                                  ": overflow: coordinates beyond ~1e150 m");
          std::copy(q, q + 3, o);
          o[3] = 0.5 * (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
          o[4] = 1.0;
        }
        return std::move(out);
      },
      py::arg("x"),
      "Conformal point x + 1/2 x^2 einf + e0 (4.54) of a point in metres: a (3,) point gives a Multivector, an "
      "(N, 3) float array an (N, 5) float64 array of coefficients (e1, e2, e3, einf, e0) (4.55). ValueError for "
      "NaN/Inf, a wrong shape or coordinates beyond ~1e150 m (1/2 x^2 would overflow), TypeError for complex "
      "input or a non-float (N, 3) array.");
  m.def(
      "down",
      [](const py::object& P) -> py::object {
        if (py::isinstance<Multivector>(P) || py::isinstance<cga::Point>(P))
          return py::cast(chk(&cga::down)(P.cast<Multivector>()));
        const RowArray p = finiteRows(P, 5, "conformal points");
        const py::ssize_t n = p.shape(0);
        py::array_t<double> out({n, py::ssize_t{3}});
        double* o = out.mutable_data();
        for (py::ssize_t i = 0; i < n; ++i, o += 3) {
          const double* q = p.data() + 5 * i;
          if (!(std::abs(q[4]) > 0)) throw py::value_error("down: row " + std::to_string(i) + " has e0 coefficient 0");
          for (int k = 0; k < 3; ++k) o[k] = q[k] / q[4];
          if (std::max({std::abs(o[0]), std::abs(o[1]), std::abs(o[2])}) > cga::kMaxCoordinate)
            throw py::value_error("down: row " + std::to_string(i) + ": overflow: e0 coefficient " + fmt(q[4]) +
                                  " puts the point beyond ~1e150 m");
        }
        return std::move(out);
      },
      py::arg("P"),
      "Euclidean point (metres) of a conformal point of any scale (divides by the e0 coefficient -einf . P): a "
      "Multivector gives a (3,) array, an (N, 5) array of coefficients (e1, e2, e3, einf, e0) an (N, 3) array. "
      "ValueError for a zero e0 coefficient (a point at infinity), NaN/Inf, or a point beyond ~1e150 m.");
  m.def("to_vector5", chk(&cga::toVector5, {"v"}), py::arg("v"), "(5,) coefficients (e1, e2, e3, einf, e0) of a vector (4.55)");
  m.def("from_vector5", [](const py::object& x) { return cga::fromVector5(Eigen::Map<const cga::Vector5>(realValues(x, 5, "x").data())); }, py::arg("x"), "the vector of (5,) coefficients (e1, e2, e3, einf, e0)");
  m.def("inner_product_matrix", &cga::innerProductMatrix, "M with X . Y = X^T M Y on (e1, e2, e3, einf, e0) (5.32)");
  m.def("blade_names", [] {
    std::vector<std::string> names;
    for (unsigned i = 0; i < 32; ++i) names.push_back(Multivector::nullBladeName(i));
    return names;
  }, "names of the 32 null-basis blades in the order of null_coefficients()");
  m.attr("e0") = Multivector::e0();
  m.attr("e1") = Multivector::e1();
  m.attr("e2") = Multivector::e2();
  m.attr("e3") = Multivector::e3();
  m.attr("einf") = Multivector::eInf();
  m.attr("Ic") = Multivector::pseudoscalar();
  m.attr("I3") = Multivector::pseudoscalar3();
  // Batched geometric product on (N,32) orthonormal coefficients (benchmarks).
  m.def("geometric_product_many", [](const py::object& a_in, const py::object& b_in) {
    const RowArray a = finiteRows(a_in, 32, "a"), b = finiteRows(b_in, 32, "b");
    if (a.shape(0) != b.shape(0)) throw py::value_error("a and b must have the same number of rows");
    const py::ssize_t n = a.shape(0);
    py::array_t<double> out({n, py::ssize_t{32}});
    {
      py::gil_scoped_release release;
      for (py::ssize_t i = 0; i < n; ++i) {
        const Multivector x = Multivector::fromOrthonormal(Eigen::Map<const Coeffs>(a.data() + 32 * i));
        const Multivector y = Multivector::fromOrthonormal(Eigen::Map<const Coeffs>(b.data() + 32 * i));
        Eigen::Map<Coeffs>(out.mutable_data() + 32 * i) = (x * y).orthonormal();
      }
    }
    for (py::ssize_t i = 0; i < 32 * n; ++i)
      if (!std::isfinite(out.data()[i]))
        throw py::value_error("overflow: row " + std::to_string(i / 32) + " of the products is not finite");
    return out;
  }, py::arg("a"), py::arg("b"),
  "Row-wise geometric products of two (N, 32) arrays of orthonormal-basis coefficients "
  "(Multivector.orthonormal_coefficients() layout)");

  // ----- typed objects -----
  fieldsOf(py::class_<cga::Sphere>(m, "Sphere", R"(Dual (IPNS) sphere S* = up(c) - 1/2 r^2 einf (4.59).

center: metres, in the caller's frame; radius: metres (radius2 < 0: imaginary sphere,
S*^2 < 0 (4.61)). from_dual / from_direct accept any scale (r^2 = S*^2/(einf.S*)^2);
through_points(a, b, c, d) uses S = PA^PB^PC^PD (4.58). A dual vector with e0
coefficient 0 is a plane and raises ValueError.)")
      .def(py::init(chk(&make<cga::Sphere, const Eigen::Vector3d&, double>, {"center", "radius"})), py::arg("center"),
           py::arg("radius"))
      .def_static("with_radius2", chk(&cga::Sphere::withRadius2, {"center", "radius2"}), py::arg("center"),
                  py::arg("radius2"))
      .def_static("from_dual", chk(&cga::Sphere::fromDual), py::arg("S"))
      .def_static("from_direct", chk(&cga::Sphere::fromDirect), py::arg("S"))
      .def_static("through_points", chk(&cga::Sphere::throughPoints, {"a", "b", "c", "d"}), py::arg("a"),
                  py::arg("b"), py::arg("c"), py::arg("d"))
      .def("dual", chk(&cga::Sphere::dual))
      .def("__repr__", [](const cga::Sphere& s) {
        return "Sphere(center=" + fmt(s.center) +
               (s.isReal() ? ", radius=" + fmt(s.radius()) : ", radius2=" + fmt(s.radius2) + " (imaginary)") + ")";
      }))
      .output("center", &cga::Sphere::center, "m", "(3,) centre")
      .output("radius2", &cga::Sphere::radius2, "m^2", "squared radius; < 0 for an imaginary sphere (S*^2 < 0, (4.61))")
      .derived("radius", [](const cga::Sphere& s) { return s.radius(); }, "m", "radius; ValueError for an imaginary sphere")
      .derived("is_real", [](const cga::Sphere& s) { return s.isReal(); }, "", "radius2 >= 0")
      .result();
  fieldsOf(py::class_<cga::Plane>(m, "Plane", R"(Dual plane Pi* = n + delta einf (4.65), |n| = 1.

normal: unit vector (normalised on construction; zero raises ValueError); distance: signed
distance of the plane from the origin along the normal, metres. point_plane_distance(x, p) =
x.n - delta (4.67), positive on the side the normal points to. through_points(a, b, c) uses
the direct plane PA^PB^PC^einf (4.64), whose orientation follows the dual convention.)")
      .def(py::init(chk(&make<cga::Plane, const Eigen::Vector3d&, double>, {"normal", "distance"})), py::arg("normal"),
           py::arg("distance"))
      .def_static("through_point", chk(&cga::Plane::throughPoint, {"normal", "point"}), py::arg("normal"),
                  py::arg("point"))
      .def_static("through_points", chk(&cga::Plane::throughPoints, {"a", "b", "c"}), py::arg("a"), py::arg("b"),
                  py::arg("c"))
      .def_static("from_dual", chk(&cga::Plane::fromDual), py::arg("P"))
      .def_static("from_direct", chk(&cga::Plane::fromDirect), py::arg("P"))
      .def("dual", chk(&cga::Plane::dual))
      .def("direct", chk(&cga::Plane::direct))
      .def("__repr__", [](const cga::Plane& p) {
        return "Plane(normal=" + fmt(p.normal) + ", distance=" + fmt(p.distance) + ")";
      }))
      .output("normal", &cga::Plane::normal, "", "(3,) unit normal")
      .output("distance", &cga::Plane::distance, "m", "signed distance of the plane from the origin along the normal")
      .result();
  fieldsOf(py::class_<cga::Line>(m, "Line", R"(Line through `point` (the closest point to the origin, metres) along the unit
`direction`. direct() = (p + e0)^d^einf = PA^PB^einf (4.68); dual() = A + b einf.)")
      .def(py::init(chk(&make<cga::Line, const Eigen::Vector3d&, const Eigen::Vector3d&>, {"point", "direction"})), py::arg("point"),
           py::arg("direction"))
      .def_static("through_points", chk(&cga::Line::throughPoints, {"a", "b"}), py::arg("a"), py::arg("b"))
      .def_static("from_direct", chk(&cga::Line::fromDirect), py::arg("L"))
      .def_static("from_dual", chk(&cga::Line::fromDual), py::arg("L_dual"))
      .def("direct", chk(&cga::Line::direct))
      .def("dual", chk(&cga::Line::dual))
      .def("__repr__", [](const cga::Line& l) {
        return "Line(point=" + fmt(l.point) + ", direction=" + fmt(l.direction) + ")";
      }))
      .output("point", &cga::Line::point, "m", "(3,) the line's closest point to the origin")
      .output("direction", &cga::Line::direction, "", "(3,) unit direction")
      .result();
  fieldsOf(py::class_<cga::Motor>(m, "Motor", R"(Rigid motion M = T R (thesis Paper 4 §3.5): T = 1 - 1/2 t einf, R = w - (x e23 + y e31 + z e12)
for the unit quaternion (w, x, y, z). Acts by X -> M X ~M; on a point it gives R x + t
(metres), so from_matrix(T_a_b) maps frame-b coordinates into frame a. a * b applies b
first. interpolate(a, b, s) slerps the rotation and lerps the translation (not a screw
motion). from_multivector checks the motor space and M~M = 1 (P5 (34)-(35)).)")
      .def(py::init<>())
      .def_static("from_matrix",
                  [](const py::object& T) {
                    const RowArray a = realValues(T, 16, "T");
                    if (a.ndim() != 2) throw py::value_error("T: expected a (4, 4) array, got shape " + shapeOf(a));
                    return checked(cga::Motor::fromMatrix(Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(a.data())));
                  },
                  py::arg("T"))
      .def_static("from_quaternion",
                  [](const py::object& wxyz, const cga_args::Coords& t) {
                    const RowArray q = realValues(wxyz, 4, "wxyz");
                    return checked(cga::Motor::fromQuaternion(
                        Eigen::Quaterniond(q.data()[0], q.data()[1], q.data()[2], q.data()[3]), coords3(t.o, "t")));
                  },
                  py::arg("wxyz"), py::arg("t"))
      .def_static("from_multivector", chk(&cga::Motor::fromMultivector, {"M", "tol"}), py::arg("M"),
                  py::arg("tol") = 1e-8)
      .def_static("interpolate", chk(&cga::Motor::interpolate, {"a", "b", "s"}), py::arg("a"), py::arg("b"),
                  py::arg("s"))
      .def("rotor", &cga::Motor::rotor)
      .def("quaternion",
           [](const cga::Motor& M) {
             const auto q = M.quaternion();
             return Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
           })
      .def("translation", chk(&cga::Motor::translation))
      .def("matrix", chk(&cga::Motor::matrix))
      .def("inverse", &cga::Motor::inverse)
      .def("__mul__", [](const cga::Motor& a, const cga::Motor& b) { return checked(a * b); }, py::is_operator())
      .def("apply_multivector", [](const cga::Motor& M, const Multivector& X) { return checked(M.apply(X)); },
           py::arg("X"))
      .def("apply_point",
           [](const cga::Motor& M, const cga_args::Coords& x) { return checked(M.apply(coords3(x.o, "x"))); },
           py::arg("x"))
      .def("apply_plane", [](const cga::Motor& M, const cga::Plane& p) { return checked(M.apply(p)); }, py::arg("p"))
      .def("apply_sphere", [](const cga::Motor& M, const cga::Sphere& s) { return checked(M.apply(s)); },
           py::arg("s"))
      .def("apply_line", [](const cga::Motor& M, const cga::Line& l) { return checked(M.apply(l)); }, py::arg("l"))
      .def("apply_points", [](const cga::Motor& M, const py::object& points) {
        const RowArray x = finiteRows(points, 3, "points");
        const py::ssize_t n = x.shape(0);
        py::array_t<double> out({n, py::ssize_t{3}});
        const Multivector Mm = M.multivector(), Mr = Mm.reverse();
        for (py::ssize_t i = 0; i < n; ++i) {
          const Eigen::Vector3d p = Eigen::Map<const Eigen::Vector3d>(x.data() + 3 * i);
          Eigen::Map<Eigen::Vector3d>(out.mutable_data() + 3 * i) = checked(cga::down(Mm * cga::up(p) * Mr));
        }
        return out;
      }, py::arg("points"))
      .def("__repr__", [](const cga::Motor& M) {
        const auto q = M.quaternion();
        return "Motor(quaternion_wxyz=[" + fmt(q.w()) + ", " + fmt(q.x()) + ", " + fmt(q.y()) + ", " + fmt(q.z()) +
               "], translation=" + fmt(M.translation()) + ")";
      }))
      // set (unpickling) through from_multivector, which re-checks M~M = 1
      .field(
          "multivector", [](const cga::Motor& M) { return M.multivector(); },
          [](cga::Motor& M, const Multivector& X) { M = cga::Motor::fromMultivector(X); }, "", "M = T R, a Multivector",
          false)
      .result();

  py::enum_<cga::Reality>(m, "Reality")
      .value("real", cga::Reality::Real)
      .value("tangent", cga::Reality::Tangent)
      .value("imaginary", cga::Reality::Imaginary);
  m.def("point_pair_reality", chk(&cga::pointPairReality, {"Q", "tol"}), py::arg("Q"), py::arg("tol") = 1e-10);

  fieldsOf(py::class_<cga::PointPair>(m, "PointPair", R"(Point pair, held as the direct 2-blade Q = PA^PB (4.62).

Build with from_points(a, b) (metres), from_direct(Q) or from_dual(Q*) (a meet result such as
meet_plane_circle). reality() is the sign of Q^2 (thesis (4.70)-(4.73)); points() gives (P-, P+) of (4.63),
i.e. (a, b) for from_points(a, b), and raises ValueError for an imaginary pair.)")
      .def_static("from_points", chk(&cga::PointPair::fromPoints, {"a", "b"}), py::arg("a"), py::arg("b"))
      .def_static("from_direct", chk(&cga::PointPair::fromDirect), py::arg("Q"))
      .def_static("from_dual", chk(&cga::PointPair::fromDual), py::arg("Q_dual"))
      .def("dual", chk(&cga::PointPair::dual))
      .def("square", chk(&cga::PointPair::square))
      .def("reality", chk(&cga::PointPair::reality, {"tol"}), py::arg("tol") = 1e-10)
      .def("points", chk(&cga::PointPair::points))
      .def("__repr__", [](const cga::PointPair& q) {
        const cga::Reality r = q.reality();
        std::string s = "PointPair(" + std::string(r == cga::Reality::Real ? "real" : r == cga::Reality::Tangent ? "tangent" : "imaginary");
        if (r != cga::Reality::Imaginary) {
          const auto pts = q.points();
          s += ", points=(" + fmt(pts.first) + ", " + fmt(pts.second) + ")";
        } else {
          s += ", Q^2=" + fmt(q.square());
        }
        return s + ")";
      }))
      .output("direct", &cga::PointPair::direct, "", "Q = PA ^ PB, a grade-2 blade (4.62)")
      .result();
  fieldsOf(py::class_<cga::FlatPoint>(m, "FlatPoint", R"(Flat point P^einf (4.69), e.g. the line-plane meet (4.73); location() in metres.)")
      .def_static("at", chk(&cga::FlatPoint::at, {"p"}), py::arg("p"))
      .def_static("from_multivector", chk(&cga::FlatPoint::fromMultivector), py::arg("F"))
      .def("location", chk(&cga::FlatPoint::location))
      .def("__repr__", [](const cga::FlatPoint& f) { return "FlatPoint(" + fmt(f.location()) + ")"; }))
      .output("direct", &cga::FlatPoint::direct, "", "up(p) ^ einf (4.69), any non-zero scale")
      .result();
  fieldsOf(py::class_<cga::Point>(m, "Point", R"(A Euclidean point (metres) as a conformal point up(x) (4.54).

Point(x).mv is the normalised conformal point; the operators *, ^, | and ~ act on it and
return Multivector. A Point is accepted wherever a Multivector is.)")
      .def(py::init(chk(&make<cga::Point, const Eigen::Vector3d&>, {"x"})), py::arg("x"))
      .def_static("from_multivector", chk(&cga::Point::fromMultivector), py::arg("P"))
      .def("__mul__", [](const cga::Point& a, const Multivector& b) { return checked(a.multivector() * b); },
           py::is_operator())
      .def("__xor__", [](const cga::Point& a, const Multivector& b) { return checked(a.multivector().outer(b)); },
           py::is_operator())
      .def("__or__", [](const cga::Point& a, const Multivector& b) { return checked(a.multivector().inner(b)); },
           py::is_operator())
      .def("__invert__", [](const cga::Point& a) { return a.multivector().reverse(); })
      .def("__repr__", [](const cga::Point& p) { return "Point(" + fmt(p.position) + ")"; }))
      .output("position", &cga::Point::position, "m", "(3,) the point")
      .derived(
          "mv", [](const cga::Point& p) { return p.multivector(); }, "", "up(position), the normalised conformal point")
      .result();
  mv.def(py::init([](const cga::Point& p) { return p.multivector(); }), py::arg("point"));
  py::implicitly_convertible<cga::Point, Multivector>();
  fieldsOf(py::class_<cga::Circle>(m, "Circle", R"(A circle: center (metres), unit normal of its carrier plane, radius (metres).

direct() is up(a) ^ up(b) ^ up(c) for three points on it (4.57); from_direct reads any direct
circle (centre C einf C, radius from <C C^> / <(einf _| C)^2>, normal from the plane C ^ einf
(4.64)); from_dual reads a meet result such as meet_sphere_plane (the dual C*; its undual
C* Ic is the direct circle). ValueError for an imaginary circle (radius^2 < 0), a line (a
circle through infinity), a zero normal or a negative radius.)")
      .def(py::init(chk(&make<cga::Circle, const Eigen::Vector3d&, const Eigen::Vector3d&, double>, {"center", "normal", "radius"})),
           py::arg("center"), py::arg("normal"), py::arg("radius"))
      .def_static("through_points", chk(&cga::Circle::throughPoints, {"a", "b", "c"}), py::arg("a"), py::arg("b"),
                  py::arg("c"))
      .def_static("from_direct", chk(&cga::Circle::fromDirect), py::arg("C"))
      .def_static("from_dual", chk(&cga::Circle::fromDual), py::arg("C_dual"))
      .def("direct", chk(&cga::Circle::direct))
      .def("dual", chk(&cga::Circle::dual))
      .def("__repr__", [](const cga::Circle& c) {
        return "Circle(center=" + fmt(c.center) + ", normal=" + fmt(c.normal) + ", radius=" + fmt(c.radius) + ")";
      }))
      .output("center", &cga::Circle::center, "m", "(3,) centre")
      .output("normal", &cga::Circle::normal, "", "(3,) unit normal of the carrier plane")
      .output("radius", &cga::Circle::radius, "m", "radius")
      .result();

  m.def("point_pair", chk(&cga::pointPair, {"a", "b"}), py::arg("a"), py::arg("b"), "direct point pair up(a) ^ up(b) (4.62), metres");
  m.def("point_pair_points", chk(&cga::pointPairPoints, {"Q"}), py::arg("Q"),
        "The two points (Q -+ sqrt(Q^2)) / (-einf . Q) (4.63) of a direct point pair, (a, b) for Q = up(a) ^ up(b) "
        "(negating Q swaps them). A dual pair from a meet is made direct with .undual(). ValueError when Q^2 < 0 "
        "(no real points, thesis (4.70)-(4.73)).");
  m.def("flat_point", chk(&cga::flatPoint, {"p"}), py::arg("p"), "flat point up(p) ^ einf (4.69)");
  m.def("flat_point_location", chk(&cga::flatPointLocation, {"F"}), py::arg("F"), "location (metres) of a flat point of any scale");
  m.def("circle", chk(&cga::circle, {"a", "b", "c"}), py::arg("a"), py::arg("b"), py::arg("c"),
        "direct circle up(a) ^ up(b) ^ up(c) through three points (4.57)");
  m.def("round_center", chk(&cga::roundCenter, {"X"}), py::arg("X"), "centre X einf X of a direct round (point pair, circle, sphere)");
  m.def("round_radius2", chk(&cga::roundRadius2, {"X"}), py::arg("X"),
        "squared radius <X X^>_0 / <D D>_0, D = einf _| X, of a direct round (Dorst et al. 2007, §14.2); < 0: imaginary");
  m.def("meet_sphere_plane", chk(&cga::meetSpherePlane, {"sphere", "plane"}), py::arg("sphere"), py::arg("plane"), "dual circle Pi* ^ S* (4.70)");
  m.def("meet_planes", chk(&cga::meetPlanes, {"a", "b"}), py::arg("a"), py::arg("b"), "dual line Pi1* ^ Pi2*");
  m.def("meet_spheres", chk(&cga::meetSpheres, {"a", "b"}), py::arg("a"), py::arg("b"), "dual circle S1* ^ S2*");
  m.def("meet_plane_circle", chk(&cga::meetPlaneCircle, {"plane", "dual_circle"}), py::arg("plane"), py::arg("dual_circle"),
        "dual point pair Pi* ^ C* (its .undual() is the direct pair)");
  m.def("meet_line_plane", chk(&cga::meetLinePlane, {"line", "plane"}), py::arg("line"), py::arg("plane"), "flat point Pi* . L (4.73)");
  m.def("meet_line_plane_flat", chk(&cga::meetLinePlaneFlat, {"line", "plane"}), py::arg("line"), py::arg("plane"), "the line-plane meet as a FlatPoint");
  m.def("meet_plane_circle_pair", chk(&cga::meetPlaneCirclePair, {"plane", "dual_circle"}), py::arg("plane"), py::arg("dual_circle"),
        "the plane-circle meet as a PointPair (4.70)");
  m.def("point_distance", chk(&cga::pointDistance, {"a", "b"}), py::arg("a"), py::arg("b"), "|a - b| from d^2 = -2 up(a) . up(b) (4.56)");
  m.def("point_plane_distance", chk(&cga::pointPlaneDistance, {"x", "plane"}), py::arg("x"), py::arg("plane"),
        "signed distance up(x) . Pi* = x . n - delta (4.67), metres, > 0 on the normal's side");
  m.def("sphere_point_inner", chk(&cga::spherePointInner, {"sphere", "x"}), py::arg("sphere"), py::arg("x"),
        "S* . up(x) = 1/2 (r^2 - |x - c|^2) (Paper 5 eq. (10)): > 0 inside, 0 on, < 0 outside");
  m.def("point_sphere_distance", chk(&cga::pointSphereDistance, {"x", "sphere"}), py::arg("x"), py::arg("sphere"),
        "|x - c| - r, metres (> 0 outside)");
  m.def("rotor", chk(&cga::rotor, {"axis", "angle"}), py::arg("axis"), py::arg("angle"),
        "rotor cos(angle/2) - sin(angle/2) B for a right-handed rotation by angle (radians) about axis (Paper 4 §3.5)");
  m.def("translator", chk(&cga::translator, {"t"}), py::arg("t"), "translator 1 - 1/2 t einf (Paper 4 §3.5), t in metres");

  // ----- angles and rotation planes (Paper 1 §3.7) -----
  m.def("normalise_blade", chk(&cga::normaliseBlade, {"A"}), py::arg("A"), "A / sqrt(|<A ~A>_0|); ValueError for a null blade");
  m.def("euclidean_dual", chk(&cga::euclideanDual, {"A"}), py::arg("A"), "Euclidean dual A I3^{-1}");
  m.def("rotation_plane_from_axis", chk(&cga::rotationPlaneFromAxis, {"axis"}), py::arg("axis"),
        "unit rotation plane N = n I3 whose Euclidean dual N* = N I3^{-1} is the unit axis (e.g. e3 -> e12)");
  m.def("rotation_axis", chk(&cga::rotationAxis, {"N"}), py::arg("N"), "unit axis N* = N I3^{-1} of a Euclidean bivector");
  m.def(
      "signed_angle",
      [](const py::object& a, const py::object& b, const Multivector& N) {
        auto vec = [](const py::object& v, const char* what) {
          if (py::isinstance<Multivector>(v)) return v.cast<Multivector>();
          return Multivector::vector(coords3(v, std::string(what) + " (3 coordinates or a grade-1 Multivector)"));
        };
        return checked(cga::signedAngle(vec(a, "a"), vec(b, "b"), N));
      },
      py::arg("a"), py::arg("b"), py::arg("N"),
      "Signed angle (radians, in (-pi, pi]) from direction a to b in the rotation plane N: theta = "
      "atan2((a^b) N^{-1}, a.b), Paper 1 eq. (17). a, b: 3-vectors (any length, one frame) or grade-1 "
      "Multivectors; N: a Euclidean bivector (normalised here). For a, b perpendicular to the axis N* this is the "
      "right-handed angle about N*.");
  m.def("rotation_plane_perpendicular_to_line",
        py::overload_cast<const cga::Line&>(&cga::rotationPlanePerpendicularToLine), py::arg("line"),
        "Unit rotation plane N = (L* ^ einf) . e0 / |.| (Paper 1 eq. (20)) perpendicular to a Line or a dual line L* "
        "(Multivector); for L = up(a)^up(b)^einf, rotation_axis(N) = (b - a)/|b - a|");
  m.def("rotation_plane_perpendicular_to_line",
        py::overload_cast<const Multivector&>(&cga::rotationPlanePerpendicularToLine), py::arg("line"));
  m.def("rotation_plane_parallel_to_plane",
        py::overload_cast<const cga::Plane&>(&cga::rotationPlaneParallelToPlane), py::arg("plane"),
        "Unit rotation plane N = (Pi . e0) . einf / |.| (Paper 1 eq. (21)) parallel to a Plane (axis oriented to "
        "plane.normal) or a direct plane Pi (Multivector, (4.64): axis (b - a) x (c - a) normalised for "
        "Pi = up(a)^up(b)^up(c)^einf, minus the normal of the dual Pi*)");
  m.def("rotation_plane_parallel_to_plane",
        py::overload_cast<const Multivector&>(&cga::rotationPlaneParallelToPlane), py::arg("plane"));

  // A multivector's state is its 32 orthonormal coefficients (exact, the storage).
  fieldsOf<Multivector>(m, "Multivector")
      .field(
          "coefficients", [](const Multivector& a) { return Coeffs(a.orthonormal()); },
          [](Multivector& a, const Coeffs& c) { a = Multivector::fromOrthonormal(c); }, "",
          "(32,) coefficients on the orthonormal basis (the storage; orthonormal_coefficients() as a property)", false)
      .result();
}

}  // namespace scanalign::python

// Bindings of the CGA core G(4,1) (scanalign/cga/*.hpp; Kleppe, PhD thesis, NTNU 2018, ch. 4). The documented API
// is python/scanalign/cga.py.
#include <sstream>

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/operators.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "scanalign/cga/multivector.hpp"
#include "scanalign/cga/objects.hpp"

namespace py = pybind11;

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

Coeffs toCoeffs(const RowArray& a, const char* what) {
  if (a.ndim() != 1 || a.shape(0) != 32) throw py::value_error(std::string(what) + ": expected 32 coefficients");
  Coeffs c;
  for (int i = 0; i < 32; ++i) c[i] = a.data()[i];
  return c;
}
py::array_t<double> fromCoeffs(const Coeffs& c) {
  py::array_t<double> out(32);
  for (int i = 0; i < 32; ++i) out.mutable_data()[i] = c[i];
  return out;
}
void checkRows(const RowArray& a, py::ssize_t cols, const char* what) {
  if (a.ndim() != 2 || a.shape(1) != cols)
    throw py::value_error(std::string(what) + ": expected an (N, " + std::to_string(cols) + ") array");
}
}  // namespace

void defineCga(py::module_& m) {
  py::class_<Multivector> mv(m, "Multivector", "General multivector of G(4,1) (32 blades)");
  mv.def(py::init<>())
      .def(py::init<double>(), py::arg("scalar"))
      .def_static("from_null", [](const RowArray& a) { return Multivector::fromNull(toCoeffs(a, "coefficients")); })
      .def_static("from_orthonormal",
                  [](const RowArray& a) { return Multivector::fromOrthonormal(toCoeffs(a, "coefficients")); })
      .def_static("blade", &Multivector::named, py::arg("name"), py::arg("value") = 1.0)
      .def_static("blade_name", &Multivector::nullBladeName, py::arg("index"))
      .def_static("e0", &Multivector::e0)
      .def_static("e1", &Multivector::e1)
      .def_static("e2", &Multivector::e2)
      .def_static("e3", &Multivector::e3)
      .def_static("einf", &Multivector::eInf)
      .def_static("e_plus", &Multivector::ePlus)
      .def_static("e_minus", &Multivector::eMinus)
      .def_static("ic", &Multivector::pseudoscalar)
      .def_static("i3", &Multivector::pseudoscalar3)
      .def_static("vector", &Multivector::vector, py::arg("v"))
      .def("null_coefficients", [](const Multivector& a) { return fromCoeffs(a.nullCoefficients()); })
      .def("orthonormal_coefficients", [](const Multivector& a) { return fromCoeffs(a.orthonormal()); })
      .def("__getitem__", &Multivector::get, py::arg("blade"))
      .def("grade", &Multivector::grade, py::arg("k"))
      .def("reverse", &Multivector::reverse)
      .def("involute", &Multivector::involute)
      .def("dual", &Multivector::dual)
      .def("undual", &Multivector::undual)
      .def("inverse",
           [](const Multivector& a) {
             try {
               return a.inverse();
             } catch (const std::domain_error& e) {
               throw py::value_error(e.what());
             }
           })
      .def("norm", &Multivector::norm)
      .def("scalar", &Multivector::scalar)
      .def("scalar_product", &Multivector::scalarProduct)
      .def("left_contraction", &Multivector::leftContraction)
      .def("outer", &Multivector::outer)
      .def("inner", &Multivector::inner)
      .def("__mul__", [](const Multivector& a, const Multivector& b) { return a * b; }, py::is_operator())
      .def("__mul__", [](const Multivector& a, double s) { return a * s; }, py::is_operator())
      .def("__rmul__", [](const Multivector& a, double s) { return a * s; }, py::is_operator())
      .def("__truediv__", [](const Multivector& a, double s) { return a / s; }, py::is_operator())
      .def("__add__", [](const Multivector& a, const Multivector& b) { return a + b; }, py::is_operator())
      .def("__add__", [](const Multivector& a, double s) { return a + Multivector(s); }, py::is_operator())
      .def("__radd__", [](const Multivector& a, double s) { return a + Multivector(s); }, py::is_operator())
      .def("__sub__", [](const Multivector& a, const Multivector& b) { return a - b; }, py::is_operator())
      .def("__sub__", [](const Multivector& a, double s) { return a - Multivector(s); }, py::is_operator())
      .def("__rsub__", [](const Multivector& a, double s) { return Multivector(s) - a; }, py::is_operator())
      .def("__neg__", [](const Multivector& a) { return -a; })
      .def("__xor__", [](const Multivector& a, const Multivector& b) { return a.outer(b); }, py::is_operator())
      .def("__or__", [](const Multivector& a, const Multivector& b) { return a.inner(b); }, py::is_operator())
      .def("__invert__", &Multivector::reverse)
      .def("__repr__", &mvRepr);

  // ----- points, vectorised -----
  m.def("up", [](const Eigen::Vector3d& x) { return cga::up(x); });
  m.def("down", [](const Multivector& P) { return cga::down(P); });
  m.def("to_vector5", &cga::toVector5);
  m.def("from_vector5", &cga::fromVector5);
  m.def("inner_product_matrix", &cga::innerProductMatrix);
  m.def("up_many", [](const RowArray& x) {
    checkRows(x, 3, "points");
    const py::ssize_t n = x.shape(0);
    py::array_t<double> out({n, py::ssize_t{5}});
    const double* p = x.data();
    double* o = out.mutable_data();
    for (py::ssize_t i = 0; i < n; ++i, p += 3, o += 5) {
      o[0] = p[0];
      o[1] = p[1];
      o[2] = p[2];
      o[3] = 0.5 * (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
      o[4] = 1.0;
    }
    return out;
  });
  m.def("down_many", [](const RowArray& v) {
    checkRows(v, 5, "conformal points");
    const py::ssize_t n = v.shape(0);
    py::array_t<double> out({n, py::ssize_t{3}});
    const double* p = v.data();
    double* o = out.mutable_data();
    for (py::ssize_t i = 0; i < n; ++i, p += 5, o += 3) {
      if (!(std::abs(p[4]) > 0)) throw py::value_error("down: row " + std::to_string(i) + " has e0 coefficient 0");
      for (int k = 0; k < 3; ++k) o[k] = p[k] / p[4];
    }
    return out;
  });
  // Batched geometric product on (N,32) orthonormal coefficients (benchmarks).
  m.def("geometric_product_many", [](const RowArray& a, const RowArray& b) {
    checkRows(a, 32, "a");
    checkRows(b, 32, "b");
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
    return out;
  });

  // ----- typed objects -----
  py::class_<cga::Sphere>(m, "Sphere", R"(Dual (IPNS) sphere S* = up(c) - 1/2 r^2 einf (4.59).

center: metres, in the caller's frame; radius: metres (radius2 < 0: imaginary sphere,
S*^2 < 0 (4.61)). from_dual / from_direct accept any scale (r^2 = S*^2/(einf.S*)^2);
through_points(a, b, c, d) uses S = PA^PB^PC^PD (4.58). A dual vector with e0
coefficient 0 is a plane and raises ValueError.)")
      .def(py::init<const Eigen::Vector3d&, double>(), py::arg("center"), py::arg("radius"))
      .def_static("with_radius2", &cga::Sphere::withRadius2, py::arg("center"), py::arg("radius2"))
      .def_static("from_dual", &cga::Sphere::fromDual)
      .def_static("from_direct", &cga::Sphere::fromDirect)
      .def_static("through_points", &cga::Sphere::throughPoints)
      .def_readonly("center", &cga::Sphere::center)
      .def_readonly("radius2", &cga::Sphere::radius2)
      .def_property_readonly("radius", &cga::Sphere::radius)
      .def_property_readonly("is_real", &cga::Sphere::isReal)
      .def("dual", &cga::Sphere::dual)
      .def("__repr__", [](const cga::Sphere& s) {
        return "Sphere(center=" + fmt(s.center) +
               (s.isReal() ? ", radius=" + fmt(s.radius()) : ", radius2=" + fmt(s.radius2) + " (imaginary)") + ")";
      });
  py::class_<cga::Plane>(m, "Plane", R"(Dual plane Pi* = n + delta einf (4.65), |n| = 1.

normal: unit vector (normalised on construction; zero raises ValueError); distance: signed
distance of the plane from the origin along the normal, metres. point_plane_distance(x, p) =
x.n - delta (4.67), positive on the side the normal points to. through_points(a, b, c) uses
the direct plane PA^PB^PC^einf (4.64), whose orientation follows the dual convention.)")
      .def(py::init<const Eigen::Vector3d&, double>(), py::arg("normal"), py::arg("distance"))
      .def_static("through_point", &cga::Plane::throughPoint, py::arg("normal"), py::arg("point"))
      .def_static("through_points", &cga::Plane::throughPoints)
      .def_static("from_dual", &cga::Plane::fromDual)
      .def_static("from_direct", &cga::Plane::fromDirect)
      .def_readonly("normal", &cga::Plane::normal)
      .def_readonly("distance", &cga::Plane::distance)
      .def("dual", &cga::Plane::dual)
      .def("direct", &cga::Plane::direct)
      .def("__repr__", [](const cga::Plane& p) {
        return "Plane(normal=" + fmt(p.normal) + ", distance=" + fmt(p.distance) + ")";
      });
  py::class_<cga::Line>(m, "Line", R"(Line through `point` (the closest point to the origin, metres) along the unit
`direction`. direct() = (p + e0)^d^einf = PA^PB^einf (4.68); dual() = A + b einf.)")
      .def(py::init<const Eigen::Vector3d&, const Eigen::Vector3d&>(), py::arg("point"), py::arg("direction"))
      .def_static("through_points", &cga::Line::throughPoints)
      .def_static("from_direct", &cga::Line::fromDirect)
      .def_static("from_dual", &cga::Line::fromDual)
      .def_readonly("point", &cga::Line::point)
      .def_readonly("direction", &cga::Line::direction)
      .def("direct", &cga::Line::direct)
      .def("dual", &cga::Line::dual)
      .def("__repr__", [](const cga::Line& l) {
        return "Line(point=" + fmt(l.point) + ", direction=" + fmt(l.direction) + ")";
      });
  py::class_<cga::Motor>(m, "Motor", R"(Rigid motion M = T R (thesis Paper 4 §3.5): T = 1 - 1/2 t einf, R = w - (x e23 + y e31 + z e12)
for the unit quaternion (w, x, y, z). Acts by X -> M X ~M; on a point it gives R x + t
(metres), so from_matrix(T_a_b) maps frame-b coordinates into frame a. a * b applies b
first. interpolate(a, b, s) slerps the rotation and lerps the translation (not a screw
motion). from_multivector checks the motor space and M~M = 1 (P5 (34)-(35)).)")
      .def(py::init<>())
      .def_static("from_matrix", &cga::Motor::fromMatrix)
      .def_static("from_quaternion",
                  [](const Eigen::Vector4d& wxyz, const Eigen::Vector3d& t) {
                    return cga::Motor::fromQuaternion(Eigen::Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]), t);
                  })
      .def_static("from_multivector", &cga::Motor::fromMultivector, py::arg("M"), py::arg("tol") = 1e-8)
      .def_static("interpolate", &cga::Motor::interpolate)
      .def_property_readonly("multivector", &cga::Motor::multivector)
      .def("rotor", &cga::Motor::rotor)
      .def("quaternion",
           [](const cga::Motor& M) {
             const auto q = M.quaternion();
             return Eigen::Vector4d(q.w(), q.x(), q.y(), q.z());
           })
      .def("translation", &cga::Motor::translation)
      .def("matrix", &cga::Motor::matrix)
      .def("inverse", &cga::Motor::inverse)
      .def("__mul__", [](const cga::Motor& a, const cga::Motor& b) { return a * b; }, py::is_operator())
      .def("apply_multivector", [](const cga::Motor& M, const Multivector& X) { return M.apply(X); })
      .def("apply_point", [](const cga::Motor& M, const Eigen::Vector3d& x) { return M.apply(x); })
      .def("apply_plane", [](const cga::Motor& M, const cga::Plane& p) { return M.apply(p); })
      .def("apply_sphere", [](const cga::Motor& M, const cga::Sphere& s) { return M.apply(s); })
      .def("apply_line", [](const cga::Motor& M, const cga::Line& l) { return M.apply(l); })
      .def("apply_points", [](const cga::Motor& M, const RowArray& x) {
        checkRows(x, 3, "points");
        const py::ssize_t n = x.shape(0);
        py::array_t<double> out({n, py::ssize_t{3}});
        const Multivector Mm = M.multivector(), Mr = Mm.reverse();
        for (py::ssize_t i = 0; i < n; ++i) {
          const Eigen::Vector3d p = Eigen::Map<const Eigen::Vector3d>(x.data() + 3 * i);
          Eigen::Map<Eigen::Vector3d>(out.mutable_data() + 3 * i) = cga::down(Mm * cga::up(p) * Mr);
        }
        return out;
      })
      .def("__repr__", [](const cga::Motor& M) {
        const auto q = M.quaternion();
        return "Motor(quaternion_wxyz=[" + fmt(q.w()) + ", " + fmt(q.x()) + ", " + fmt(q.y()) + ", " + fmt(q.z()) +
               "], translation=" + fmt(M.translation()) + ")";
      });

  py::enum_<cga::Reality>(m, "Reality")
      .value("real", cga::Reality::Real)
      .value("tangent", cga::Reality::Tangent)
      .value("imaginary", cga::Reality::Imaginary);
  m.def("point_pair_reality", &cga::pointPairReality, py::arg("Q"), py::arg("tol") = 1e-10);

  py::class_<cga::PointPair>(m, "PointPair", R"(Point pair, held as the direct 2-blade Q = PA^PB (4.62).

Build with from_points(a, b) (metres), from_direct(Q) or from_dual(Q*) (a meet result such as
meet_plane_circle). reality() is the sign of Q^2 (thesis (4.70)-(4.73)); points() gives (P-, P+) of (4.63),
i.e. (a, b) for from_points(a, b), and raises ValueError for an imaginary pair.)")
      .def_static("from_points", &cga::PointPair::fromPoints, py::arg("a"), py::arg("b"))
      .def_static("from_direct", &cga::PointPair::fromDirect, py::arg("Q"))
      .def_static("from_dual", &cga::PointPair::fromDual, py::arg("Q_dual"))
      .def_readonly("direct", &cga::PointPair::direct)
      .def("dual", &cga::PointPair::dual)
      .def("square", &cga::PointPair::square)
      .def("reality", &cga::PointPair::reality, py::arg("tol") = 1e-10)
      .def("points", &cga::PointPair::points)
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
      });
  py::class_<cga::FlatPoint>(m, "FlatPoint", R"(Flat point P^einf (4.69), e.g. the line-plane meet (4.73); location() in metres.)")
      .def_static("at", &cga::FlatPoint::at, py::arg("p"))
      .def_static("from_multivector", &cga::FlatPoint::fromMultivector, py::arg("F"))
      .def_readonly("direct", &cga::FlatPoint::direct)
      .def("location", &cga::FlatPoint::location)
      .def("__repr__", [](const cga::FlatPoint& f) { return "FlatPoint(" + fmt(f.location()) + ")"; });
  m.def("meet_line_plane_flat", &cga::meetLinePlaneFlat);
  m.def("meet_plane_circle_pair", &cga::meetPlaneCirclePair);

  m.def("normalise_blade", &cga::normaliseBlade);
  m.def("euclidean_dual", &cga::euclideanDual);
  m.def("rotation_plane_from_axis", &cga::rotationPlaneFromAxis);
  m.def("rotation_axis", &cga::rotationAxis);
  m.def("signed_angle", py::overload_cast<const Eigen::Vector3d&, const Eigen::Vector3d&, const Multivector&>(&cga::signedAngle));
  m.def("signed_angle_mv", py::overload_cast<const Multivector&, const Multivector&, const Multivector&>(&cga::signedAngle));
  m.def("rotation_plane_perpendicular_to_line", py::overload_cast<const Multivector&>(&cga::rotationPlanePerpendicularToLine));
  m.def("rotation_plane_perpendicular_to_line_typed", py::overload_cast<const cga::Line&>(&cga::rotationPlanePerpendicularToLine));
  m.def("rotation_plane_parallel_to_plane", py::overload_cast<const Multivector&>(&cga::rotationPlaneParallelToPlane));
  m.def("rotation_plane_parallel_to_plane_typed", py::overload_cast<const cga::Plane&>(&cga::rotationPlaneParallelToPlane));
  m.def("point_pair_points", &cga::pointPairPoints);
  m.def("flat_point_location", &cga::flatPointLocation);
  m.def("round_center", &cga::roundCenter);
  m.def("round_radius2", &cga::roundRadius2);
  m.def("rotor", &cga::rotor);
  m.def("translator", &cga::translator);
  m.def("meet_sphere_plane", &cga::meetSpherePlane);
  m.def("meet_planes", &cga::meetPlanes);
  m.def("meet_spheres", &cga::meetSpheres);
  m.def("meet_plane_circle", &cga::meetPlaneCircle);
  m.def("meet_line_plane", &cga::meetLinePlane);
  m.def("point_distance", &cga::pointDistance);
  m.def("point_plane_distance", &cga::pointPlaneDistance);
  m.def("sphere_point_inner", &cga::spherePointInner);
  m.def("point_sphere_distance", &cga::pointSphereDistance);

  // std::invalid_argument and std::domain_error reach Python as ValueError (pybind11 defaults).
}

}  // namespace scanalign::python

// Typed CGA objects (Kleppe, PhD thesis, NTNU 2018, (4.54)-(4.69), and its Papers 1, 4, 5): points, dual spheres and planes, lines,
// point pairs, flat points, rotors, translators, motors; meets, distances and the 5x5
// matrix form of the inner product. Units: metres and radians.
#pragma once

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "scanalign/cga/multivector.hpp"

namespace scanalign::cga {

using Vector3 = Eigen::Vector3d;
using Vector5 = Eigen::Matrix<double, 5, 1>;
using Matrix5 = Eigen::Matrix<double, 5, 5>;

/// Largest coordinate (metres) or length the objects accept: up(x) squares |x| (4.54) and the
/// products square again, so 1e150 keeps every coefficient of a point, sphere, plane, line or
/// motor built from it finite in double precision (max ~1.8e308). Beyond it a ValueError
/// ("overflow") is raised instead of returning an object with inf or NaN coefficients.
inline constexpr double kMaxCoordinate = 1e150;

namespace detail {
inline void requireFinite(const Vector3& v, const char* what) {
  if (!v.allFinite()) throw std::invalid_argument(std::string("cga: ") + what + " is not finite");
}
inline void requireFinite(double v, const char* what) {
  if (!std::isfinite(v)) throw std::invalid_argument(std::string("cga: ") + what + " is not finite");
}
/// Finite and within kMaxCoordinate: a position (metres) or a length that gets squared.
inline void requireCoordinate(const Vector3& v, const char* what) {
  requireFinite(v, what);
  if (v.cwiseAbs().maxCoeff() > kMaxCoordinate)
    throw std::invalid_argument(std::string("cga: ") + what + ": overflow: coordinates beyond ~1e150 m");
}
inline void requireCoordinate(double v, const char* what) {
  requireFinite(v, what);
  if (std::abs(v) > kMaxCoordinate)
    throw std::invalid_argument(std::string("cga: ") + what + ": overflow: values beyond ~1e150 m");
}
/// |v| without overflow for components up to DBL_MAX (|n| of a 1e300 normal is not inf).
inline double safeNorm(const Vector3& v) { return v.stableNorm(); }
inline void requireFinite(const Multivector& m, const char* what) {
  if (!m.allFinite()) throw std::invalid_argument(std::string("cga: ") + what + " is not finite");
}
inline Vector3 euclidean(const Multivector& m) {
  const auto& c = m.orthonormal();
  return {c[1], c[2], c[4]};
}
}  // namespace detail

// ---------------------------------------------------------------------------
// Vector (grade-1) coefficients and the matrix form (4.55), (4.60), (4.66), (5.32)
// ---------------------------------------------------------------------------

/// Coefficients of a conformal vector in the order (e1, e2, e3, einf, e0) (thesis (4.55), (4.60), (4.66)).
inline Vector5 toVector5(const Multivector& v) {
  const auto n = v.nullCoefficients();
  return {n[2], n[4], n[8], n[16], n[1]};
}
inline Multivector fromVector5(const Vector5& x) {
  Multivector::Coeffs n = Multivector::Coeffs::Zero();
  n[2] = x[0];
  n[4] = x[1];
  n[8] = x[2];
  n[16] = x[3];
  n[1] = x[4];
  return Multivector::fromNull(n);
}
/// M with X . Y = [X]^T M [Y] for vectors in (e1, e2, e3, einf, e0) coefficients (5.32).
inline Matrix5 innerProductMatrix() {
  Matrix5 M = Matrix5::Zero();
  M(0, 0) = M(1, 1) = M(2, 2) = 1;
  M(3, 4) = M(4, 3) = -1;
  return M;
}

// ---------------------------------------------------------------------------
// Points (4.54)
// ---------------------------------------------------------------------------

/// up(x) = x + 1/2 x^2 einf + e0 (4.54).
inline Multivector up(const Vector3& x) {
  detail::requireCoordinate(x, "point");
  return fromVector5((Vector5() << x, 0.5 * x.squaredNorm(), 1.0).finished());
}
/// Euclidean point of a (possibly scaled) conformal point: x = P / (-einf . P), Euclidean part.
/// Throws when -einf . P is 0 (a point at infinity / not a point).
inline Vector3 down(const Multivector& P) {
  detail::requireFinite(P, "point");
  const Vector5 v = toVector5(P);
  const double w = v[4];
  if (!(std::abs(w) > 1e-12 * std::max(1.0, v.head<3>().norm())))
    throw std::domain_error("cga: down() of a multivector with zero e0 coefficient (not a finite point)");
  const Vector3 x = v.head<3>() / w;
  detail::requireCoordinate(x, "down() result");
  return x;
}
/// P scaled so that -einf . P = 1 (e0 coefficient 1).
inline Multivector normalisePoint(const Multivector& P) { return up(down(P)); }

// ---------------------------------------------------------------------------
// Dual sphere S* = up(c) - 1/2 r^2 einf (4.59), dual plane Pi* = n + delta einf (4.65)
// ---------------------------------------------------------------------------

struct Sphere {
  Vector3 center = Vector3::Zero();
  /// Squared radius, m^2; negative for an imaginary sphere (S*^2 < 0, (4.61)).
  double radius2 = 0;

  Sphere() = default;
  Sphere(const Vector3& c, double radius) : center(c), radius2(radius * radius) {
    detail::requireCoordinate(c, "sphere centre");
    detail::requireCoordinate(radius, "sphere radius");
    if (radius < 0) throw std::invalid_argument("cga: sphere radius must be >= 0");
  }
  static Sphere withRadius2(const Vector3& c, double r2) {
    Sphere s;
    detail::requireCoordinate(c, "sphere centre");
    detail::requireFinite(r2, "sphere radius^2");
    if (std::abs(r2) > kMaxCoordinate * kMaxCoordinate)
      throw std::invalid_argument("cga: sphere radius^2: overflow: radius beyond ~1e150 m");
    s.center = c;
    s.radius2 = r2;
    return s;
  }
  bool isReal() const { return radius2 >= 0; }
  /// Radius, m; throws for an imaginary sphere.
  double radius() const {
    if (radius2 < 0) throw std::domain_error("cga: imaginary sphere has no real radius");
    return std::sqrt(radius2);
  }
  /// The dual (IPNS) sphere S* (4.59), e0-normalised.
  Multivector dual() const { return up(center) - Multivector::eInf() * (0.5 * radius2); }
  /// From any scaled dual sphere; r^2 = S*^2/(einf.S*)^2 (thesis (4.61), any scale). Throws for a plane
  /// (e0 coefficient ~ 0) or a multivector that is not a vector.
  static Sphere fromDual(const Multivector& S) {
    detail::requireFinite(S, "sphere");
    if ((S - S.grade(1)).maxAbs() > 1e-9 * std::max(1.0, S.maxAbs()))
      throw std::invalid_argument("cga: a dual sphere must be a vector (grade 1)");
    const Vector5 v = toVector5(S);
    if (!(std::abs(v[4]) > 1e-12 * std::max(1.0, v.norm())))
      throw std::domain_error("cga: e0 coefficient is 0: this is a plane, not a sphere");
    const Vector5 u = v / v[4];
    return withRadius2(u.head<3>(), u.head<3>().squaredNorm() - 2 * u[3]);
  }
  /// From the direct sphere S = PA^PB^PC^PD (4.58) (any orientation).
  static Sphere fromDirect(const Multivector& S) { return fromDual(S.dual()); }
  static Sphere throughPoints(const Vector3& a, const Vector3& b, const Vector3& c, const Vector3& d) {
    return fromDirect(up(a).outer(up(b)).outer(up(c)).outer(up(d)));
  }
};

struct Plane {
  Vector3 normal = Vector3::UnitZ();  ///< unit normal
  double distance = 0;                ///< signed distance from the origin along the normal, m

  Plane() = default;
  /// n need not be unit (it is normalised); throws for a zero normal.
  Plane(const Vector3& n, double delta) {
    detail::requireFinite(n, "plane normal");
    detail::requireCoordinate(delta, "plane distance");
    const double l = detail::safeNorm(n);
    if (!(l > 1e-12)) throw std::invalid_argument("cga: plane normal is zero");
    normal = n / l;
    distance = delta / l;
  }
  static Plane throughPoint(const Vector3& n, const Vector3& p) {
    detail::requireCoordinate(p, "plane point");
    const Plane q(n, 0.0);
    return Plane(q.normal, q.normal.dot(p));
  }
  /// Pi* = n + delta einf (4.65).
  Multivector dual() const { return Multivector::vector(normal) + Multivector::eInf() * distance; }
  /// Direct plane Pi = Pi* Ic (undual, (4.51)).
  Multivector direct() const { return dual().undual(); }
  /// From a scaled dual plane (normalised so |n| = 1; the orientation kept).
  static Plane fromDual(const Multivector& P) {
    detail::requireFinite(P, "plane");
    if ((P - P.grade(1)).maxAbs() > 1e-9 * std::max(1.0, P.maxAbs()))
      throw std::invalid_argument("cga: a dual plane must be a vector (grade 1)");
    const Vector5 v = toVector5(P);
    const double l = v.head<3>().norm();
    if (!(l > 1e-12) || std::abs(v[4]) > 1e-9 * l)
      throw std::domain_error("cga: not a plane (e0 coefficient must be 0 and the normal non-zero)");
    return Plane(v.head<3>(), v[3]);
  }
  /// From the direct plane PA^PB^PC^einf (4.64). The orientation follows the dual
  /// convention (with the dual of thesis (4.50): the plane through (0,0,1),(1,0,1),(0,1,1) gives -(e3 + einf)).
  static Plane fromDirect(const Multivector& P) { return fromDual(P.dual()); }
  static Plane throughPoints(const Vector3& a, const Vector3& b, const Vector3& c) {
    return fromDirect(up(a).outer(up(b)).outer(up(c)).outer(Multivector::eInf()));
  }
};

// ---------------------------------------------------------------------------
// Lines (4.68): L = PA^PB^einf = (p + e0)^d^einf (P4)
// ---------------------------------------------------------------------------

struct Line {
  Vector3 point = Vector3::Zero();          ///< closest point to the origin, m
  Vector3 direction = Vector3::UnitZ();     ///< unit direction

  Line() = default;
  Line(const Vector3& p, const Vector3& d) {
    detail::requireCoordinate(p, "line point");
    detail::requireFinite(d, "line direction");
    const double l = detail::safeNorm(d);
    if (!(l > 1e-12)) throw std::invalid_argument("cga: line direction is zero");
    direction = d / l;
    point = p - direction * direction.dot(p);
  }
  static Line throughPoints(const Vector3& a, const Vector3& b) { return Line(a, b - a); }
  /// Direct line (p + e0)^d^einf (P4), = up(a)^up(a+d)^einf (4.68).
  Multivector direct() const {
    return (Multivector::vector(point) + Multivector::e0()).outer(Multivector::vector(direction)).outer(Multivector::eInf());
  }
  /// Dual line l* = A + b einf (Paper 4 §2.1).
  Multivector dual() const { return direct().dual(); }
  /// From a direct line (any scale). The direction is the e0^ei^einf part (= -(L.e0).einf
  /// of (4.68) by Paper 1 eq. (18)); the moment p^d is the ei^ej^einf part.
  static Line fromDirect(const Multivector& L) {
    detail::requireFinite(L, "line");
    const auto n = L.nullCoefficients();
    // e0^ei^einf: bits 1|2^i|16 ; ei^ej^einf: bits 2^i|2^j|16
    const Vector3 d(n[1 | 2 | 16], n[1 | 4 | 16], n[1 | 8 | 16]);
    const Vector3 m(n[4 | 8 | 16], -n[2 | 8 | 16], n[2 | 4 | 16]);  // (p^d) as p x d: (e23, e31, e12)
    const double l2 = d.squaredNorm();
    if (!(l2 > 1e-24)) throw std::domain_error("cga: not a line (zero direction)");
    return Line(d.cross(m) / l2, d);
  }
  static Line fromDual(const Multivector& Ls) { return fromDirect(Ls.undual()); }
};

// ---------------------------------------------------------------------------
// Angles and rotation planes (Paper 1 §3.7, eqs. (12)-(21))
// ---------------------------------------------------------------------------

/// A / sqrt(|<A ~A>_0|) (Paper 1 §3.7 normalisation). Throws for a (near) null blade.
inline Multivector normaliseBlade(const Multivector& A) {
  detail::requireFinite(A, "blade");
  const double n2 = std::abs(A.scalarProduct(A.reverse()));
  if (!(n2 > 1e-24 * std::max(1e-300, A.orthonormal().squaredNorm())) || !(n2 > 0))
    throw std::domain_error("cga: cannot normalise a null or zero blade");
  return A / std::sqrt(n2);
}
/// Euclidean dual A I3^{-1} (thesis (4.18)-(4.51), (4.39)); I3^{-1} = -I3.
inline Multivector euclideanDual(const Multivector& A) { return -(A * Multivector::pseudoscalar3()); }
/// Unit rotation plane N (a Euclidean unit bivector) whose Euclidean dual N* = N I3^{-1} is the
/// unit `axis`: N = n I3 (e.g. axis e3 -> N = e12). A rotation by +theta about the axis
/// (right-handed) turns a vector in N by +theta in the sense of (17).
inline Multivector rotationPlaneFromAxis(const Vector3& axis) {
  detail::requireFinite(axis, "rotation axis");
  const double l = detail::safeNorm(axis);
  if (!(l > 1e-12)) throw std::invalid_argument("cga: rotation axis is zero");
  return Multivector::vector(axis / l) * Multivector::pseudoscalar3();
}
/// The unit rotation axis N* = N I3^{-1} of a Euclidean bivector N (normalised). Throws when N
/// has components outside e12, e13, e23 or is zero.
inline Vector3 rotationAxis(const Multivector& N) {
  detail::requireFinite(N, "rotation plane");
  const auto& c = N.orthonormal();
  const double e = Eigen::Vector3d(c[3], c[5], c[6]).norm();
  if (!(e > 1e-12)) throw std::domain_error("cga: rotation plane is zero");
  Multivector rest = N;
  rest.orthonormal()[3] = rest.orthonormal()[5] = rest.orthonormal()[6] = 0;
  if (rest.maxAbs() > 1e-9 * e) throw std::invalid_argument("cga: a rotation plane is a Euclidean bivector (e12, e13, e23 only)");
  return detail::euclidean(euclideanDual(N)).normalized();
}

/// Signed angle (rad, in (-pi, pi]) from direction a to direction b in the rotation plane N,
/// theta = atan2((a^b) N^{-1}, a.b) (17) (scalar part; N^{-1} = ~N = -N for a unit bivector).
/// Any scale of a, b and N > 0 is allowed (N is normalised, Paper 1 §3.7). For a, b perpendicular
/// to N* this is the right-handed angle about the axis N* (Paper 1 eq. (17)); components along N* do
/// not enter (a^b is projected onto N by the scalar part).
inline double signedAngle(const Multivector& a, const Multivector& b, const Multivector& N) {
  detail::requireFinite(a, "direction a");
  detail::requireFinite(b, "direction b");
  const Multivector Nu = normaliseBlade(N);
  const double s = (a.outer(b) * Nu.inverse()).scalar();  // (a^b) N^{-1}, (13)-(17)
  const double c = a.inner(b).scalar();                   // a.b = |a||b| cos(theta) (12)
  return std::atan2(s, c);
}
inline double signedAngle(const Vector3& a, const Vector3& b, const Multivector& N) {
  return signedAngle(Multivector::vector(a), Multivector::vector(b), N);
}

/// Rotation plane perpendicular to a line, N = (L* ^ einf) . e0 / |.| (20), from the dual
/// line L*. For L = up(a)^up(b)^einf (4.68) its Euclidean dual N* is (b - a)/|b - a|
/// (Paper 1 §3.7; checked in the tests).
inline Multivector rotationPlanePerpendicularToLine(const Multivector& dualLine) {
  detail::requireFinite(dualLine, "dual line");
  return normaliseBlade(dualLine.outer(Multivector::eInf()).inner(Multivector::e0()));
}
inline Multivector rotationPlanePerpendicularToLine(const Line& l) { return rotationPlanePerpendicularToLine(l.dual()); }
/// Rotation plane parallel to a plane, N = (Pi . e0) . einf / |.| (21), from the direct plane
/// Pi (4.64). For Pi = up(a)^up(b)^up(c)^einf the axis N* is (b - a) x (c - a)/|.|, which is
/// MINUS the normal n of the dual Pi* = Pi Ic^{-1} = n + delta einf (tested).
inline Multivector rotationPlaneParallelToPlane(const Multivector& directPlane) {
  detail::requireFinite(directPlane, "direct plane");
  return normaliseBlade(directPlane.inner(Multivector::e0()).inner(Multivector::eInf()));
}
/// (21) for a typed plane, oriented explicitly (the orientation of (4.64) depends on the dual convention) so that the axis N* = p.normal.
inline Multivector rotationPlaneParallelToPlane(const Plane& p) { return -rotationPlaneParallelToPlane(p.direct()); }

// ---------------------------------------------------------------------------
// Point pairs Q = PA^PB (4.62), (4.63), thesis (4.70)-(4.73)
// ---------------------------------------------------------------------------

enum class Reality { Real, Tangent, Imaginary };

/// Q^2 = Q.Q sign test (thesis (4.70)-(4.73)): >0 real, =0 tangent, <0 imaginary. `tol` is relative to
/// the squared magnitude of Q.
inline Reality pointPairReality(const Multivector& Q, double tol = 1e-10) {
  detail::requireFinite(Q, "point pair");
  const double q2 = (Q * Q).scalar();
  const double s = Q.orthonormal().squaredNorm();
  if (q2 > tol * s) return Reality::Real;
  if (q2 < -tol * s) return Reality::Imaginary;
  return Reality::Tangent;
}

/// The two points of a direct point pair: P+- = (Q +- sqrt(Q^2)) / (-einf . Q) (4.63);
/// for Q = up(a)^up(b), first = a ("-"), second = b ("+"). Throws for an imaginary pair
/// or a pair with a point at infinity; a tangent pair returns the touching point twice.
inline std::pair<Vector3, Vector3> pointPairPoints(const Multivector& Q) {
  const Reality r = pointPairReality(Q);
  if (r == Reality::Imaginary) throw std::domain_error("cga: imaginary point pair (Q^2 < 0): no real points");
  const double q2 = std::max(0.0, (Q * Q).scalar());
  const double s = r == Reality::Tangent ? 0.0 : std::sqrt(q2);
  const Multivector d = -(Multivector::eInf().inner(Q));
  const Multivector dinv = d.inverse();
  const Multivector Pm = (Q - Multivector(s)) * dinv;
  const Multivector Pp = (Q + Multivector(s)) * dinv;
  return {down(Pm), down(Pp)};
}

/// Direct point pair through two points.
inline Multivector pointPair(const Vector3& a, const Vector3& b) { return up(a).outer(up(b)); }

/// Flat point P^einf (4.69); its location from any scaled flat point.
inline Multivector flatPoint(const Vector3& p) { return up(p).outer(Multivector::eInf()); }
inline Vector3 flatPointLocation(const Multivector& F) {
  detail::requireFinite(F, "flat point");
  const auto n = F.nullCoefficients();
  // up(p)^einf = p^einf + e0^einf: coefficients ei^einf = p_i, e0^einf = 1.
  const double w = n[1 | 16];
  if (!(std::abs(w) > 1e-12 * std::max(1.0, F.maxAbs()))) throw std::domain_error("cga: not a flat point");
  return Vector3(n[2 | 16], n[4 | 16], n[8 | 16]) / w;
}

/// Typed point pair (thesis (4.62)-(4.63)): holds the direct 2-blade Q = PA^PB (4.62); its dual
/// Q* = Q Ic^{-1} is what meets such as Pi* ^ C* return (4.70).
struct PointPair {
  Multivector direct;  ///< Q, a grade-2 blade

  PointPair() = default;
  /// Q = up(a) ^ up(b) (4.62); points() returns (a, b) (thesis (4.63)).
  static PointPair fromPoints(const Vector3& a, const Vector3& b) { return fromDirect(pointPair(a, b)); }
  /// From a direct pair (any scale; a negative scale swaps the two points). Throws unless Q
  /// is a non-zero grade-2 multivector.
  static PointPair fromDirect(const Multivector& Q) {
    detail::requireFinite(Q, "point pair");
    const double m = Q.maxAbs();
    if (!(m > 0)) throw std::invalid_argument("cga: point pair is zero");
    if ((Q - Q.grade(2)).maxAbs() > 1e-9 * m) throw std::invalid_argument("cga: a direct point pair has grade 2 only");
    PointPair q;
    q.direct = Q;
    return q;
  }
  /// From a dual pair Q* (grade 3), e.g. meetPlaneCircle: Q = Q* Ic (undual, (4.51)).
  static PointPair fromDual(const Multivector& Qs) { return fromDirect(Qs.undual()); }
  Multivector dual() const { return direct.dual(); }
  /// Q^2 = Q.Q (a scalar for a 2-blade): (1/2 |a - b|^2)^2 for Q = up(a)^up(b) (thesis (4.62)-(4.63)).
  double square() const { return (direct * direct).scalar(); }
  /// Sign of Q^2 (thesis (4.70)-(4.73)): real (> 0), tangent (= 0, within tol relative to |Q|^2), imaginary.
  Reality reality(double tol = 1e-10) const { return pointPairReality(direct, tol); }
  /// (P-, P+) of (4.63) as Euclidean points, m; throws std::domain_error for an imaginary pair.
  std::pair<Vector3, Vector3> points() const { return pointPairPoints(direct); }
};

/// Typed flat point P ^ einf (4.69), e.g. the line-plane meet Pi* . L (4.73).
struct FlatPoint {
  Multivector direct;  ///< up(p) ^ einf, any non-zero scale

  FlatPoint() : direct(flatPoint(Vector3::Zero())) {}
  static FlatPoint at(const Vector3& p) { return fromMultivector(flatPoint(p)); }
  /// Checks the grade (2) and that a finite location exists (e0^einf coefficient non-zero).
  static FlatPoint fromMultivector(const Multivector& F) {
    detail::requireFinite(F, "flat point");
    if ((F - F.grade(2)).maxAbs() > 1e-9 * std::max(1.0, F.maxAbs()))
      throw std::invalid_argument("cga: a flat point has grade 2 only");
    flatPointLocation(F);  // throws when there is no finite location
    FlatPoint f;
    f.direct = F;
    return f;
  }
  /// Location, m.
  Vector3 location() const { return flatPointLocation(direct); }
};

// ---------------------------------------------------------------------------
// Rounds (circles from three points); centre and radius of direct rounds
// ---------------------------------------------------------------------------

/// Direct circle through three points (4.57).
inline Multivector circle(const Vector3& a, const Vector3& b, const Vector3& c) {
  return up(a).outer(up(b)).outer(up(c));
}
/// Centre of a direct round (point pair, circle, sphere): X einf X (normalised).
inline Vector3 roundCenter(const Multivector& X) { return down(X * Multivector::eInf() * X); }
/// Squared radius of a direct round (point pair, circle, sphere):
/// rho^2 = <X X^>_0 / <D D>_0 with D = einf _| X and ^ the grade involution (Dorst et al.
/// 2007, §14.2; checked against circles and point pairs through known points).
inline double roundRadius2(const Multivector& X) {
  detail::requireFinite(X, "round");
  const Multivector d = Multivector::eInf().leftContraction(X);
  const double den = (d * d).scalar();
  if (!(std::abs(den) > 1e-12 * std::max(1e-300, X.orthonormal().squaredNorm())))
    throw std::domain_error("cga: not a finite round");
  return (X * X.involute()).scalar() / den;
}

/// A Euclidean point (metres) held with its conformal point up(x) (4.54).
struct Point {
  Vector3 position = Vector3::Zero();  ///< m

  Point() = default;
  explicit Point(const Vector3& x) : position(x) { detail::requireCoordinate(x, "point"); }
  /// From a conformal point of any scale (down(), throws for a point at infinity).
  static Point fromMultivector(const Multivector& P) { return Point(down(P)); }
  Multivector multivector() const { return up(position); }
};

/// A circle: centre and radius (metres) and the unit normal of its carrier plane. Its direct
/// form is up(a) ^ up(b) ^ up(c) for three points on it (4.57).
struct Circle {
  Vector3 center = Vector3::Zero();   ///< m
  Vector3 normal = Vector3::UnitZ();  ///< unit normal of the carrier plane
  double radius = 0;                  ///< m

  Circle() = default;
  Circle(const Vector3& c, const Vector3& n, double r) : center(c), radius(r) {
    detail::requireCoordinate(c, "circle centre");
    detail::requireFinite(n, "circle normal");
    detail::requireCoordinate(r, "circle radius");
    const double l = detail::safeNorm(n);
    if (!(l > 1e-12)) throw std::invalid_argument("cga: circle normal is zero");
    if (r < 0) throw std::invalid_argument("cga: circle radius must be >= 0");
    normal = n / l;
  }
  static Circle throughPoints(const Vector3& a, const Vector3& b, const Vector3& c) {
    return fromDirect(circle(a, b, c));
  }
  /// From any direct circle C: centre C einf C, radius^2 from roundRadius2, normal from the
  /// plane C ^ einf (4.64). Throws for an imaginary circle (radius^2 < 0) or a line (a circle
  /// through infinity).
  static Circle fromDirect(const Multivector& C) {
    const double r2 = roundRadius2(C);
    if (r2 < 0) throw std::domain_error("cga: imaginary circle (radius^2 = " + std::to_string(r2) + ")");
    return Circle(roundCenter(C), Plane::fromDirect(C.outer(Multivector::eInf())).normal, std::sqrt(r2));
  }
  /// From a dual circle C*, e.g. meetSpherePlane (its undual C* Ic is the direct circle).
  static Circle fromDual(const Multivector& Cs) { return fromDirect(Cs.undual()); }
  /// up(a) ^ up(b) ^ up(c) for three points of the circle (4.57).
  Multivector direct() const {
    Vector3 u = normal.cross(Vector3::UnitX());
    if (u.norm() < 0.5) u = normal.cross(Vector3::UnitY());
    u.normalize();
    const Vector3 v = normal.cross(u);
    return circle(center + radius * u, center + radius * v, center - radius * u);
  }
  Multivector dual() const { return direct().dual(); }
};

// ---------------------------------------------------------------------------
// Meets (4.70)-(4.73): dual results M* = A*^B*
// ---------------------------------------------------------------------------

/// Dual circle C* = Pi* ^ S* (sphere meet plane).
inline Multivector meetSpherePlane(const Sphere& s, const Plane& p) { return p.dual().outer(s.dual()); }
/// Dual line L* = Pi1* ^ Pi2*.
inline Multivector meetPlanes(const Plane& a, const Plane& b) { return a.dual().outer(b.dual()); }
/// Dual circle C* = S1* ^ S2*.
inline Multivector meetSpheres(const Sphere& a, const Sphere& b) { return a.dual().outer(b.dual()); }
/// Dual point pair Q* = Pi* ^ C* for a dual circle C*; the direct pair is Q*.undual().
inline Multivector meetPlaneCircle(const Plane& p, const Multivector& dualCircle) { return p.dual().outer(dualCircle); }
/// Flat point Pi* . L (4.73) for a direct line L.
inline Multivector meetLinePlane(const Line& l, const Plane& p) { return p.dual().inner(l.direct()); }
/// Typed line-plane meet (4.73).
inline FlatPoint meetLinePlaneFlat(const Line& l, const Plane& p) { return FlatPoint::fromMultivector(meetLinePlane(l, p)); }
/// Typed plane-circle meet: the point pair of the dual circle C* and the plane (4.70).
inline PointPair meetPlaneCirclePair(const Plane& p, const Multivector& dualCircle) {
  return PointPair::fromDual(meetPlaneCircle(p, dualCircle));
}

// ---------------------------------------------------------------------------
// Distances (4.56), (4.67), P5(10)
// ---------------------------------------------------------------------------

// The inner products below are invariant under translations (a rigid motion preserves X . Y),
// and each is evaluated with its first argument moved to the origin. Evaluated in place, the
// null vectors of points far from the origin carry 1/2 |x|^2 in both e+ and e-, and the products
// cancel them: at |x| = 1e6 m the distance of two points 1 m apart came out as 8192 m.

/// |a - b| from d^2 = -2 PA.PB (4.56), with a moved to the origin (PA = e0).
inline double pointDistance(const Vector3& a, const Vector3& b) {
  detail::requireCoordinate(a, "point");
  return std::sqrt(std::max(0.0, -2.0 * Multivector::e0().inner(up(b - a)).scalar()));
}
/// Signed distance P.Pi* = p.n - delta (4.67): positive on the side the normal points to.
inline double pointPlaneDistance(const Vector3& x, const Plane& p) {
  detail::requireCoordinate(x, "point");
  return Multivector::e0().inner(Plane(p.normal, p.distance - p.normal.dot(x)).dual()).scalar();
}
/// S*.P = 1/2 (r^2 - |p-c|^2) (Paper 5 eq. (10)): > 0 inside, 0 on, < 0 outside.
inline double spherePointInner(const Sphere& s, const Vector3& x) {
  detail::requireCoordinate(x, "point");
  return Sphere::withRadius2(Vector3::Zero(), s.radius2).dual().inner(up(x - s.center)).scalar();
}
/// Distance from the sphere's centre, d_c^2 = S.S - 2 S.P (P5(10)).
inline double pointSphereCenterDistance(const Vector3& x, const Sphere& s) {
  detail::requireCoordinate(x, "point");
  const Multivector S = Sphere::withRadius2(Vector3::Zero(), s.radius2).dual();
  return std::sqrt(std::max(0.0, S.inner(S).scalar() - 2 * S.inner(up(x - s.center)).scalar()));
}
/// Signed distance to the surface of a real sphere: |x - c| - r (> 0 outside).
inline double pointSphereDistance(const Vector3& x, const Sphere& s) {
  return pointSphereCenterDistance(x, s) - s.radius();
}

// ---------------------------------------------------------------------------
// Rotors, translators, motors (Paper 4 §3.5, Paper 5 eqs. (33)-(35))
// ---------------------------------------------------------------------------

/// Rotor of a unit quaternion (w, x, y, z): R = w - (x e23 + y e31 + z e12) (Paper 4 §3.5).
inline Multivector rotorFromQuaternion(const Eigen::Quaterniond& q) {
  const Eigen::Quaterniond u = q.normalized();
  Multivector R(u.w());
  R.orthonormal()[6] = -u.x();   // e23
  R.orthonormal()[5] = u.y();    // e13 = -e31
  R.orthonormal()[3] = -u.z();   // e12
  return R;
}
/// R = cos(theta/2) - sin(theta/2) B, B = axis* (unit bivector), right-handed about axis.
inline Multivector rotor(const Vector3& axis, double angle) {
  detail::requireFinite(axis, "rotation axis");
  detail::requireFinite(angle, "rotation angle");
  const double l = detail::safeNorm(axis);
  if (!(l > 1e-12)) throw std::invalid_argument("cga: rotation axis is zero");
  return rotorFromQuaternion(Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis / l)));
}
/// T = 1 - 1/2 t einf (Paper 4 §3.5).
inline Multivector translator(const Vector3& t) {
  detail::requireCoordinate(t, "translation");
  return Multivector(1.0) - Multivector::vector(t).outer(Multivector::eInf()) * 0.5;
}

/// A rigid motion M = T R (Paper 4 §3.5) acting by X -> M X ~M; applied to a point it gives
/// R x + t. Stored as the 32-coefficient multivector (8 non-zero, Paper 5 eq. (34)).
class Motor {
 public:
  Motor() : m_(1.0) {}
  static Motor fromRotationTranslation(const Eigen::Matrix3d& R, const Vector3& t) {
    if (!R.allFinite()) throw std::invalid_argument("cga: rotation is not finite");
    if (!(R.transpose() * R - Eigen::Matrix3d::Identity()).isZero(1e-6) || R.determinant() < 0)
      throw std::invalid_argument("cga: matrix is not a rotation");
    return fromQuaternion(Eigen::Quaterniond(R), t);
  }
  static Motor fromMatrix(const Eigen::Matrix4d& T) {
    if (!T.allFinite()) throw std::invalid_argument("cga: transform is not finite");
    if (!T.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1), 1e-12))
      throw std::invalid_argument("cga: last row of a rigid transform must be (0, 0, 0, 1)");
    return fromRotationTranslation(T.topLeftCorner<3, 3>(), T.topRightCorner<3, 1>());
  }
  static Motor fromQuaternion(const Eigen::Quaterniond& q, const Vector3& t) {
    if (!q.coeffs().allFinite() || !(q.norm() > 1e-12)) throw std::invalid_argument("cga: bad quaternion");
    Motor m;
    m.m_ = translator(t) * rotorFromQuaternion(q);
    return m;
  }
  /// From a motor multivector; checks M in the motor space and M~M = 1 (P5 (34)-(35)).
  static Motor fromMultivector(const Multivector& M, double tol = 1e-8) {
    detail::requireFinite(M, "motor");
    const auto& c = M.orthonormal();
    // Motor space span{1, e23, e31, e12, e1inf, e2inf, e3inf, e123inf}: the even grades
    // without e0 components. Check evenness and M~M = 1, and that M einf ~M = einf.
    Multivector odd = M - M.grade(0) - M.grade(2) - M.grade(4);
    if (odd.maxAbs() > tol) throw std::invalid_argument("cga: a motor has even grade only");
    const Multivector mm = M * M.reverse();
    if ((mm - Multivector(1.0)).maxAbs() > tol) throw std::invalid_argument("cga: not a unit motor (M~M != 1)");
    const Multivector ei = M * Multivector::eInf() * M.reverse();
    if ((ei - Multivector::eInf()).maxAbs() > tol * std::max(1.0, c.norm() * c.norm()))
      throw std::invalid_argument("cga: not a rigid motor (einf not preserved)");
    Motor m;
    m.m_ = M;
    return m;
  }
  const Multivector& multivector() const { return m_; }

  /// Rotation part R (a rotor): the grade-0 and Euclidean bivector parts of M.
  Multivector rotor() const {
    const auto& c = m_.orthonormal();
    Multivector R(c[0]);
    R.orthonormal()[3] = c[3];
    R.orthonormal()[5] = c[5];
    R.orthonormal()[6] = c[6];
    return R;
  }
  Eigen::Quaterniond quaternion() const {
    const auto& c = m_.orthonormal();
    Eigen::Quaterniond q(c[0], -c[6], c[5], -c[3]);
    return q.normalized();
  }
  /// t from T = M ~R = 1 - 1/2 t einf.
  Vector3 translation() const {
    const Multivector T = m_ * rotor().reverse();
    return Vector3(-2 * T.get("e1inf"), -2 * T.get("e2inf"), -2 * T.get("e3inf"));
  }
  Eigen::Matrix3d rotationMatrix() const { return quaternion().toRotationMatrix(); }
  Eigen::Matrix4d matrix() const {
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    T.topLeftCorner<3, 3>() = rotationMatrix();
    T.topRightCorner<3, 1>() = translation();
    return T;
  }
  /// Composition: (a * b) applies b first, then a.
  Motor operator*(const Motor& o) const {
    Motor m;
    m.m_ = m_ * o.m_;
    return m;
  }
  Motor inverse() const {
    Motor m;
    m.m_ = m_.reverse();
    return m;
  }
  /// M X ~M for any multivector (points, dual planes/spheres, lines, ...).
  Multivector apply(const Multivector& X) const { return m_ * X * m_.reverse(); }
  Vector3 apply(const Vector3& x) const { return down(apply(up(x))); }
  Plane apply(const Plane& p) const { return Plane::fromDual(apply(p.dual())); }
  Sphere apply(const Sphere& s) const { return Sphere::fromDual(apply(s.dual())); }
  Line apply(const Line& l) const { return Line::fromDirect(apply(l.direct())); }

  /// Interpolation at s in [0, 1]: rotation by quaternion slerp, translation by linear
  /// interpolation (not a screw motion; the endpoints are exact).
  static Motor interpolate(const Motor& a, const Motor& b, double s) {
    detail::requireFinite(s, "interpolation parameter");
    const Eigen::Quaterniond q = a.quaternion().slerp(s, b.quaternion());
    const Vector3 t = (1 - s) * a.translation() + s * b.translation();
    return fromQuaternion(q, t);
  }

 private:
  Multivector m_;
};

}  // namespace scanalign::cga

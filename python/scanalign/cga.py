"""Conformal geometric algebra G(4,1) (Kleppe, PhD thesis, NTNU 2018, ch. 4).

Basis vectors ``e1, e2, e3`` (Euclidean, metres), ``e0`` (origin) and ``einf`` (infinity)
with ``e0 . einf = -1`` and ``e0^2 = einf^2 = 0`` (4.44)-(4.45); internally the orthonormal
``e+ (e+^2 = 1)``, ``e- (e-^2 = -1)`` with ``e0 = (e- - e+)/2``, ``einf = e- + e+``.
Blades are named by their vectors in the order ``e0, e1, e2, e3, einf``: ``m["e1inf"]``
is the coefficient of ``e1^einf``; ``Multivector.null_coefficients()`` gives all 32 in the
order of ``blade_names()`` (index bits: 1 = e0, 2 = e1, 4 = e2, 8 = e3, 16 = einf).

Operators on :class:`Multivector`: ``*`` geometric product, ``^`` outer product, ``|`` inner
product (Hestenes/"fat" ``<A_r B_s>_{|r-s|}``, zero when either grade is 0, as the
``clifford`` package), ``~`` reverse (4.32); ``.dual()`` is ``A Ic^{-1}`` with
``Ic = e0^e1^e2^e3^einf`` and ``Ic^2 = -1`` (4.48)-(4.50), ``.undual()`` is ``A Ic``.

Objects (all coordinates in metres, in the frame the caller works in):

- :func:`up` / :func:`down`: Euclidean points to conformal points
  ``P = x + 1/2 x^2 einf + e0`` (4.54) and back; vectorised over ``(N, 3)`` arrays, where
  conformal points are ``(N, 5)`` arrays of coefficients ``(e1, e2, e3, einf, e0)`` (4.55)
  and :func:`inner_product_matrix` gives ``M`` with ``X . Y = X^T M Y`` (5.32).
- :class:`Sphere` (dual ``S* = up(c) - 1/2 r^2 einf`` (4.59)), :class:`Plane` (dual
  ``Pi* = n + delta einf`` (4.65)), :class:`Line` (direct ``(p + e0)^d^einf`` (4.68)),
  point pairs ``up(a)^up(b)`` (4.62), flat points ``up(p)^einf`` (4.69), circles.
- :class:`Motor` ``M = T R`` with ``T = 1 - 1/2 t einf`` and ``R`` the rotor of the
  quaternion ``(w, x, y, z)``: ``R = w - (x e23 + y e31 + z e12)``; ``M up(x) ~M = up(R x + t)``.
  :meth:`Motor.interpolate` slerps the rotation and lerps the translation (not a screw).
- meets (4.70)-(4.73) return dual objects ``A* ^ B*`` (the line-plane meet returns the
  flat point ``Pi* . L``); distances (4.56), (4.67), P5(10).
- :class:`PointPair` (direct ``Q = PA^PB``; ``reality()`` is the sign of ``Q^2``, thesis (4.70)-(4.73);
  ``points()`` by (4.63)) and :class:`FlatPoint` (``P^einf``, ``location()``), also from meets.
- angles (Paper 1 §3.7): :func:`signed_angle` ``atan2((a^b) N^{-1}, a.b)`` (17) about a rotation
  plane ``N`` (unit Euclidean bivector whose Euclidean dual ``N* = N I3^{-1}`` is the rotation
  axis); :func:`rotation_plane_perpendicular_to_line` (20) and
  :func:`rotation_plane_parallel_to_plane` (21).

Invalid input (NaN/Inf, zero normals or directions, a point at infinity passed to
:func:`down`, an imaginary point pair asked for its points) raises ``ValueError``.
"""

from __future__ import annotations

from typing import Tuple, Union

import numpy as np

from ._core import cga as _c

__all__ = [
    "Multivector", "Sphere", "Plane", "Line", "Motor", "Point", "Circle", "Reality",
    "e0", "e1", "e2", "e3", "einf", "Ic", "I3", "blade_names",
    "up", "down", "to_vector5", "from_vector5", "inner_product_matrix",
    "point_pair", "point_pair_points", "point_pair_reality", "flat_point", "flat_point_location",
    "circle", "round_center", "round_radius2", "rotor", "translator",
    "meet_sphere_plane", "meet_planes", "meet_spheres", "meet_plane_circle", "meet_line_plane",
    "point_distance", "point_plane_distance", "sphere_point_inner", "point_sphere_distance",
    "geometric_product_many",
    "PointPair", "FlatPoint", "meet_plane_circle_pair", "meet_line_plane_flat",
    "signed_angle", "rotation_plane_from_axis", "rotation_axis", "normalise_blade", "euclidean_dual",
    "rotation_plane_perpendicular_to_line", "rotation_plane_parallel_to_plane",
]

Multivector = _c.Multivector
Sphere = _c.Sphere
Plane = _c.Plane
Line = _c.Line
Motor = _c.Motor
Reality = _c.Reality
PointPair = _c.PointPair
FlatPoint = _c.FlatPoint

e0 = Multivector.e0()
e1 = Multivector.e1()
e2 = Multivector.e2()
e3 = Multivector.e3()
einf = Multivector.einf()
Ic = Multivector.ic()
I3 = Multivector.i3()

inner_product_matrix = _c.inner_product_matrix
to_vector5 = _c.to_vector5
from_vector5 = _c.from_vector5
point_pair_reality = _c.point_pair_reality
flat_point_location = _c.flat_point_location
round_center = _c.round_center
round_radius2 = _c.round_radius2
meet_sphere_plane = _c.meet_sphere_plane
meet_planes = _c.meet_planes
meet_spheres = _c.meet_spheres
meet_plane_circle = _c.meet_plane_circle
meet_line_plane = _c.meet_line_plane
point_plane_distance = _c.point_plane_distance
sphere_point_inner = _c.sphere_point_inner
point_sphere_distance = _c.point_sphere_distance
meet_plane_circle_pair = _c.meet_plane_circle_pair
meet_line_plane_flat = _c.meet_line_plane_flat
normalise_blade = _c.normalise_blade
euclidean_dual = _c.euclidean_dual
rotation_axis = _c.rotation_axis


def blade_names() -> list:
    """Names of the 32 null-basis blades in the order of ``null_coefficients()``."""
    return [Multivector.blade_name(i) for i in range(32)]


def _vec3(x, what: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64)
    if a.shape != (3,):
        raise ValueError(f"{what}: expected 3 coordinates, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: not finite")
    return a


def _rows(x, cols: int, what: str) -> np.ndarray:
    a = np.asarray(x)
    if a.dtype not in (np.float32, np.float64):
        raise TypeError(f"{what}: expected float32/float64, got {a.dtype}")
    if a.ndim != 2 or a.shape[1] != cols:
        raise ValueError(f"{what}: expected an (N, {cols}) array, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: contains NaN or Inf")
    return np.ascontiguousarray(a, dtype=np.float64)


def up(x) -> Union[Multivector, np.ndarray]:
    """Conformal point ``x + 1/2 x^2 einf + e0`` (4.54) of a point in metres.

    A single point (3,) gives a :class:`Multivector`; an (N, 3) array gives an (N, 5)
    float64 array of coefficients ``(e1, e2, e3, einf, e0)`` (4.55)."""
    a = np.asarray(x)
    if a.ndim == 2:
        return _c.up_many(_rows(a, 3, "points"))
    return _c.up(_vec3(a, "point"))


def down(P) -> np.ndarray:
    """Euclidean point (metres) of a conformal point of any scale (divides by the e0
    coefficient ``-einf . P``). Accepts a :class:`Multivector` or an (N, 5) coefficient array
    ``(e1, e2, e3, einf, e0)``. Raises ``ValueError`` for a zero e0 coefficient."""
    if isinstance(P, Multivector):
        return _c.down(P)
    return _c.down_many(_rows(P, 5, "conformal points"))


def point_pair(a, b) -> Multivector:
    """Direct point pair ``up(a) ^ up(b)`` (4.62)."""
    return _c.up(_vec3(a, "a")) ^ _c.up(_vec3(b, "b"))


def point_pair_points(Q: Multivector) -> Tuple[np.ndarray, np.ndarray]:
    """The two points ``(Q -+ sqrt(Q^2)) / (-einf . Q)`` (4.63) of a direct point pair,
    ``(a, b)`` for ``Q = up(a) ^ up(b)`` (negating Q swaps them). A dual pair from a meet is
    made direct with ``.undual()``. Raises ``ValueError`` when ``Q^2 < 0`` (no real points,
    thesis (4.70)-(4.73))."""
    return _c.point_pair_points(Q)


def rotation_plane_from_axis(axis) -> Multivector:
    """Unit rotation plane ``N = n I3`` whose Euclidean dual ``N* = N I3^{-1}`` is the unit
    ``axis`` (e.g. ``e3 -> e12``); :func:`rotation_axis` is the inverse (Paper 1 §3.7)."""
    return _c.rotation_plane_from_axis(_vec3(axis, "axis"))


def signed_angle(a, b, N: Multivector) -> float:
    """Signed angle (radians, in (-pi, pi]) from direction ``a`` to ``b`` in the rotation plane
    ``N``: ``theta = atan2((a^b) N^{-1}, a.b)`` (17), Paper 1 §3.7.

    ``a``, ``b``: 3-vectors (any length, in one frame) or grade-1 :class:`Multivector`;
    ``N``: a Euclidean bivector (normalised here). For ``a, b`` perpendicular to the axis
    ``N*`` this is the right-handed angle about ``N*`` (Paper 1 eq. (17))."""
    if isinstance(a, Multivector) or isinstance(b, Multivector):
        A = a if isinstance(a, Multivector) else _c.Multivector.vector(_vec3(a, "a"))
        Bv = b if isinstance(b, Multivector) else _c.Multivector.vector(_vec3(b, "b"))
        return _c.signed_angle_mv(A, Bv, N)
    return _c.signed_angle(_vec3(a, "a"), _vec3(b, "b"), N)


def rotation_plane_perpendicular_to_line(line) -> Multivector:
    """Unit rotation plane ``N = (L* ^ einf) . e0 / |.|`` (20) perpendicular to a line: a
    :class:`Line` or a dual line ``L*`` (:class:`Multivector`). For ``L = up(a)^up(b)^einf``,
    ``rotation_axis(N) = (b - a)/|b - a|``."""
    if isinstance(line, Line):
        return _c.rotation_plane_perpendicular_to_line_typed(line)
    return _c.rotation_plane_perpendicular_to_line(line)


def rotation_plane_parallel_to_plane(plane) -> Multivector:
    """Unit rotation plane ``N = (Pi . e0) . einf / |.|`` (21) parallel to a plane: a
    :class:`Plane` or a direct plane ``Pi`` (:class:`Multivector`, (4.64)). Its axis
    ``rotation_axis(N)`` is ``(b - a) x (c - a)`` normalised for ``Pi = up(a)^up(b)^up(c)^einf``
    (minus the normal of the dual ``Pi*``); for a :class:`Plane` it is oriented to ``plane.normal``."""
    if isinstance(plane, Plane):
        return _c.rotation_plane_parallel_to_plane_typed(plane)
    return _c.rotation_plane_parallel_to_plane(plane)


def flat_point(p) -> Multivector:
    """Flat point ``up(p) ^ einf`` (4.69)."""
    return _c.up(_vec3(p, "point")) ^ einf


def circle(a, b, c) -> Multivector:
    """Direct circle ``up(a) ^ up(b) ^ up(c)`` through three points (4.57)."""
    return _c.up(_vec3(a, "a")) ^ _c.up(_vec3(b, "b")) ^ _c.up(_vec3(c, "c"))


def rotor(axis, angle: float) -> Multivector:
    """Rotor ``cos(angle/2) - sin(angle/2) B`` for a right-handed rotation by ``angle``
    (radians) about ``axis`` (Paper 4 §3.5)."""
    return _c.rotor(_vec3(axis, "axis"), float(angle))


def translator(t) -> Multivector:
    """Translator ``1 - 1/2 t einf`` (Paper 4 §3.5), ``t`` in metres."""
    return _c.translator(_vec3(t, "translation"))


def point_distance(a, b) -> float:
    """``|a - b|`` from ``d^2 = -2 up(a) . up(b)`` (4.56)."""
    return _c.point_distance(_vec3(a, "a"), _vec3(b, "b"))


def geometric_product_many(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise geometric products of two (N, 32) arrays of orthonormal-basis coefficients
    (``Multivector.orthonormal_coefficients()`` layout), computed in C++."""
    return _c.geometric_product_many(_rows(a, 32, "a"), _rows(b, 32, "b"))


class Point:
    """A Euclidean point (metres) as a conformal point ``up(x)`` (4.54).

    ``Point(x).mv`` is the normalised conformal point; the operators ``*``, ``^``, ``|``
    and ``~`` act on it and return :class:`Multivector`."""

    __slots__ = ("position",)

    def __init__(self, x) -> None:
        self.position = _vec3(x, "point")

    @property
    def mv(self) -> Multivector:
        return _c.up(self.position)

    @classmethod
    def from_multivector(cls, P: Multivector) -> "Point":
        return cls(_c.down(P))

    @staticmethod
    def _other(o):
        return o.mv if isinstance(o, Point) else o

    def __mul__(self, o):
        return self.mv * self._other(o)

    def __xor__(self, o):
        return self.mv ^ self._other(o)

    def __or__(self, o):
        return self.mv | self._other(o)

    def __invert__(self):
        return ~self.mv

    def __repr__(self) -> str:
        return "Point(" + np.array2string(self.position, separator=", ", precision=6) + ")"


class Circle:
    """A circle: ``center`` (metres), unit ``normal`` of its carrier plane, ``radius`` (metres).

    ``direct()`` is ``up(a) ^ up(b) ^ up(c)`` for three points on it (4.57), built from the
    centre, normal and radius; :meth:`from_direct` reads any direct circle (centre
    ``C einf C``, radius from ``<C C^> / <(einf _| C)^2>``, normal from the plane ``C ^ einf``
    (4.64)); :meth:`from_dual` reads a meet result such as ``meet_sphere_plane`` (the dual
    ``C*``; its undual ``C* Ic`` is the direct circle). Raises ``ValueError`` for an
    imaginary circle (radius^2 < 0) or a line (a circle through infinity)."""

    __slots__ = ("center", "normal", "radius")

    def __init__(self, center, normal, radius: float) -> None:
        self.center = _vec3(center, "circle centre")
        n = _vec3(normal, "circle normal")
        ln = float(np.linalg.norm(n))
        if not ln > 1e-12:
            raise ValueError("circle normal is zero")
        self.normal = n / ln
        if not (np.isfinite(radius) and radius >= 0):
            raise ValueError("circle radius must be finite and >= 0")
        self.radius = float(radius)

    @classmethod
    def through_points(cls, a, b, c) -> "Circle":
        return cls.from_direct(circle(a, b, c))

    @classmethod
    def from_direct(cls, C: Multivector) -> "Circle":
        r2 = _c.round_radius2(C)
        if r2 < 0:
            raise ValueError(f"imaginary circle (radius^2 = {r2:g})")
        plane = Plane.from_direct(C ^ einf)
        return cls(_c.round_center(C), plane.normal, float(np.sqrt(r2)))

    @classmethod
    def from_dual(cls, Cs: Multivector) -> "Circle":
        return cls.from_direct(Cs.undual())

    def direct(self) -> Multivector:
        u = np.cross(self.normal, [1.0, 0.0, 0.0])
        if np.linalg.norm(u) < 0.5:
            u = np.cross(self.normal, [0.0, 1.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(self.normal, u)
        c, r = self.center, self.radius
        return circle(c + r * u, c + r * v, c - r * u)

    def dual(self) -> Multivector:
        return self.direct().dual()

    def __repr__(self) -> str:
        f = lambda v: np.array2string(np.asarray(v), separator=", ", precision=6)  # noqa: E731
        return f"Circle(center={f(self.center)}, normal={f(self.normal)}, radius={self.radius:.6g})"

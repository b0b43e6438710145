"""Conformal geometric algebra G(4,1) (Kleppe, PhD thesis, NTNU 2018, ch. 4).

Basis vectors ``e1, e2, e3`` (Euclidean, metres), ``e0`` (origin) and ``einf`` (infinity) with ``e0 . einf = -1`` and
``e0^2 = einf^2 = 0`` (4.44)-(4.45); internally the orthonormal ``e+ (e+^2 = 1)``, ``e- (e-^2 = -1)`` with
``e0 = (e- - e+)/2``, ``einf = e- + e+``. Blades are named by their vectors in the order ``e0, e1, e2, e3, einf``:
``m["e1inf"]`` is the coefficient of ``e1^einf``; ``Multivector.null_coefficients()`` gives all 32 in the order of
``blade_names()`` (index bits: 1 = e0, 2 = e1, 4 = e2, 8 = e3, 16 = einf).

Operators on :class:`Multivector`: ``*`` geometric product, ``^`` outer product, ``|`` inner product (Hestenes/"fat"
``<A_r B_s>_{|r-s|}``, zero when either grade is 0, as the ``clifford`` package), ``~`` reverse (4.32); ``.dual()`` is
``A Ic^{-1}`` with ``Ic = e0^e1^e2^e3^einf`` and ``Ic^2 = -1`` (4.48)-(4.50), ``.undual()`` is ``A Ic``.

Objects (all coordinates in metres, in the frame the caller works in):

- :func:`up` / :func:`down`: Euclidean points to conformal points ``P = x + 1/2 x^2 einf + e0`` (4.54) and back;
  vectorised over ``(N, 3)`` arrays, where conformal points are ``(N, 5)`` arrays of coefficients
  ``(e1, e2, e3, einf, e0)`` (4.55) and :func:`inner_product_matrix` gives ``M`` with ``X . Y = X^T M Y`` (5.32).
- :class:`Sphere` (dual ``S* = up(c) - 1/2 r^2 einf`` (4.59)), :class:`Plane` (dual ``Pi* = n + delta einf`` (4.65)),
  :class:`Line` (direct ``(p + e0)^d^einf`` (4.68)), :class:`Point`, :class:`Circle` (direct ``up(a)^up(b)^up(c)``
  (4.57)), point pairs ``up(a)^up(b)`` (4.62), flat points ``up(p)^einf`` (4.69).
- :class:`Motor` ``M = T R`` (``M up(x) ~M = up(R x + t)``), :class:`PointPair` (``Q = PA^PB``) and
  :class:`FlatPoint` (``P^einf``): their class docstrings give the construction and equations.
- meets (4.70)-(4.73) return dual objects ``A* ^ B*`` (the line-plane meet returns the
  flat point ``Pi* . L``); distances (4.56), (4.67), Paper 5 eq. (10).
- angles (Paper 1 §3.7): :func:`signed_angle` ``atan2((a^b) N^{-1}, a.b)`` (17) about a rotation plane ``N`` (unit
  Euclidean bivector whose Euclidean dual ``N* = N I3^{-1}`` is the rotation axis);
  :func:`rotation_plane_perpendicular_to_line` (20) and :func:`rotation_plane_parallel_to_plane` (21).

Everything here is the C++ core (``scanalign/cga/*.hpp``) bound directly; each function and
class carries its docstring. Invalid input (NaN/Inf, zero normals or directions, a point at
infinity passed to :func:`down`, an imaginary point pair, coordinates beyond ~1e150 m or a product
that would overflow) raises ``ValueError`` naming the argument; complex, string or None ``TypeError``.
"""

from __future__ import annotations

from scanalign import _core

__all__ = ["Multivector", "Sphere", "Plane", "Line", "Motor", "Point", "Circle", "Reality", "e0", "e1", "e2", "e3",
           "einf", "Ic", "I3", "blade_names", "up", "down", "to_vector5", "from_vector5", "inner_product_matrix",
           "point_pair", "point_pair_points", "point_pair_reality", "flat_point", "flat_point_location", "circle",
           "round_center", "round_radius2", "rotor", "translator", "meet_sphere_plane", "meet_planes", "meet_spheres",
           "meet_plane_circle", "meet_line_plane", "point_distance", "point_plane_distance", "sphere_point_inner",
           "point_sphere_distance", "geometric_product_many", "PointPair", "FlatPoint", "meet_plane_circle_pair",
           "meet_line_plane_flat", "signed_angle", "rotation_plane_from_axis", "rotation_axis", "normalise_blade",
           "euclidean_dual", "rotation_plane_perpendicular_to_line", "rotation_plane_parallel_to_plane"]

globals().update({name: getattr(_core.cga, name) for name in __all__})  # the bound C++ names, as they are

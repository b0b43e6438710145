"""Sphere, plane and circle fitting (Kleppe, PhD thesis, NTNU 2018, §5.1 and §6.3).

- :func:`fit_sphere` -- Dorst's conformal (CGA) sphere fit (thesis (5.26)-(5.34)), optionally
  weighted ((6.5)-(6.11)). It returns a sphere, or a plane when the data is (nearly) flat.
- :func:`fit_spheres` -- many independent fits in one call (e.g. one per neighbourhood).
- :func:`fit_circle_2d` -- Pratt's algebraic circle fit ((5.21)-(5.25)).

Conformal objects are 5-vectors of coefficients on (e1, e2, e3, e_inf, e0): a dual sphere
is ``[c, (|c|^2 - r^2)/2, 1]`` (4.60) and a dual plane ``[n, delta, 0]`` for the plane
``n . p = delta`` (4.66). Units are metres. The functions and result types are the C++ ones
(``scanalign._core.fitting``), documented there: ``help(fit_sphere)``, ``help(SphereFitResult)``.
"""

from __future__ import annotations

from scanalign import _core

__all__ = ["SphereFitResult", "CircleFitResult", "SphereFitBatchResult", "fit_sphere", "fit_spheres", "fit_circle_2d",
           "MIN_SPHERE_POINTS"]

globals().update({name: getattr(_core.fitting, name) for name in __all__[:-1]})  # the bound C++ names, as they are
#: Points (with positive weight) that :func:`fit_sphere` requires (four determine a sphere exactly).
MIN_SPHERE_POINTS: int = _core.fitting.MIN_SPHERE_POINTS

"""Sphere, plane and circle fitting (thesis spec §2).

- :func:`fit_sphere` -- Dorst's conformal (CGA) sphere fit (thesis 5.26-5.34), optionally
  weighted (6.5-6.11). It returns a sphere, or a plane when the data is (nearly) flat.
- :func:`fit_spheres` -- many independent fits in one call (e.g. one per neighbourhood).
- :func:`fit_circle_2d` -- Pratt's algebraic circle fit (5.21-5.25).

Conformal objects are 5-vectors of coefficients on (e1, e2, e3, e_inf, e0): a dual sphere
is ``[c, (|c|^2 - r^2)/2, 1]`` (4.60) and a dual plane ``[n, delta, 0]`` for the plane
``n . p = delta`` (4.66). Units are metres.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import _core
from ._arrays import as_points

__all__ = ["SphereFitResult", "CircleFitResult", "SphereFitBatch", "fit_sphere", "fit_spheres", "fit_circle_2d",
           "MIN_SPHERE_POINTS"]

#: Points (with positive weight) that :func:`fit_sphere` requires. Four points in general
#: position determine a sphere exactly; a fit needs at least five.
MIN_SPHERE_POINTS = 5


#: Result of :func:`fit_sphere` (bound from C++; its fields are documented there:
#: ``help(SphereFitResult)``): ``center``, ``radius``, ``is_plane``, ``normal``,
#: ``distance``, ``imaginary``, ``rms``, ``objective``, ``count``, ``dual``.
SphereFitResult = _core.fitting.SphereFitResult
#: Result of :func:`fit_circle_2d` (bound from C++): ``center``, ``radius``, ``rms``,
#: ``coefficients``, ``count``.
CircleFitResult = _core.fitting.CircleFitResult


@dataclass(frozen=True)
class SphereFitBatch:
    """Result of :func:`fit_spheres`: the fields of :class:`SphereFitResult` as arrays with one
    row per group. A group that cannot be fitted has ``count == 0`` and NaN values."""

    center: np.ndarray
    radius: np.ndarray
    is_plane: np.ndarray
    normal: np.ndarray
    distance: np.ndarray
    imaginary: np.ndarray
    rms: np.ndarray
    count: np.ndarray
    dual: np.ndarray


def _check_tolerance(plane_tolerance: float) -> float:
    t = float(plane_tolerance)
    if not (np.isfinite(t) and t >= 0):
        raise ValueError("plane_tolerance must be finite and >= 0")
    return t


def fit_sphere(points: np.ndarray, weights: Optional[np.ndarray] = None, *,
               plane_tolerance: float = 1e-6) -> SphereFitResult:
    """Fits a sphere (or a plane) to 3-D points with the CGA sphere fit.

    Minimises ``sum_i w_i (S.P_i)^2 / S^2 / sum_i w_i`` over dual spheres S (thesis 5.27; per
    point ``(S.P)^2/S^2 ~ delta^2``, delta the geometric distance), solved as the eigenvector
    of the smallest positive eigenvalue of ``Q = sum_i w_i [P_i][P_i]^T M / sum_i w_i`` (5.31,
    6.6) in a numerically stable symmetric form. Exact points give the exact sphere; exactly
    coplanar points give a plane.

    Args:
        points: (N, 3) float32/float64 points, metres.
        weights: optional (N,) non-negative finite weights. A point with weight 0 is removed
            (it may even be NaN); integer weights act as duplicated points; only ratios matter.
        plane_tolerance: return a plane when the fitted radius exceeds about
            ``1 / plane_tolerance`` times the extent of the data.

    Returns:
        :class:`SphereFitResult`.

    Raises:
        TypeError: points or weights not a float/real array.
        ValueError: wrong shapes; non-finite points (with positive weight); negative or
            non-finite weights; all weights zero; fewer than 5 points with positive weight;
            degenerate data (coincident or collinear points, points on one circle).
    """
    p = as_points(points, "points")
    w = None
    if weights is not None:
        w = np.asarray(weights)
        if w.dtype.kind not in "biuf":
            raise TypeError(f"weights: expected a real array, got dtype {w.dtype}")
        w = np.ascontiguousarray(w, dtype=np.float64)
        if w.shape != (p.shape[0],):
            raise ValueError(f"weights: expected shape ({p.shape[0]},), got {w.shape}")
        if not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValueError("weights must be finite and non-negative")
        if p.shape[0] > 0 and not np.any(w > 0):
            raise ValueError("weights: all weights are zero")
        used = w > 0
    else:
        used = slice(None)
    if not np.all(np.isfinite(p[used])):
        raise ValueError("points: non-finite coordinates (give such points weight 0 to remove them)")
    n_used = int(np.count_nonzero(w > 0)) if w is not None else p.shape[0]
    if n_used < MIN_SPHERE_POINTS:
        raise ValueError(f"fit_sphere needs at least {MIN_SPHERE_POINTS} points (with positive weight), got {n_used}")
    fn = _core.fitting.fit_sphere_f64 if p.dtype == np.float64 else _core.fitting.fit_sphere_f32
    return fn(p, w, _check_tolerance(plane_tolerance))


def fit_spheres(points: np.ndarray, offsets: np.ndarray, *, plane_tolerance: float = 1e-6,
                num_threads: int = 0) -> SphereFitBatch:
    """Many unweighted :func:`fit_sphere` fits in one call (parallel, OpenMP).

    Args:
        points: (N, 3) float32/float64 points, metres; group g is
            ``points[offsets[g]:offsets[g + 1]]``.
        offsets: (G + 1,) non-decreasing integer offsets into ``points``.
        plane_tolerance: as in :func:`fit_sphere`.
        num_threads: OpenMP threads, 0 = all cores.

    Returns:
        :class:`SphereFitBatch`; groups that cannot be fitted get ``count == 0`` and NaNs.
    """
    p = as_points(points, "points")
    o = np.asarray(offsets)
    if o.dtype.kind not in "iu":
        raise TypeError(f"offsets: expected an integer array, got dtype {o.dtype}")
    o = np.ascontiguousarray(o, dtype=np.int64)
    if o.ndim != 1 or o.shape[0] < 1:
        raise ValueError("offsets: expected shape (G + 1,)")
    if np.any(np.diff(o) < 0) or o[0] < 0 or o[-1] > p.shape[0]:
        raise ValueError("offsets must be non-decreasing, >= 0 and <= len(points)")
    fn = _core.fitting.fit_spheres_f64 if p.dtype == np.float64 else _core.fitting.fit_spheres_f32
    d = fn(p, o, _check_tolerance(plane_tolerance), int(num_threads))
    return SphereFitBatch(**d)


def fit_circle_2d(points: np.ndarray) -> CircleFitResult:
    """Pratt's algebraic circle fit of 2-D points (thesis 5.21-5.25).

    Minimises ``sum g(p_i)^2 / (d^2 + e^2 - 4af)`` for the circle
    ``g(p) = a|p|^2 + d x + e y + f = 0`` (the Sampson approximation of the geometric
    distance, 5.9), as the eigenvector of the smallest positive eigenvalue of ``Mc = lambda Nc``.

    Args:
        points: (N, 2) float points, metres; N >= 3.

    Returns:
        :class:`CircleFitResult`.

    Raises:
        TypeError: not a float array. ValueError: wrong shape, fewer than 3 points,
        non-finite values, collinear or coincident points.
    """
    a = np.asarray(points)
    if a.dtype.kind != "f":
        raise TypeError(f"points: expected a float array, got dtype {a.dtype}")
    if a.ndim != 2 or a.shape[1] != 2:
        raise ValueError(f"points: expected shape (N, 2), got {a.shape}")
    if a.shape[0] < 3:
        raise ValueError(f"fit_circle_2d needs at least 3 points, got {a.shape[0]}")
    if not np.all(np.isfinite(a)):
        raise ValueError("points: non-finite coordinates")
    return _core.fitting.fit_circle_pratt(np.ascontiguousarray(a, dtype=np.float64))

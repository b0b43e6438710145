"""RANSAC planes and spheres with conformal (CGA) models, and table segmentation.

Thesis §5.2 (generic RANSAC, eq. 5.2): draw a minimal sample, build a model, count the
points whose error is below the threshold ``E_T``, keep the best. The CGA plane through
three points is ``Pi = P_A ^ P_B ^ P_C ^ e_inf`` (5.35), with the inlier test
``|P . Pi*| < E_T`` on the normalised dual plane ``Pi* = n + delta e_inf``, ``|n| = 1``
(5.36, 4.65-4.67); the sphere through four points is ``S = P_A ^ P_B ^ P_C ^ P_D``
(4.58), dual ``S* = up(c) - r^2/2 e_inf`` (4.59). The winner is refitted by least
squares over its inliers (plane: PCA; sphere: the CGA algebraic fit, thesis 5.31), and the
returned ``inliers`` are then exactly the finite points whose error under the *returned*
model is below ``threshold`` (plane: ``|n.p - distance| < threshold``; sphere:
``| |p - center| - radius | < threshold``).

The number of hypotheses adapts to the best inlier ratio found so far (``confidence``);
sample ``k`` is drawn from a generator seeded by ``(seed, k)`` and hypotheses are accepted
in order, so results are reproducible for a seed and independent of ``num_threads``.

Input: ``(N, 3)`` float32/float64 points in metres (other dtypes raise ``TypeError``,
other shapes ``ValueError``). Rows with NaN/Inf are ignored: they are never sampled nor
inliers, and every returned index refers to a row of the input array. Fewer finite points
than the minimal sample (3 for a plane, 4 for a sphere) raises ``ValueError``. When no
model can be built -- every sample drawn was degenerate, e.g. collinear points for a
plane or points within ``threshold`` of one plane for a sphere -- the result has
``status == "degenerate"`` and ``success == False`` (nothing is raised).

Table segmentation (paper 3 §3.1.2-3.1.3): (1) optional pass-through crop to a box;
(2) RANSAC plane = the table; (3) remove its inliers and every point below it (signed
distance under ``threshold``, the normal oriented towards ``up`` or else the camera
``viewpoint``); (4) Euclidean clustering with a k-d tree (points within
``cluster_tolerance`` are linked); (5) clusters outside ``[min_cluster_size,
max_cluster_size]`` dropped. Each remaining cluster is one object.
"""

from __future__ import annotations

from typing import List, Optional, Sequence, Tuple

import numpy as np

from . import _core
from ._arrays import as_points

__all__ = [
    "PlaneResult",
    "SphereResult",
    "TableSegmentation",
    "ransac_plane",
    "ransac_sphere",
    "segment_table",
    "plane_from_points",
    "sphere_from_points",
]


#: Result of :func:`ransac_plane` (bound from C++; ``help(PlaneResult)`` documents every
#: field): ``normal``, ``distance``, ``inliers``, ``status``, ``success``, ``iterations``,
#: ``degenerate_samples``, ``refined``, ``hypothesis_normal``, ``hypothesis_distance``,
#: ``hypothesis_inliers``, and ``signed_distance(points)``.
PlaneResult = _core.segmentation.PlaneResult
#: Result of :func:`ransac_sphere` (bound from C++): ``center``, ``radius``, and the
#: fields PlaneResult shares (``inliers``, ``status``, ...; ``hypothesis_center``, ``hypothesis_radius``).
SphereResult = _core.segmentation.SphereResult
#: Result of :func:`segment_table_full` (bound from C++): ``plane``, ``objects``,
#: ``cropped_points``, ``above_points``, ``status``, ``success``.
TableSegmentation = _core.segmentation.TableSegmentation


def _check_common(threshold: float, max_iterations: int, confidence: float) -> None:
    if not (np.isfinite(threshold) and threshold > 0):
        raise ValueError("threshold must be a finite positive distance in metres")
    if int(max_iterations) < 1:
        raise ValueError("max_iterations must be at least 1")
    if not (0.0 <= confidence <= 1.0):
        raise ValueError("confidence must lie in [0, 1] (0 or 1: no adaptive stop)")


def _points(points: object, minimum: int, what: str) -> np.ndarray:
    p = as_points(points, "points")
    finite = int(np.count_nonzero(np.all(np.isfinite(p), axis=1)))
    if finite < minimum:
        raise ValueError(f"{what} needs at least {minimum} finite points, got {finite}")
    return p


def ransac_plane(
    points: np.ndarray,
    threshold: float,
    *,
    max_iterations: int = 1000,
    confidence: float = 0.99,
    seed: int = 0,
    refine: bool = True,
    num_threads: int = 0,
) -> PlaneResult:
    """The dominant plane by RANSAC with the CGA plane model (thesis 5.35-5.36).

    Args:
        points: (N, 3) float32/float64, metres; NaN/Inf rows ignored.
        threshold: E_T, metres: a point is an inlier if its distance to the plane is below it.
        max_iterations: n, the most hypotheses drawn.
        confidence: stop once ``k >= log(1 - confidence) / log(1 - w^3)`` for the best
            inlier ratio ``w`` so far; 0 or 1 disables the adaptive stop.
        seed: RNG seed (sample k depends on (seed, k) only).
        refine: PCA refit over the winner's inliers, then inliers re-selected.
        num_threads: OpenMP threads for scoring hypotheses (0 = all); never changes the result.

    Raises:
        TypeError / ValueError: bad dtype / shape / settings; fewer than 3 finite points.
    """
    _check_common(threshold, max_iterations, confidence)
    p = _points(points, 3, "ransac_plane")
    fn = _core.segmentation.ransac_plane_f64 if p.dtype == np.float64 else _core.segmentation.ransac_plane_f32
    return fn(p, float(threshold), int(max_iterations), float(confidence), int(seed) & (2**64 - 1),
              int(num_threads), bool(refine))


def ransac_sphere(
    points: np.ndarray,
    threshold: float,
    *,
    min_radius: float = 0.0,
    max_radius: float = np.inf,
    max_iterations: int = 1000,
    confidence: float = 0.99,
    seed: int = 0,
    refine: bool = True,
    num_threads: int = 0,
) -> SphereResult:
    """A sphere by RANSAC with the CGA sphere through four points (4.58-4.60).

    A sample is degenerate (no hypothesis) when its four points lie within ``threshold``
    of one plane, or when its sphere's radius is outside ``[min_radius, max_radius]``
    (metres); on planar data the result is ``status == "degenerate"``. The refit (the
    CGA least-squares fit, 5.31) is kept only when its radius is within the limits.
    Other arguments as :func:`ransac_plane`; ``w^4`` in the adaptive stop.
    """
    _check_common(threshold, max_iterations, confidence)
    if not (min_radius >= 0 and max_radius > min_radius):
        raise ValueError("need 0 <= min_radius < max_radius (metres)")
    p = _points(points, 4, "ransac_sphere")
    fn = _core.segmentation.ransac_sphere_f64 if p.dtype == np.float64 else _core.segmentation.ransac_sphere_f32
    return fn(p, float(threshold), int(max_iterations), float(confidence), int(seed) & (2**64 - 1), int(num_threads),
              bool(refine), float(min_radius), float(max_radius))


def _vec3(v: Optional[Sequence[float]], name: str, allow_inf: bool = False) -> Optional[np.ndarray]:
    if v is None:
        return None
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3,) or np.any(np.isnan(a)) or (not allow_inf and not np.all(np.isfinite(a))):
        raise ValueError(f"{name}: expected 3 {'non-NaN' if allow_inf else 'finite'} coordinates")
    return a


def segment_table(
    points: np.ndarray,
    *,
    threshold: float = 0.01,
    crop_min: Optional[Sequence[float]] = None,
    crop_max: Optional[Sequence[float]] = None,
    viewpoint: Sequence[float] = (0.0, 0.0, 0.0),
    up: Optional[Sequence[float]] = None,
    cluster_tolerance: float = 0.02,
    min_cluster_size: int = 100,
    max_cluster_size: Optional[int] = None,
    max_iterations: int = 1000,
    confidence: float = 0.99,
    seed: int = 0,
    num_threads: int = 0,
) -> Tuple[PlaneResult, List[np.ndarray]]:
    """Table plane and object clusters (paper 3 pipeline, see the module docstring).

    Args:
        points: (N, 3) float32/float64, metres (e.g. in the camera frame); NaN rows ignored.
        threshold: Delta, metres: plane inlier distance, and points closer than this above
            the table are removed with it.
        crop_min, crop_max: pass-through box corners, metres (either may be None: open
            side; ``np.inf`` entries allowed). No crop when both are None.
        viewpoint: camera centre, metres: the table normal is oriented towards it (unless
            ``up`` is given). Points on the other side of the table are removed.
        up: optional "up" direction (any length) to orient the normal instead.
        cluster_tolerance: metres: points this close are in the same object.
        min_cluster_size, max_cluster_size: points per object kept (None: no upper limit).
        max_iterations, confidence, seed, num_threads: the plane RANSAC, as
            :func:`ransac_plane`.

    Returns:
        ``(plane, objects)``: the table :class:`PlaneResult` (``plane.success`` False if no
        plane could be built: ``objects`` is then empty) and a list of int64 index arrays
        into ``points``, one per object, largest first. :func:`segment_table_full` also
        returns the point counts after each step.

    Raises:
        TypeError / ValueError: bad dtype / shape / settings; fewer than 3 finite points
        (after the crop the plane RANSAC reports ``too_few_points`` instead).
    """
    r = segment_table_full(points, threshold=threshold, crop_min=crop_min, crop_max=crop_max, viewpoint=viewpoint,
                           up=up, cluster_tolerance=cluster_tolerance, min_cluster_size=min_cluster_size,
                           max_cluster_size=max_cluster_size, max_iterations=max_iterations, confidence=confidence,
                           seed=seed, num_threads=num_threads)
    return r.plane, r.objects


def segment_table_full(points: np.ndarray, **kwargs) -> TableSegmentation:
    """As :func:`segment_table` (same keyword arguments), returning a :class:`TableSegmentation`."""
    threshold = kwargs.pop("threshold", 0.01)
    max_iterations = kwargs.pop("max_iterations", 1000)
    confidence = kwargs.pop("confidence", 0.99)
    _check_common(threshold, max_iterations, confidence)
    crop_min = _vec3(kwargs.pop("crop_min", None), "crop_min", allow_inf=True)
    crop_max = _vec3(kwargs.pop("crop_max", None), "crop_max", allow_inf=True)
    viewpoint = _vec3(kwargs.pop("viewpoint", (0.0, 0.0, 0.0)), "viewpoint")
    up = _vec3(kwargs.pop("up", None), "up")
    up = np.zeros(3) if up is None else up
    tol = float(kwargs.pop("cluster_tolerance", 0.02))
    if not (np.isfinite(tol) and tol > 0):
        raise ValueError("cluster_tolerance must be a finite positive distance in metres")
    min_size = int(kwargs.pop("min_cluster_size", 100))
    max_size = kwargs.pop("max_cluster_size", None)
    max_size = 2**63 - 1 if max_size is None else int(max_size)
    if min_size < 1 or max_size < min_size:
        raise ValueError("need 1 <= min_cluster_size <= max_cluster_size")
    seed = int(kwargs.pop("seed", 0)) & (2**64 - 1)
    num_threads = int(kwargs.pop("num_threads", 0))
    if kwargs:
        raise TypeError(f"unexpected keyword arguments: {sorted(kwargs)}")
    p = _points(points, 3, "segment_table")
    fn = _core.segmentation.segment_table_f64 if p.dtype == np.float64 else _core.segmentation.segment_table_f32
    return fn(p, float(threshold), int(max_iterations), float(confidence), seed, num_threads, True, crop_min, crop_max,
              viewpoint, up, tol, min_size, max_size)


def plane_from_points(a: Sequence[float], b: Sequence[float], c: Sequence[float]) -> Optional[Tuple[np.ndarray, float]]:
    """Plane through three points, dual of ``P_A ^ P_B ^ P_C ^ e_inf`` (5.35) normalised
    to ``|n| = 1``: ``(normal, distance)``, or None when the points are collinear."""
    r = _core.segmentation.plane_from_points(*(np.asarray(v, dtype=np.float64) for v in (a, b, c)))
    return None if r is None else (np.asarray(r[0]), float(r[1]))


def sphere_from_points(a: Sequence[float], b: Sequence[float], c: Sequence[float],
                       d: Sequence[float]) -> Optional[Tuple[np.ndarray, float]]:
    """Sphere through four points, dual of ``P_A ^ P_B ^ P_C ^ P_D`` (4.58):
    ``(center, radius)``, or None when the points are coplanar."""
    r = _core.segmentation.sphere_from_points(*(np.asarray(v, dtype=np.float64) for v in (a, b, c, d)))
    return None if r is None else (np.asarray(r[0]), float(r[1]))

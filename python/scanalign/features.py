"""Point features: surface normals (seed 000 §3.5)."""

from __future__ import annotations

from typing import Optional, Sequence, Tuple, Union

import numpy as np

from . import _core
from ._arrays import as_points

__all__ = ["estimate_normals"]


def estimate_normals(
    points: np.ndarray,
    radius: float = 0.005,
    viewpoint: Sequence[float] = (0.0, 0.0, 0.0),
    *,
    min_neighbors: int = 3,
    return_curvature: bool = False,
    num_threads: int = 0,
) -> Union[np.ndarray, Tuple[np.ndarray, np.ndarray]]:
    """Unit normals by PCA over a radius neighbourhood, oriented towards a viewpoint.

    The normal of point p is the eigenvector of the smallest eigenvalue of the covariance
    of its neighbours within ``radius`` (Rusu 2009, as PCL's ``NormalEstimation``),
    flipped so that ``n . (viewpoint - p) >= 0``.

    Args:
        points: (N, 3) float32/float64 points, metres.
        radius: neighbourhood radius, metres (seed 000 §3.5: 5 mm).
        viewpoint: point the normals face, metres, in the cloud's frame (the camera
            centre, i.e. the origin, for a cloud in its camera frame).
        min_neighbors: fewer neighbours (the point included) give a NaN normal.
        return_curvature: also return the surface variation
            lambda_0 / (lambda_0 + lambda_1 + lambda_2) in [0, 1/3].
        num_threads: OpenMP threads, 0 = all cores.

    Returns:
        (N, 3) normals in the input dtype (NaN rows for non-finite points or too few
        neighbours), and the (N,) curvature when asked for.
    """
    p = as_points(points, "points")
    vp = np.asarray(viewpoint, dtype=np.float64)
    if vp.shape != (3,) or not np.all(np.isfinite(vp)):
        raise ValueError("viewpoint: expected 3 finite coordinates")
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError("radius must be a finite positive distance in metres")
    fn = _core.features.estimate_normals_f64 if p.dtype == np.float64 else _core.features.estimate_normals_f32
    normals, curvature = fn(p, float(radius), vp, int(min_neighbors), int(num_threads))
    return (normals, curvature) if return_curvature else normals

"""Point features: surface normals (the eye-in-hand paper, Comput. Electron. Agric. 180 (2021)
105929, §3.5) and PCA shape factors (Kleppe, PhD thesis, NTNU 2018, (6.1)-(6.3))."""

from __future__ import annotations

from typing import Optional, Sequence, Tuple, Union

import numpy as np

from scanalign import _core
from scanalign.common.arrays import as_points
from scanalign.common.settings import with_overrides

__all__ = ["NormalEstimationSettings", "estimate_normals", "shape_factors"]

NormalEstimationSettings = _core.features.NormalEstimationSettings


def estimate_normals(points: np.ndarray, radius: Optional[float] = None, viewpoint: Optional[Sequence[float]] = None, *,
                     settings: Optional[NormalEstimationSettings] = None, return_curvature: bool = False,
                     **overrides: object) -> Union[np.ndarray, Tuple[np.ndarray, np.ndarray]]:
    """Unit normals by PCA over a radius neighbourhood, oriented towards a viewpoint.

    The normal of point p is the eigenvector of the smallest eigenvalue of the covariance of its neighbours within
    ``radius`` (Rusu 2009, as PCL's ``NormalEstimation``), flipped so that ``n . (viewpoint - p) >= 0``. ``points``:
    (N, 3) float32/float64, metres. ``radius`` (m; eye-in-hand paper §3.5: 5 mm) and ``viewpoint``, the point the
    normals face (m, the cloud's frame: the camera centre, i.e. the origin, for a cloud in its camera frame); None:
    those of ``settings``, a :class:`NormalEstimationSettings` (default its C++ defaults) whose other fields keyword
    ``overrides`` name (``min_neighbors``: fewer neighbours, the point included, give a NaN normal; ``num_threads``:
    0 = all cores).

    Returns (N, 3) normals in the input dtype (NaN rows for non-finite points or too few neighbours) and, with
    ``return_curvature``, the (N,) surface variation lambda_0 / (lambda_0 + lambda_1 + lambda_2) in [0, 1/3]. TypeError:
    non-float points. ValueError: shape, non-positive radius, a viewpoint that is not 3 finite numbers,
    min_neighbors < 3.
    """
    given = {k: v for k, v in (("radius", radius), ("viewpoint", viewpoint)) if v is not None}
    s = with_overrides(NormalEstimationSettings, settings, {**given, **overrides}, "normal estimation")
    normals, curvature = _core.features.estimate_normals(as_points(points, "points"), s)
    return (normals, curvature) if return_curvature else normals


def shape_factors(eigenvalues) -> np.ndarray:
    """Shape factors (C_l, C_p, C_s) of PCA eigenvalues (thesis (6.1)-(6.3)): a float64 array of the shape of
    ``eigenvalues``, (3,) or (N, 3) covariance eigenvalues (m^2, any common scale; any order -- each row is sorted
    descending here). With l1 >= l2 >= l3 >= 0 and S = l1 + l2 + l3: ``C_l = (l1 - l2)/S``, ``C_p = 2 (l2 - l3)/S``,
    ``C_s = 3 l3/S``; they sum to 1 (1, 0, 0 for a line, 0, 1, 0 for a plane, 0, 0, 1 for an isotropic cloud).
    ValueError: wrong shape, NaN/Inf or negative eigenvalues, or a zero sum."""
    return _core.features.shape_factors(eigenvalues)

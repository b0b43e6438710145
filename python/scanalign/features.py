"""Point features: surface normals (the eye-in-hand paper, Comput. Electron. Agric. 180 (2021)
105929, §3.5) and PCA shape factors (Kleppe, PhD thesis, NTNU 2018, (6.1)-(6.3))."""

from __future__ import annotations

from typing import Sequence, Tuple, Union

import numpy as np

from . import _core
from ._arrays import as_points

__all__ = ["estimate_normals", "shape_factors"]


def estimate_normals(points: np.ndarray, radius: float = 0.005, viewpoint: Sequence[float] = (0.0, 0.0, 0.0), *,
                     min_neighbors: int = 3, return_curvature: bool = False,
                     num_threads: int = 0) -> Union[np.ndarray, Tuple[np.ndarray, np.ndarray]]:
    """Unit normals by PCA over a radius neighbourhood, oriented towards a viewpoint.

    The normal of point p is the eigenvector of the smallest eigenvalue of the covariance
    of its neighbours within ``radius`` (Rusu 2009, as PCL's ``NormalEstimation``),
    flipped so that ``n . (viewpoint - p) >= 0``.

    Args:
        points: (N, 3) float32/float64 points, metres.
        radius: neighbourhood radius, metres (eye-in-hand paper §3.5: 5 mm).
        viewpoint: point the normals face, metres, in the cloud's frame (the camera
            centre, i.e. the origin, for a cloud in its camera frame).
        min_neighbors: fewer neighbours (the point included) give a NaN normal.
        return_curvature: also return the surface variation
            lambda_0 / (lambda_0 + lambda_1 + lambda_2) in [0, 1/3].
        num_threads: OpenMP threads, 0 = all cores.

    Returns:
        (N, 3) normals in the input dtype (NaN rows for non-finite points or too few
        neighbours), and the (N,) curvature when asked for.

    Raises:
        TypeError: non-float points. ValueError: shape, non-positive radius, a viewpoint
        that is not 3 finite numbers, min_neighbors < 3.
    """
    normals, curvature = _core.features.estimate_normals(as_points(points, "points"), radius, viewpoint,
                                                         min_neighbors, num_threads)  # types checked in C++
    return (normals, curvature) if return_curvature else normals


def shape_factors(eigenvalues) -> np.ndarray:
    """Shape factors (C_l, C_p, C_s) of PCA eigenvalues (thesis (6.1)-(6.3)).

    With l1 >= l2 >= l3 >= 0 and S = l1 + l2 + l3:
    ``C_l = (l1 - l2)/S``, ``C_p = 2 (l2 - l3)/S``, ``C_s = 3 l3/S``; they sum to 1
    (1, 0, 0 for a line, 0, 1, 0 for a plane, 0, 0, 1 for an isotropic cloud).

    Args:
        eigenvalues: (3,) or (N, 3) covariance eigenvalues (m^2, any common scale; any
            order -- each row is sorted descending here).

    Returns:
        float64 array of the same shape: (C_l, C_p, C_s) per row.

    Raises:
        ValueError: wrong shape, NaN/Inf or negative eigenvalues, or a zero sum.
    """
    return _core.features.shape_factors(eigenvalues)

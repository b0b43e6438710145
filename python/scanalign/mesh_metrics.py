"""Reconstruction accuracy against a mesh: exact cloud-to-surface distances (m) and their summary.

:class:`MeshDistanceIndex` is the C++ index (a bounding-volume hierarchy over the triangles,
exact point-to-triangle distances after Ericson, Real-Time Collision Detection, 2005,
§5.1.5; queries in parallel) bound directly; its documentation is its docstring.  Points
and mesh share one frame; distances are unsigned (no inside / outside notion).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict

import numpy as np

from ._core.evaluation import MeshDistanceIndex

__all__ = ["MeshDistanceIndex", "MeshDistanceStats", "point_to_mesh_distance", "mesh_distance_stats"]


def point_to_mesh_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Exact Euclidean distance (m) from each point to a triangle mesh (its surface).

    Args:
        points: (N, 3) float32/float64, in the mesh's frame.  Rows with NaN/Inf are not
            an error: their distance is NaN.
        vertices: (V, 3) float32/float64 (m).
        faces: (F, 3) integer vertex indices in [0, V).

    Returns:
        (N,) float64 distances.

    See :class:`MeshDistanceIndex` (to reuse the index over several clouds) for the method
    and the errors raised.
    """
    return MeshDistanceIndex(vertices, faces).distance(points)


@dataclass
class MeshDistanceStats:
    """Cloud-to-mesh distance summary (m) over the finite points.

    ``count`` points were measured; ``dropped`` rows had NaN/Inf coordinates and were left out.
    """

    mean: float
    median: float
    p95: float
    max: float
    rmse: float
    count: int
    dropped: int = 0

    def as_dict(self) -> Dict[str, Any]:
        return {k: getattr(self, k) for k in ("mean", "median", "p95", "max", "rmse", "count", "dropped")}


def mesh_distance_stats(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> MeshDistanceStats:
    """Statistics of :func:`point_to_mesh_distance` (m); non-finite point rows are dropped.

    ``p95`` is the 95th percentile (linear interpolation, ``numpy.percentile``).

    Raises:
        ValueError: no finite point (besides the input errors of point_to_mesh_distance).
    """
    d = point_to_mesh_distance(points, vertices, faces)
    e = d[np.isfinite(d)]
    if e.size == 0:
        raise ValueError("mesh_distance_stats: no finite point to measure")
    return MeshDistanceStats(mean=float(e.mean()), median=float(np.median(e)), p95=float(np.percentile(e, 95)),
                             max=float(e.max()), rmse=float(np.sqrt(np.mean(e * e))), count=int(e.size),
                             dropped=int(d.size - e.size))

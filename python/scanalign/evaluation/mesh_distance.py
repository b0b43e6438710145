"""Reconstruction accuracy against a mesh: exact cloud-to-surface distances (m) and their summary.

:class:`MeshDistanceIndex` is the C++ index (a bounding-volume hierarchy over the triangles,
exact point-to-triangle distances after Ericson, Real-Time Collision Detection, 2005,
§5.1.5; queries in parallel) bound directly; its documentation is its docstring.  Points
and mesh share one frame; distances are unsigned (no inside / outside notion).
"""

from __future__ import annotations

import numpy as np

from scanalign._core.evaluation import MeshDistanceIndex, MeshDistanceStats

__all__ = ["MeshDistanceIndex", "MeshDistanceStats", "point_to_mesh_distance", "mesh_distance_stats"]


def point_to_mesh_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Exact Euclidean distance (m, (N,) float64) from each of the (N, 3) ``points`` to the
    surface of the mesh ``(vertices (V, 3), faces (F, 3))`` in the same frame; rows with
    NaN/Inf give NaN.  :class:`MeshDistanceIndex` reuses the index over several clouds and
    documents the method and the errors raised."""
    return MeshDistanceIndex(vertices, faces).distance(points)


def mesh_distance_stats(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> MeshDistanceStats:
    """:meth:`MeshDistanceIndex.stats` of ``points`` to the mesh ``(vertices, faces)``: mean,
    median, p95 (``numpy.percentile``'s linear interpolation), max and rmse (m) over the
    finite points; rows with NaN/Inf are dropped (counted).

    Raises:
        ValueError: no finite point (besides the input errors of point_to_mesh_distance).
    """
    return MeshDistanceIndex(vertices, faces).stats(points)

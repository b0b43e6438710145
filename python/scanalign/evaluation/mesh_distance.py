"""Exact, unsigned cloud-to-mesh distances (m) and their summary, points and mesh in one frame;
:class:`MeshDistanceIndex` is the C++ index (method and errors in its docstring)."""

from __future__ import annotations

import numpy as np

from scanalign._core.evaluation import MeshDistanceIndex, MeshDistanceStats

__all__ = ["MeshDistanceIndex", "MeshDistanceStats", "point_to_mesh_distance", "mesh_distance_stats"]


def point_to_mesh_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(N,) float64 distances (m) from the (N, 3) ``points`` to the mesh ``(vertices (V, 3),
    faces (F, 3))``; rows with NaN/Inf give NaN.  :class:`MeshDistanceIndex` reuses the index."""
    return MeshDistanceIndex(vertices, faces).distance(points)


def mesh_distance_stats(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> MeshDistanceStats:
    """:meth:`MeshDistanceIndex.stats` of ``points`` to the mesh ``(vertices, faces)``: mean, median, p95, max and
    rmse (m) over the finite points (rows with NaN/Inf are dropped, counted; ValueError when none is finite)."""
    return MeshDistanceIndex(vertices, faces).stats(points)

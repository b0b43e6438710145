"""RANSAC planes and spheres with conformal (CGA) models, and table segmentation.

Kleppe, PhD thesis, NTNU 2018, §5.2 (generic RANSAC, eq. (5.2)): draw a minimal sample, build a model, count the points
whose error is below the threshold ``E_T``, keep the best. The CGA plane through three points is
``Pi = P_A ^ P_B ^ P_C ^ e_inf`` (5.35), with the inlier test ``|P . Pi*| < E_T`` on the normalised dual plane
``Pi* = n + delta e_inf``, ``|n| = 1`` ((5.36), (4.65)-(4.67)); the sphere through four points is
``S = P_A ^ P_B ^ P_C ^ P_D`` (4.58), dual ``S* = up(c) - r^2/2 e_inf`` (4.59). The winner is refitted by least squares
over its inliers (plane: PCA; sphere: the CGA algebraic fit, (5.31)), and the returned ``inliers`` are then exactly the
finite points whose error under the *returned* model is below ``threshold`` (plane: ``|n.p - distance| < threshold``;
sphere: ``| |p - center| - radius | < threshold``).

Results are reproducible for a ``seed`` whatever ``num_threads`` (sample ``k`` depends on
``(seed, k)`` only). Input: ``(N, 3)`` float32/float64 points in metres; NaN/Inf rows are never
sampled nor inliers, and every returned index refers to a row of the input. When every sample
drawn is degenerate the result has ``status == "degenerate"`` (nothing is raised).

Table segmentation (the thesis's Paper 3, §3.1.2-3.1.3): :func:`segment_table_full` documents the five steps (crop,
RANSAC table plane, removal of the table and everything below it, Euclidean clustering, cluster size limits).

The functions, settings and results are the C++ ones (``scanalign._core.segmentation``),
each documented there: ``help(ransac_plane)``, ``help(PlaneResult)``.
"""

from __future__ import annotations

from typing import List, Tuple

import numpy as np

from scanalign import _core

__all__ = ["PlaneResult", "SphereResult", "CylinderResult", "TableSegmentationResult", "RansacSettings",
           "CylinderSettings", "TableSegmentationSettings", "ransac_plane", "ransac_sphere", "ransac_cylinder",
           "fit_cylinder", "segment_table", "segment_table_full", "plane_from_points", "sphere_from_points"]

globals().update({name: getattr(_core.segmentation, name) for name in __all__ if name != "segment_table"})  # as bound


def segment_table(points: np.ndarray, **kwargs: object) -> Tuple[PlaneResult, List[np.ndarray]]:
    """:func:`segment_table_full` (same arguments) returning just ``(plane, objects)``: the table
    :class:`PlaneResult` and one int64 index array into ``points`` per object, largest first."""
    r = segment_table_full(points, **kwargs)
    return r.plane, r.objects

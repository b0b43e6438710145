"""Curvature-based descriptor (CBD) of Kleppe, PhD thesis, NTNU 2018, ch. 6 / paper 5.

For every point, the PCA of its radius neighbourhood gives shape factors C_l, C_p, C_s (6.1)-(6.3); keypoints pass (6.4)
(or the automatic variant of paper 5, §III-B4); at each keypoint two CGA spheres are fitted to the neighbourhood,
weighted by ``exp(-gamma * |distance to a plane through the keypoint|)`` (6.8)-(6.11), one for the plane normal to v2
and one for the plane normal to v1. The descriptors are ``(r1, d1, r2, d2)`` (sphere radius, distance from the sphere
centre to the keypoint; paper 5 (29)-(32)) and the scalar ``F = (S1 + S2)·P = ½(r1² − d1²) + ½(r2² − d2²)``
(6.14)-(6.16).

Units: metres (points, radius, r, d), 1/m (gamma: the thesis's 0.2 per mm is 200), m² (F).
Descriptors are invariant to rigid motions of the cloud and to the signs of the PCA eigenvectors.

Example::

    from scanalign.pose import cbd
    f = cbd.compute(points)                     # thesis parameters
    pairs = cbd.match(f_model, f_scene)         # (K, 2) point indices
"""

from __future__ import annotations

from typing import Any, Literal, Optional, Tuple

import numpy as np

from scanalign import _core
from scanalign.common.arrays import as_points
from scanalign.common.settings import with_overrides

__all__ = ["CbdSettings", "ShapeThresholds", "CbdFeatures", "make_settings", "compute", "neighbourhood_pca",
           "keypoint_scores", "select_keypoints", "automatic_keypoints", "match"]

CbdSettings = _core.pose.CbdSettings
ShapeThresholds = _core.pose.ShapeThresholds
CbdFeatures = _core.pose.CbdFeatures
Variant = Literal["radius_distance", "scalar"]


def make_settings(settings: Optional[CbdSettings] = None, **overrides: object) -> CbdSettings:
    """A copy of ``settings`` (or the defaults) with fields overridden by keyword; enum fields
    take their names (``keypoint_mode="automatic"``, ``variant="scalar"``), ``thresholds`` a
    3-tuple. TypeError for an unknown field; values are checked in C++ when used."""
    if "thresholds" in overrides and not isinstance(overrides["thresholds"], ShapeThresholds):
        overrides["thresholds"] = ShapeThresholds(*(float(v) for v in overrides["thresholds"]))  # type: ignore
    return with_overrides(CbdSettings, settings, overrides, "CBD")


def compute(points: np.ndarray, settings: Optional[CbdSettings] = None, *,
            thresholds: Optional[ShapeThresholds] = None, **overrides: object) -> CbdFeatures:
    """CBD keypoints and descriptors of an (N, 3) float cloud (metres; NaN rows skipped) with :class:`CbdSettings`
    (thesis defaults) and keyword overrides; ``thresholds`` forces (6.4) with these deltas (inclusive), e.g. the model's
    derived ones applied to the scene. Returns :class:`CbdFeatures`, possibly with 0 keypoints (too sparse, or no edge
    or corner-like point)."""
    return _core.pose.compute_cbd(as_points(points, "points"), make_settings(settings, **overrides), thresholds)


def _default(name: str, value: Any) -> Any:
    """``value``, or the :class:`CbdSettings` default of the field ``name`` when None."""
    return getattr(CbdSettings(), name) if value is None else value


def neighbourhood_pca(points: np.ndarray, radius: Optional[float] = None, *,
                      num_threads: int = 0) -> Tuple[np.ndarray, np.ndarray]:
    """Neighbour counts (N,) and covariance eigenvalues (N, 3), descending, m², of every point's ball of ``radius``
    metres (default ``CbdSettings.radius``; k-d tree search). NaN points get count 0."""
    return _core.pose.neighbourhood_pca(as_points(points, "points"), float(_default("radius", radius)),
                                        int(num_threads))


def keypoint_scores(counts: np.ndarray, eigenvalues: np.ndarray, min_neighbors: Optional[int] = None) -> np.ndarray:
    """Score C_lC_p + C_pC_s + C_sC_l per point (paper 5, §III-B4); 1/3 below ``min_neighbors``."""
    return _core.pose.keypoint_scores(np.asarray(counts, np.uint32), np.asarray(eigenvalues, np.float64),
                                      int(_default("min_neighbors", min_neighbors)))


def select_keypoints(counts: np.ndarray, eigenvalues: np.ndarray, thresholds: ShapeThresholds = ShapeThresholds(),
                     min_neighbors: Optional[int] = None, *, inclusive: bool = False) -> np.ndarray:
    """Indices passing (6.4): ``count >= min_neighbors`` and some factor > its delta (>= when
    ``inclusive``); a delta >= 1 disables its factor."""
    return _core.pose.select_keypoints(np.asarray(counts, np.uint32), np.asarray(eigenvalues, np.float64),
                                       thresholds, int(_default("min_neighbors", min_neighbors)),
                                       bool(inclusive)).astype(np.int64)


def automatic_keypoints(counts: np.ndarray, eigenvalues: np.ndarray, k: Optional[int] = None,
                        min_neighbors: Optional[int] = None) -> Tuple[np.ndarray, ShapeThresholds]:
    """The ``k`` lowest-score points and the deltas they imply (paper 5, §III-B4)."""
    keys, t = _core.pose.automatic_keypoints(np.asarray(counts, np.uint32), np.asarray(eigenvalues, np.float64),
                                             int(_default("num_keypoints", k)),
                                             int(_default("min_neighbors", min_neighbors)))
    return keys.astype(np.int64), t


def match(source: CbdFeatures, target: CbdFeatures, *, variant: Variant = "radius_distance", k: int = 1,
          num_threads: int = 0) -> Tuple[np.ndarray, np.ndarray]:
    """Descriptor correspondences: each source keypoint with its ``k`` nearest target
    keypoints (a k-d tree over (r1, d1, r2, d2), or a sorted array of F).

    Returns:
        ``(pairs, error)``: (M, 2) int64 point indices (source cloud, target cloud) and the
        (M,) descriptor errors (paper 5 (32) or (6.18)).
    """
    members = _core.pose.CbdDescriptorVariant.__members__
    if variant not in members:
        raise ValueError(f"variant: unknown value {variant!r}; expected one of {sorted(members)}")
    return _core.pose.match_cbd(source, target, members[variant], int(k), int(num_threads))

"""Curvature-based descriptor (CBD) of Kleppe, PhD thesis, NTNU 2018, ch. 6 / paper 5.

For every point, the PCA of its radius neighbourhood gives shape factors C_l, C_p, C_s
(6.1)-(6.3); keypoints pass (6.4) (or the automatic variant of paper 5, §III-B4); at each
keypoint two CGA spheres are fitted to the neighbourhood, weighted by
``exp(-gamma * |distance to a plane through the keypoint|)`` (6.8)-(6.11), one for the
plane normal to v2 and one for the plane normal to v1. The descriptors are
``(r1, d1, r2, d2)`` (sphere radius, distance from the sphere centre to the keypoint; paper 5
(29)-(32)) and the scalar ``F = (S1 + S2)·P = ½(r1² − d1²) + ½(r2² − d2²)`` (6.14)-(6.16).

Units: metres (points, radius, r, d), 1/m (gamma: the thesis's 0.2 per mm is 200),
m² (F). Descriptors are invariant to rigid motions of the cloud and to the signs of the
PCA eigenvectors.

Example::

    from scanalign import cbd
    f = cbd.compute(points)                     # thesis parameters
    pairs = cbd.match(f_model, f_scene)         # (K, 2) point indices
"""

from __future__ import annotations

from typing import Literal, Optional, Tuple

import numpy as np

from . import _core
from ._arrays import as_points

__all__ = [
    "CbdSettings",
    "ShapeThresholds",
    "CbdFeatures",
    "make_settings",
    "compute",
    "neighbourhood_pca",
    "keypoint_scores",
    "select_keypoints",
    "automatic_keypoints",
    "match",
]

CbdSettings = _core.pose.CbdSettings
ShapeThresholds = _core.pose.ShapeThresholds
Variant = Literal["radius_distance", "scalar"]
KeypointMode = Literal["thresholds", "automatic"]

CbdFeatures = _core.pose.CbdFeatures


def make_settings(settings: Optional[CbdSettings] = None, **overrides: object) -> CbdSettings:
    """A copy of ``settings`` (or the defaults) with fields overridden by keyword.

    ``keypoint_mode`` and ``variant`` accept strings (``"thresholds"``/``"automatic"``,
    ``"radius_distance"``/``"scalar"``), ``thresholds`` a 3-tuple.

    Raises:
        TypeError: an unknown field.
        ValueError: a value out of range (checked again in C++).
    """
    s = CbdSettings()
    if settings is not None:
        for name in _FIELDS:
            setattr(s, name, getattr(settings, name))
    for name, value in overrides.items():
        if name not in _FIELDS:
            raise TypeError(f"unknown CBD setting {name!r}; known: {', '.join(_FIELDS)}")
        if name == "keypoint_mode" and isinstance(value, str):
            value = _enum(_core.pose.CbdKeypointMode, value, name)
        elif name == "variant" and isinstance(value, str):
            value = _enum(_core.pose.CbdDescriptorVariant, value, name)
        elif name == "thresholds" and not isinstance(value, ShapeThresholds):
            lin, pla, sph = (float(v) for v in value)  # type: ignore[union-attr]
            value = ShapeThresholds(lin, pla, sph)
        setattr(s, name, value)
    if not (np.isfinite(s.radius) and s.radius > 0):
        raise ValueError(f"radius must be a finite positive distance in metres, got {s.radius!r}")
    if not (np.isfinite(s.gamma) and s.gamma >= 0):
        raise ValueError(f"gamma must be finite and >= 0 (1/m), got {s.gamma!r}")
    if s.min_neighbors != 0 and s.min_neighbors < 5:
        raise ValueError("min_neighbors must be 0 (automatic) or >= 5")
    return s


_FIELDS = ("radius", "gamma", "min_neighbors", "keypoint_mode", "num_keypoints", "thresholds", "max_keypoints",
           "max_sphere_radius", "variant", "num_threads")


def _enum(enum: object, value: str, what: str) -> object:
    try:
        return getattr(enum, value)
    except AttributeError:
        names = [k for k in dir(enum) if not k.startswith("_") and k not in ("name", "value")]
        raise ValueError(f"{what}: unknown value {value!r}; expected one of {names}") from None


def compute(points: np.ndarray, settings: Optional[CbdSettings] = None, *,
            thresholds: Optional[ShapeThresholds] = None, **overrides: object) -> CbdFeatures:
    """CBD keypoints and descriptors of a cloud.

    Args:
        points: (N, 3) float32/float64, metres; NaN rows are skipped.
        settings: :class:`CbdSettings` (thesis defaults); ``**overrides`` change fields.
        thresholds: force (6.4) with these deltas (inclusive), e.g. the ones derived from
            the model's automatic keypoints, applied to the scene .

    Returns:
        :class:`CbdFeatures` (possibly with 0 keypoints: too sparse for ``radius`` and
        ``min_neighbors``, or no edge/corner-like point).

    Raises:
        TypeError / ValueError: bad array or settings.
    """
    return _core.pose.compute_cbd(as_points(points, "points"), make_settings(settings, **overrides), thresholds)


def neighbourhood_pca(points: np.ndarray, radius: float = 0.0063, *,
                      num_threads: int = 0) -> Tuple[np.ndarray, np.ndarray]:
    """Neighbour counts (N,) and covariance eigenvalues (N, 3), descending, m², of every
    point's ball of ``radius`` metres (k-d tree search). NaN points get count 0."""
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError("radius must be a finite positive distance in metres")
    return _core.pose.neighbourhood_pca(as_points(points, "points"), float(radius), int(num_threads))


def keypoint_scores(counts: np.ndarray, eigenvalues: np.ndarray, min_neighbors: int = 200) -> np.ndarray:
    """Score C_lC_p + C_pC_s + C_sC_l per point (paper 5, §III-B4); 1/3 below ``min_neighbors``."""
    return _core.pose.keypoint_scores(np.asarray(counts, np.uint32), np.asarray(eigenvalues, np.float64),
                                      int(min_neighbors))


def select_keypoints(counts: np.ndarray, eigenvalues: np.ndarray, thresholds: ShapeThresholds = ShapeThresholds(),
                     min_neighbors: int = 200, *, inclusive: bool = False) -> np.ndarray:
    """Indices passing (6.4): ``count >= min_neighbors`` and some factor > its delta (>= when
    ``inclusive``); a delta >= 1 disables its factor ."""
    return _core.pose.select_keypoints(np.asarray(counts, np.uint32), np.asarray(eigenvalues, np.float64),
                                       thresholds, int(min_neighbors), bool(inclusive)).astype(np.int64)


def automatic_keypoints(counts: np.ndarray, eigenvalues: np.ndarray, k: int = 2000,
                        min_neighbors: int = 200) -> Tuple[np.ndarray, ShapeThresholds]:
    """The ``k`` lowest-score points and the deltas they imply (paper 5, §III-B4)."""
    if int(k) < 1:
        raise ValueError("k must be >= 1")
    keys, t = _core.pose.automatic_keypoints(np.asarray(counts, np.uint32), np.asarray(eigenvalues, np.float64),
                                             int(k), int(min_neighbors))
    return keys.astype(np.int64), t


def match(source: CbdFeatures, target: CbdFeatures, *, variant: Variant = "radius_distance", k: int = 1,
          num_threads: int = 0) -> Tuple[np.ndarray, np.ndarray]:
    """Descriptor correspondences: each source keypoint with its ``k`` nearest target
    keypoints (a k-d tree over (r1, d1, r2, d2), or a sorted array of F).

    Returns:
        ``(pairs, error)``: (M, 2) int64 point indices (source cloud, target cloud) and the
        (M,) descriptor errors (paper 5 (32) or (6.18)).
    """
    v = _enum(_core.pose.CbdDescriptorVariant, variant, "variant")
    if int(k) < 1:
        raise ValueError("k must be >= 1")
    return _core.pose.match_cbd(source, target, v, int(k), int(num_threads))

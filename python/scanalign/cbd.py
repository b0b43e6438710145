"""Curvature-based descriptor (CBD) of thesis chapter 6 / paper 5 (spec §7.1-§7.4).

For every point, the PCA of its radius neighbourhood gives shape factors C_l, C_p, C_s
(6.1)-(6.3); keypoints pass (6.4) (or the automatic variant of P5 §III-B4); at each
keypoint two CGA spheres are fitted to the neighbourhood, weighted by
``exp(-gamma * |distance to a plane through the keypoint|)`` (6.8)-(6.11), one for the
plane normal to v2 and one for the plane normal to v1. The descriptors are
``(r1, d1, r2, d2)`` (sphere radius, distance from the sphere centre to the keypoint; P5
(29)-(32)) and the scalar ``F = (S1 + S2)·P = ½(r1² − d1²) + ½(r2² − d2²)`` (6.14)-(6.16).

Units: metres (points, radius, r, d), 1/m (gamma: the thesis's 0.2 per mm is 200),
m² (F). Descriptors are invariant to rigid motions of the cloud and to the signs of the
PCA eigenvectors (claim 18).

Example::

    from scanalign import cbd
    f = cbd.compute(points)                     # thesis parameters
    pairs = cbd.match(f_model, f_scene)         # (K, 2) point indices
"""

from __future__ import annotations

from dataclasses import dataclass
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
    "shape_factors_of",
    "keypoint_scores",
    "select_keypoints",
    "automatic_keypoints",
    "match",
]

CbdSettings = _core.pose.CbdSettings
ShapeThresholds = _core.pose.ShapeThresholds
Variant = Literal["radius_distance", "scalar"]
KeypointMode = Literal["thresholds", "automatic"]

CbdSettings.__doc__ = """Settings of the curvature-based descriptor (thesis values by default).

Fields:
    radius: neighbourhood radius r, metres (P5 §IV-A: 0.0063).
    gamma: plane-distance weight exp(-gamma |d|), 1/m (P5: 0.2 per mm = 200).
    min_neighbors: n_min, neighbours (the point included) needed to be a keypoint (P5: 200,
        for ~0.2 mm spacing); 0 = half the median neighbour count of the cloud.
    keypoint_mode: ``CbdKeypointMode.thresholds`` ((6.4), default) or ``.automatic``
        (the ``num_keypoints`` lowest shape scores, P5 §III-B4).
    num_keypoints: k of the automatic mode (P5: 2000).
    thresholds: :class:`ShapeThresholds` (delta_l, delta_p, delta_s) = (0.3, 1, 0.3).
    max_keypoints: cap in the thresholds mode, lowest scores kept (2000; 0 = none).
    max_sphere_radius: metres; larger spheres and planes count as flat (r = d = this,
        F term 0) (1.0).
    variant: ``CbdDescriptorVariant.radius_distance`` (default) or ``.scalar``, for matching.
    num_threads: OpenMP threads, 0 = all cores."""

ShapeThresholds.__doc__ = """delta_l, delta_p, delta_s of (6.4); a value >= 1 disables its shape factor."""


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


@dataclass
class CbdFeatures:
    """Keypoints and descriptors of one cloud (all arrays indexed by keypoint).

    Attributes:
        keypoints: (K,) int64 indices into the cloud.
        descriptors: (K, 4) ``(r1, d1, r2, d2)``, metres.
        scalar: (K,) ``F``, m².
        sphere1, sphere2: (K, 5) dual spheres ``[c; ½(c² − r²); 1]`` on (e1, e2, e3, e∞, e0)
            in the cloud's frame (flat ones as dual planes ``[n; δ; 0]``).
        flat1, flat2: (K,) bool, the sphere was a plane or larger than ``max_sphere_radius``.
        axes: (K, 3, 3) PCA eigenvectors v1, v2, v3 as columns.
        thresholds: the (6.4) deltas used (derived ones in the automatic mode).
        min_neighbors: n_min used.
        points_with_min_neighbors: points with at least n_min neighbours.
        seconds: wall time.
    """

    keypoints: np.ndarray
    descriptors: np.ndarray
    scalar: np.ndarray
    sphere1: np.ndarray
    sphere2: np.ndarray
    flat1: np.ndarray
    flat2: np.ndarray
    axes: np.ndarray
    thresholds: ShapeThresholds
    min_neighbors: int
    points_with_min_neighbors: int
    seconds: float

    def __len__(self) -> int:
        return len(self.keypoints)


def _features(d: dict) -> CbdFeatures:
    return CbdFeatures(
        keypoints=np.asarray(d["keypoints"], dtype=np.int64), descriptors=d["descriptors"], scalar=d["scalar"],
        sphere1=d["sphere1"]["dual"], sphere2=d["sphere2"]["dual"], flat1=d["sphere1"]["flat"],
        flat2=d["sphere2"]["flat"], axes=d["axes"], thresholds=d["thresholds"], min_neighbors=int(d["min_neighbors"]),
        points_with_min_neighbors=int(d["points_with_min_neighbors"]), seconds=float(d["seconds"]))


def compute(points: np.ndarray, settings: Optional[CbdSettings] = None, *,
            thresholds: Optional[ShapeThresholds] = None, **overrides: object) -> CbdFeatures:
    """CBD keypoints and descriptors of a cloud.

    Args:
        points: (N, 3) float32/float64, metres; NaN rows are skipped.
        settings: :class:`CbdSettings` (thesis defaults); ``**overrides`` change fields.
        thresholds: force (6.4) with these deltas (inclusive), e.g. the ones derived from
            the model's automatic keypoints, applied to the scene (spec §7.2).

    Returns:
        :class:`CbdFeatures` (possibly with 0 keypoints: too sparse for ``radius`` and
        ``min_neighbors``, or no edge/corner-like point).

    Raises:
        TypeError / ValueError: bad array or settings.
    """
    p = as_points(points, "points")
    s = make_settings(settings, **overrides)
    fn = _core.pose.cbd_f64 if p.dtype == np.float64 else _core.pose.cbd_f32
    return _features(fn(p, s, thresholds))


def neighbourhood_pca(points: np.ndarray, radius: float = 0.0063, *,
                      num_threads: int = 0) -> Tuple[np.ndarray, np.ndarray]:
    """Neighbour counts (N,) and covariance eigenvalues (N, 3), descending, m², of every
    point's ball of ``radius`` metres (k-d tree search; spec §7.1). NaN points get count 0."""
    p = as_points(points, "points")
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError("radius must be a finite positive distance in metres")
    fn = _core.pose.neighbourhood_pca_f64 if p.dtype == np.float64 else _core.pose.neighbourhood_pca_f32
    count, ev = fn(p, float(radius), int(num_threads))
    return count.astype(np.int64), ev


def shape_factors_of(eigenvalues: np.ndarray) -> np.ndarray:
    """(N, 3) shape factors (C_l, C_p, C_s) of (N, 3) eigenvalues (6.1)-(6.3); rows with zero
    spread give zeros."""
    ev = np.sort(np.asarray(eigenvalues, dtype=np.float64), axis=-1)[..., ::-1]
    s = ev.sum(axis=-1, keepdims=True)
    c = np.stack([ev[..., 0] - ev[..., 1], 2 * (ev[..., 1] - ev[..., 2]), 3 * ev[..., 2]], axis=-1)
    return np.divide(c, s, out=np.zeros_like(c), where=s > 0)


def keypoint_scores(counts: np.ndarray, eigenvalues: np.ndarray, min_neighbors: int = 200) -> np.ndarray:
    """Score C_lC_p + C_pC_s + C_sC_l per point (P5 §III-B4); 1/3 below ``min_neighbors``."""
    return _core.pose.keypoint_scores(np.asarray(counts, np.uint32), np.asarray(eigenvalues, np.float64),
                                      int(min_neighbors))


def select_keypoints(counts: np.ndarray, eigenvalues: np.ndarray, thresholds: ShapeThresholds = ShapeThresholds(),
                     min_neighbors: int = 200, *, inclusive: bool = False) -> np.ndarray:
    """Indices passing (6.4): ``count >= min_neighbors`` and some factor > its delta (>= when
    ``inclusive``); a delta >= 1 disables its factor (claim 16)."""
    return _core.pose.select_keypoints(np.asarray(counts, np.uint32), np.asarray(eigenvalues, np.float64),
                                       thresholds, int(min_neighbors), bool(inclusive)).astype(np.int64)


def automatic_keypoints(counts: np.ndarray, eigenvalues: np.ndarray, k: int = 2000,
                        min_neighbors: int = 200) -> Tuple[np.ndarray, ShapeThresholds]:
    """The ``k`` lowest-score points and the deltas they imply (P5 §III-B4, claim 17)."""
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
        (M,) descriptor errors (P5 (32) or (6.18)).
    """
    v = _enum(_core.pose.CbdDescriptorVariant, variant, "variant")
    if int(k) < 1:
        raise ValueError("k must be >= 1")
    s, t, e = _core.pose.match_cbd(source.descriptors, source.scalar, target.descriptors, target.scalar, v, int(k),
                                   int(num_threads))
    pairs = np.stack([source.keypoints[s.astype(np.int64)], target.keypoints[t.astype(np.int64)]], axis=1)
    return pairs, e

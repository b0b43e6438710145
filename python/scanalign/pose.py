"""Pose of a known part from its CAD model (thesis ch. 6-7, papers 4-5; spec §6-§8).

Building blocks (all C++):

* :func:`estimate_motor` -- Valkenburg-Dorst motor estimation from point pairs (spec §7.5),
  equal to :func:`estimate_rigid_svd` (Kabsch) to numerical precision (claim 21).
* :func:`ransac_rigid_motion` -- RANSAC over putative pairs with a motor refit.
* :func:`align_cbd` -- curvature-based descriptor matching + RANSAC (paper 5).
* :func:`align_flags` -- paper 4's correspondence-free initial alignment with motors
  (centroid + average normal line; partial views only, closed surfaces are refused).
* :func:`pcl_feature_alignment` -- the stock PCL baselines of the thesis (FPFH, SHOT,
  3DSC with SampleConsensusPrerejective or SAC-IA, and PPF) with its preset.

Pipeline: :func:`estimate_pose` matches a model (a mesh rendered from the 42 vertices of a
tessellated sphere, or a cloud) against one object cloud, refines with scanalign's ICP and
keeps the best view; :func:`find_objects` first segments the table and clusters the objects
(paper 3 pipeline, :func:`scanalign.segmentation.segment_table`).

Frames and units: metres and radians. Every transform is ``T_target_source``
(``p_target = T @ p_source``); for the pipeline that is ``T_scene_model``: it maps model
(CAD) coordinates into the scene (camera) frame.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Literal, Optional, Sequence, Tuple, Union

import numpy as np

from . import _core, cbd as _cbd
from ._arrays import as_points, as_transform

__all__ = [
    "MotorEstimate",
    "RansacResult",
    "CoarseAlignment",
    "FlagAlignment",
    "PoseResult",
    "ObjectPoses",
    "estimate_motor",
    "estimate_rigid_svd",
    "motor_to_matrix",
    "ransac_rigid_motion",
    "align_cbd",
    "normal_line_flag",
    "align_flags",
    "pcl_feature_alignment",
    "alignment_fitness",
    "estimate_pose",
    "find_objects",
    "write_pose_outputs",
    "METHODS",
    "THESIS_PCL_PRESET",
]

Method = Literal["cbd", "fpfh", "fpfh_sac_ia", "shot", "3dsc", "ppf", "flags"]
METHODS: Tuple[str, ...] = ("cbd", "fpfh", "fpfh_sac_ia", "shot", "3dsc", "ppf", "flags")

#: The thesis's baseline preset (spec §7.6), metres: 1 mm voxel grid, 30 mm normal and feature
#: radius, RANSAC with 1000 iterations and a 5 mm inlier threshold (3DSC: 40 mm radii, 4 mm
#: minimal radius, 8 mm density radius).
THESIS_PCL_PRESET: Dict[str, Dict[str, float]] = {
    "fpfh": dict(voxel_size=0.001, normal_radius=0.03, feature_radius=0.03, max_iterations=1000,
                 inlier_threshold=0.005),
    "shot": dict(voxel_size=0.001, normal_radius=0.03, feature_radius=0.03, max_iterations=1000,
                 inlier_threshold=0.005),
    "3dsc": dict(voxel_size=0.001, normal_radius=0.04, feature_radius=0.04, shape_context_min_radius=0.004,
                 shape_context_density_radius=0.008, max_iterations=1000, inlier_threshold=0.005),
    "ppf": dict(voxel_size=0.001, normal_radius=0.03, inlier_threshold=0.005),
}


# ---------------------------------------------------------------------------------------------
# Motor estimation and RANSAC
# ---------------------------------------------------------------------------------------------

@dataclass
class MotorEstimate:
    """A rigid motion estimated from point pairs.

    Attributes:
        T_target_source: (4, 4) ``y ≈ R x + t``.
        motor: (8,) coefficients on (1, e23, e31, e12, e1∞, e2∞, e3∞, e123∞), ``M M̃ = 1``.
        rmse: weighted RMS pair residual, metres.
        count: pairs used.
        valid: False when there were fewer than 3 pairs or they were collinear.
        message: why not valid.
    """

    T_target_source: np.ndarray
    motor: np.ndarray
    rmse: float
    count: int
    valid: bool
    message: str


def _pairs_arrays(source: object, target: object) -> Tuple[np.ndarray, np.ndarray]:
    s = as_points(source, "source", np.dtype(np.float64))
    t = as_points(target, "target", np.dtype(np.float64))
    if s.shape != t.shape:
        raise ValueError(f"source and target must be paired (same shape), got {s.shape} and {t.shape}")
    return s, t


def _weights(weights: object, n: int) -> Optional[np.ndarray]:
    if weights is None:
        return None
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (n,):
        raise ValueError(f"weights: expected shape ({n},), got {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ValueError("weights must be finite and >= 0")
    return w


def estimate_motor(source: np.ndarray, target: np.ndarray, weights: Optional[np.ndarray] = None, *,
                   normalize: bool = True) -> MotorEstimate:
    """Valkenburg-Dorst motor from pairs ``source[i] <-> target[i]`` (spec §7.5, (36)-(44)).

    Maximises ``Σ w_k ⟨M̃ Y_k M X_k⟩ = −½ Σ w_k |y_k − M x_k M̃|²`` over unit motors: the
    rotor is the top eigenvector of ``Q_rr − Q_rt Q_tt⁺ Q_tr``, the translation part follows
    from (44).

    Args:
        source, target: (N, 3) paired points, metres (source frame / target frame).
        weights: optional (N,) non-negative weights.
        normalize: centre and scale the data before forming Q (better conditioned; the
            estimator is equivariant, so only rounding changes).

    Returns:
        :class:`MotorEstimate`; ``valid`` is False (identity pose) for fewer than 3 pairs or
        collinear data.

    Raises:
        TypeError / ValueError: bad arrays, NaN pairs, bad weights.
    """
    s, t = _pairs_arrays(source, target)
    _check_finite_pairs(s, t, weights)
    return MotorEstimate(**_core.pose.estimate_motor(s, t, _weights(weights, len(s)), bool(normalize)))


def estimate_rigid_svd(source: np.ndarray, target: np.ndarray,
                       weights: Optional[np.ndarray] = None) -> MotorEstimate:
    """Kabsch/Umeyama (SVD) estimate from the same pairs, the oracle of claim 21."""
    s, t = _pairs_arrays(source, target)
    _check_finite_pairs(s, t, weights)
    return MotorEstimate(**_core.pose.estimate_rigid_svd(s, t, _weights(weights, len(s))))


def _check_finite_pairs(s: np.ndarray, t: np.ndarray, weights: object) -> None:
    used = np.ones(len(s), bool) if weights is None else np.asarray(weights, np.float64) != 0
    if used.shape == (len(s),) and not (np.all(np.isfinite(s[used])) and np.all(np.isfinite(t[used]))):
        raise ValueError("pairs contain NaN or infinite coordinates")


def motor_to_matrix(motor: Sequence[float]) -> np.ndarray:
    """(4, 4) transform of an 8-coefficient motor (normalised first)."""
    m = np.asarray(motor, dtype=np.float64)
    if m.shape != (8,) or not np.all(np.isfinite(m)):
        raise ValueError("motor: expected 8 finite coefficients")
    return _core.pose.motor_to_matrix(m)


@dataclass
class RansacResult:
    """Outcome of :func:`ransac_rigid_motion`.

    Attributes:
        T_target_source: (4, 4) the pose (identity when not found).
        found: a hypothesis with at least 3 inlier pairs was found.
        inliers: (K,) int64 indices into the pair list.
        inlier_rmse: metres, over the inlier pairs.
        iterations: hypotheses drawn.
        message: why nothing was found.
    """

    T_target_source: np.ndarray
    found: bool
    inliers: np.ndarray
    inlier_rmse: float
    iterations: int
    message: str


def _ransac_settings(max_iterations: int, inlier_threshold: float, edge_similarity: float, confidence: float,
                     seed: int, num_threads: int) -> Any:
    s = _core.pose.CorrespondenceRansacSettings()
    if int(max_iterations) < 1:
        raise ValueError("max_iterations must be >= 1")
    if not (np.isfinite(inlier_threshold) and inlier_threshold > 0):
        raise ValueError("inlier_threshold must be a finite positive distance in metres")
    if not 0 <= edge_similarity < 1:
        raise ValueError("edge_similarity must be in [0, 1)")
    if not 0 < confidence < 1:
        raise ValueError("confidence must be in (0, 1)")
    s.max_iterations, s.inlier_threshold, s.edge_similarity = int(max_iterations), float(inlier_threshold), float(
        edge_similarity)
    s.confidence, s.seed, s.num_threads = float(confidence), int(seed) & (2**64 - 1), int(num_threads)
    return s


def ransac_rigid_motion(source: np.ndarray, target: np.ndarray, pairs: np.ndarray, *, max_iterations: int = 1000,
                        inlier_threshold: float = 0.005, edge_similarity: float = 0.9, confidence: float = 0.999,
                        seed: int = 0, num_threads: int = 0) -> RansacResult:
    """Rigid motion from putative pairs with outliers: RANSAC over 3-pair samples
    (prerejected unless their triangles' edge lengths agree within ``edge_similarity``),
    Kabsch hypotheses, then a motor refit on the inliers (spec §7.5).

    Args:
        source, target: (N, 3) / (M, 3) points, metres.
        pairs: (K, 2) integer indices (into source, into target).
        max_iterations: hypotheses (thesis baselines: 1000); stops early at ``confidence``.
        inlier_threshold: metres (thesis: 0.005).
        seed: random seed; results do not depend on the thread count.

    Raises:
        TypeError / ValueError: bad arrays, indices out of range, bad settings.
    """
    s = as_points(source, "source", np.dtype(np.float64))
    t = as_points(target, "target", np.dtype(np.float64))
    p = np.asarray(pairs)
    if p.ndim != 2 or p.shape[1] != 2 or (p.size and not np.issubdtype(p.dtype, np.integer)):
        raise ValueError(f"pairs: expected an integer (K, 2) array, got {p.dtype} {p.shape}")
    if p.size and (p.min() < 0 or p[:, 0].max() >= len(s) or p[:, 1].max() >= len(t)):
        raise ValueError("pairs: index out of range")
    settings = _ransac_settings(max_iterations, inlier_threshold, edge_similarity, confidence, seed, num_threads)
    d = _core.pose.ransac_rigid_motion(s, t, p.astype(np.uint32).reshape(-1, 2), settings)
    d["inliers"] = np.asarray(d["inliers"], dtype=np.int64)
    return RansacResult(**d)


def alignment_fitness(source: np.ndarray, target: np.ndarray, T_target_source: np.ndarray,
                      threshold: float = 0.005, *, num_threads: int = 0) -> Tuple[float, float]:
    """``(fitness, inlier_rmse)``: the fraction of finite source points whose nearest target
    point lies within ``threshold`` metres after ``T_target_source``, and their RMS distance (m)."""
    s = as_points(source, "source", np.dtype(np.float64))
    t = as_points(target, "target", np.dtype(np.float64))
    if not (np.isfinite(threshold) and threshold > 0):
        raise ValueError("threshold must be a finite positive distance in metres")
    return _core.pose.alignment_fitness_f64(s, t, as_transform(T_target_source, "T_target_source"), float(threshold),
                                            int(num_threads))


# ---------------------------------------------------------------------------------------------
# Coarse alignment
# ---------------------------------------------------------------------------------------------

@dataclass
class CoarseAlignment:
    """A coarse (global) registration of a source cloud to a target cloud.

    Attributes:
        T_target_source: (4, 4) maps source into target.
        found: the method produced a pose (RANSAC consensus / PCL convergence).
        fitness: fraction of source points within ``inlier_threshold`` of the target.
        inlier_rmse: metres, over those points.
        method: which method.
        seconds: wall time; ``feature_seconds`` the part spent on keypoints/descriptors.
        details: method-specific figures (keypoints, matches, inliers, ...).
        message: why nothing was found.
    """

    T_target_source: np.ndarray
    found: bool
    fitness: float
    inlier_rmse: float
    method: str
    seconds: float
    feature_seconds: float = 0.0
    details: Dict[str, Any] = field(default_factory=dict)
    message: str = ""


def _cbd_alignment_settings(cbd_settings: Optional[_cbd.CbdSettings], cbd_overrides: Dict[str, object],
                            ransac: Dict[str, Any], matches_per_keypoint: int) -> Any:
    s = _core.pose.CbdAlignmentSettings()
    s.cbd = _cbd.make_settings(cbd_settings, **cbd_overrides)
    r = dict(max_iterations=10000, inlier_threshold=0.005, edge_similarity=0.9, confidence=0.999, seed=0,
             num_threads=0)
    unknown = set(ransac) - set(r)
    if unknown:
        raise TypeError(f"unknown RANSAC settings {sorted(unknown)}; known: {sorted(r)}")
    r.update(ransac)
    s.ransac = _ransac_settings(**r)
    if int(matches_per_keypoint) < 1:
        raise ValueError("matches_per_keypoint must be >= 1")
    s.matches_per_keypoint = int(matches_per_keypoint)
    return s


def align_cbd(source: np.ndarray, target: np.ndarray, settings: Optional[_cbd.CbdSettings] = None, *,
              ransac: Optional[Dict[str, Any]] = None, matches_per_keypoint: int = 1,
              **cbd_overrides: object) -> CoarseAlignment:
    """Coarse alignment with the curvature-based descriptor (paper 5): CBD on both clouds,
    nearest-descriptor matches, RANSAC + motor refit.

    Args:
        source: (N, 3) e.g. a model view, metres; ``target``: (M, 3) e.g. a scene object.
        settings / **cbd_overrides: :class:`scanalign.cbd.CbdSettings` fields (thesis defaults:
            radius 6.3 mm, gamma 200 /m, n_min 200, 2000 keypoints).
        ransac: :func:`ransac_rigid_motion` keywords (default 10000 iterations, 5 mm).
        matches_per_keypoint: k nearest target descriptors per source keypoint.

    Returns:
        :class:`CoarseAlignment` (``found`` False with a message when there are too few
        keypoints or no consensus).
    """
    s = as_points(source, "source")
    t = as_points(target, "target", s.dtype)
    if len(s) == 0 or len(t) == 0:
        raise ValueError("align_cbd: source and target must not be empty")
    st = _cbd_alignment_settings(settings, cbd_overrides, ransac or {}, matches_per_keypoint)
    fn = _core.pose.align_cbd_f64 if s.dtype == np.float64 else _core.pose.align_cbd_f32
    d = fn(s, t, st)
    details = {k: d[k] for k in ("source_keypoints", "target_keypoints", "matches", "match_inliers",
                                 "match_seconds", "ransac_seconds")}
    return CoarseAlignment(T_target_source=d["T_target_source"], found=bool(d["found"]), fitness=float(d["fitness"]),
                           inlier_rmse=float(d["inlier_rmse"]), method="cbd", seconds=float(d["seconds"]),
                           feature_seconds=float(d["feature_seconds"]), details=details, message=d["message"])


@dataclass
class FlagAlignment:
    """Outcome of :func:`align_flags` (paper 4).

    Attributes:
        T_target_source: (4, 4) the motor as a matrix, ``f_target = M f_source M̃``.
        valid: False when refused (closed surface, centroid on the average line).
        iterations: Levenberg-Marquardt iterations.
        cost: ½(δ² + sin²(θ/2) + d²) at the solution (m² and rad² mixed, as the thesis).
        source_flag, target_flag: dicts with centroid, direction, foot (m), mean_normal_length,
            pitch (m), count.
        message: why refused.
    """

    T_target_source: np.ndarray
    valid: bool
    iterations: int
    cost: float
    source_flag: Dict[str, Any]
    target_flag: Dict[str, Any]
    message: str


def _cloud_with_normals(points: object, normals: object, what: str) -> Tuple[np.ndarray, np.ndarray]:
    p = as_points(points, what, np.dtype(np.float64))
    n = as_points(normals, f"{what}_normals", np.dtype(np.float64))
    if p.shape != n.shape:
        raise ValueError(f"{what}: points and normals differ in shape: {p.shape} vs {n.shape}")
    if len(p) == 0:
        raise ValueError(f"{what}: empty cloud")
    return p, n


def normal_line_flag(points: np.ndarray, normals: np.ndarray) -> Dict[str, Any]:
    """The flag of a cloud (paper 4): centroid and average normal line (spec §6).

    Returns a dict: ``centroid`` (3,) m, ``direction`` (3,) unit, ``foot`` (3,) m (the line's
    point nearest the centroid), ``mean_normal_length`` (|mean unit normal|, ~0 for a
    closed surface), ``pitch`` (m), ``count``."""
    p, n = _cloud_with_normals(points, normals, "points")
    return _core.pose.normal_line_flag_f64(p, n)


def align_flags(source: np.ndarray, source_normals: np.ndarray, target: np.ndarray, target_normals: np.ndarray, *,
                min_mean_normal_length: float = 0.05, max_iterations: int = 100) -> FlagAlignment:
    """Paper 4 initial alignment with motors: the motor mapping the source flag (centroid +
    average normal line) onto the target's, by Levenberg-Marquardt on the motor manifold.

    Works on partial (single-view) clouds only: on a closed surface the normals average to
    zero (claim 33) and the result is refused (``valid`` False) when the mean unit normal is
    shorter than ``min_mean_normal_length``.
    """
    a, an = _cloud_with_normals(source, source_normals, "source")
    b, bn = _cloud_with_normals(target, target_normals, "target")
    s = _core.pose.FlagAlignmentSettings()
    if not 0 <= min_mean_normal_length < 1:
        raise ValueError("min_mean_normal_length must be in [0, 1)")
    s.min_mean_normal_length, s.max_iterations = float(min_mean_normal_length), int(max_iterations)
    return FlagAlignment(**_core.pose.align_flags_f64(a, an, b, bn, s))


_DESCRIPTOR = {"fpfh": ("fpfh", "prerejective"), "fpfh_sac_ia": ("fpfh", "sac_ia"), "shot": ("shot", "prerejective"),
               "3dsc": ("3dsc", "prerejective"), "ppf": ("ppf", "prerejective")}
_PCL_DEFAULTS = dict(voxel_size=0.001, normal_radius=0.03, feature_radius=0.03, shot_lrf_radius=0.0,
                     shape_context_min_radius=0.004, shape_context_density_radius=0.008, max_iterations=1000,
                     inlier_threshold=0.005, num_samples=3, correspondence_randomness=5, similarity_threshold=0.9,
                     inlier_fraction=0.25, min_sample_distance=0.0, ppf_angle_step=math.radians(12.0),
                     ppf_distance_step=0.0, ppf_scene_fraction=0.1, seed=0, num_threads=0)


def pcl_feature_alignment(source: np.ndarray, target: np.ndarray, method: str = "fpfh",
                          **settings: object) -> CoarseAlignment:
    """A stock PCL 1.13 coarse registration (the thesis's baselines, spec §7.6).

    Args:
        source, target: (N, 3) / (M, 3) points, metres (converted to float32 for PCL).
        method: ``"fpfh"`` (FPFHEstimationOMP + SampleConsensusPrerejective), ``"fpfh_sac_ia"``
            (SampleConsensusInitialAlignment), ``"shot"``, ``"3dsc"`` (both with the
            prerejective matcher) or ``"ppf"`` (PPFRegistration).
        **settings: override the preset :data:`THESIS_PCL_PRESET` for the method: voxel_size,
            normal_radius, feature_radius, shot_lrf_radius, shape_context_min_radius,
            shape_context_density_radius (m), max_iterations, inlier_threshold (m),
            num_samples, correspondence_randomness, similarity_threshold, inlier_fraction,
            min_sample_distance (m), ppf_angle_step (rad), ppf_distance_step (m),
            ppf_scene_fraction, seed, num_threads.
    """
    if method not in _DESCRIPTOR:
        raise ValueError(f"method: expected one of {sorted(_DESCRIPTOR)}, got {method!r}")
    unknown = set(settings) - set(_PCL_DEFAULTS)
    if unknown:
        raise TypeError(f"unknown PCL settings {sorted(unknown)}; known: {sorted(_PCL_DEFAULTS)}")
    s = as_points(source, "source", np.dtype(np.float32))
    t = as_points(target, "target", np.dtype(np.float32))
    if len(s) == 0 or len(t) == 0:
        raise ValueError("pcl_feature_alignment: source and target must not be empty")
    kw = dict(_PCL_DEFAULTS)
    kw.update(THESIS_PCL_PRESET["fpfh" if method == "fpfh_sac_ia" else method])
    kw.update(settings)
    descriptor, matcher = _DESCRIPTOR[method]
    d = _core.pose.pcl_feature_alignment(s, t, descriptor, matcher, **kw)
    details = {k: d[k] for k in ("source_points", "target_points", "source_descriptors", "target_descriptors")}
    return CoarseAlignment(T_target_source=d["T_target_source"], found=bool(d["converged"]),
                           fitness=float(d["fitness"]), inlier_rmse=float(d["inlier_rmse"]), method=method,
                           seconds=float(d["seconds"]), feature_seconds=float(d["feature_seconds"]), details=details,
                           message=d["message"])


# ---------------------------------------------------------------------------------------------
# Pipeline
# ---------------------------------------------------------------------------------------------

@dataclass
class PoseResult:
    """Pose of a model in an object cloud.

    Attributes:
        T_scene_model: (4, 4) maps model (CAD) coordinates into the scene frame.
        found: a coarse alignment succeeded and ICP refined it.
        fitness: fraction of the matched model cloud within ``inlier_threshold`` of the scene
            after ICP.
        coverage: fraction of the object's points within ``inlier_threshold`` of the placed
            model cloud.
        inlier_rmse: metres, ICP inliers.
        method: coarse method used.
        view: index of the best model view (None when the model was a cloud).
        seconds: wall time, all views; ``coarse_seconds`` the part in coarse alignment.
        candidates: per-view summaries (view, found, fitness, coverage, score).
        message: why nothing was found.
    """

    T_scene_model: np.ndarray
    found: bool
    fitness: float
    coverage: float
    inlier_rmse: float
    method: str
    view: Optional[int]
    seconds: float
    coarse_seconds: float = 0.0
    candidates: List[Dict[str, Any]] = field(default_factory=list)
    message: str = ""

    def as_dict(self) -> Dict[str, Any]:
        d = {k: getattr(self, k) for k in ("found", "fitness", "coverage", "inlier_rmse", "method", "view", "seconds",
                                          "coarse_seconds", "message")}
        d["T_scene_model"] = np.asarray(self.T_scene_model).tolist()
        return d


def _model_clouds(model: object, resolution: int, views: Optional[Sequence[int]]
                  ) -> Tuple[List[np.ndarray], List[np.ndarray], List[Optional[int]]]:
    """The model as a list of (points, normals) candidates: one per tessellated-sphere view
    of a mesh (spec §8: 42 views), the given views, or the given cloud itself."""
    from . import cad, io

    if isinstance(model, list) and model and all(isinstance(v, cad.ModelView) for v in model):
        vs = model
    else:
        if isinstance(model, (str, Path)):
            model = io.read_mesh(model)
        vs = None
    if vs is None and isinstance(model, np.ndarray):
        p = as_points(model, "model", np.dtype(np.float64))
        if len(p) == 0:
            raise ValueError("model: empty cloud")
        from .features import estimate_normals
        return [p], [estimate_normals(p, radius=0.005, viewpoint=p.mean(axis=0) + np.array([0, 0, 1.0]))], [None]
    if vs is None:
        vs = cad.render_views(model, resolution=resolution)
    idx = list(range(len(vs))) if views is None else [int(i) for i in views]
    for i in idx:
        if not 0 <= i < len(vs):
            raise ValueError(f"views: index {i} out of range 0..{len(vs) - 1}")
    return [vs[i].points for i in idx], [vs[i].normals for i in idx], list(idx)


def estimate_pose(model: object, scene: np.ndarray, *, method: Method = "cbd", views: Optional[Sequence[int]] = None,
                  resolution: int = 150, inlier_threshold: float = 0.005, icp_distance: float = 0.01,
                  normal_radius: float = 0.005, cbd_settings: Optional[_cbd.CbdSettings] = None,
                  ransac: Optional[Dict[str, Any]] = None, pcl_settings: Optional[Dict[str, Any]] = None,
                  progress: bool = False, num_threads: int = 0, **cbd_overrides: object) -> PoseResult:
    """Pose of ``model`` in one object cloud: coarse alignment of every model view (or the
    model cloud) to the object, ICP refinement (point-to-plane, scanalign's engine), and the
    candidate with the best score ``2 fitness coverage / (fitness + coverage)``.

    Args:
        model: a mesh (:class:`scanalign.io.Mesh`, ``(vertices, faces)`` or a mesh file path;
            metres) rendered from the 42 vertices of a tessellated sphere, the list of
            :class:`scanalign.cad.ModelView` that :func:`scanalign.cad.render_views` returned
            (rendered once, reused across objects), or an (N, 3) cloud.
        scene: (M, 3) the object's points in the scene (camera) frame, metres.
        method: coarse method, one of :data:`METHODS` (``"cbd"`` default).
        views: subset of view indices to try (default all 42).
        resolution: model view image size, pixels (thesis: 90 to 400).
        inlier_threshold: metres, for fitness and coverage (thesis: 5 mm).
        icp_distance: ICP max correspondence distance, metres.
        normal_radius: scene normal radius for point-to-plane ICP and flags, metres.
        cbd_settings / **cbd_overrides: CBD settings (``min_neighbors`` defaults to 0 here:
            automatic, since scan density varies).
        ransac: RANSAC keywords for CBD; ``pcl_settings``: PCL baseline overrides.
        progress: print a progress bar over the views on stderr.

    Returns:
        :class:`PoseResult` (``found`` False with a message when no view aligned).

    Raises:
        TypeError / ValueError: bad inputs or settings.
    """
    from .features import estimate_normals
    from .registration import icp

    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    t_start = time.perf_counter()
    scene = as_points(scene, "scene", np.dtype(np.float64))
    finite = np.all(np.isfinite(scene), axis=1)
    scene = scene[finite]
    for name, v in (("inlier_threshold", inlier_threshold), ("icp_distance", icp_distance),
                    ("normal_radius", normal_radius)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite positive distance in metres")
    clouds, normals, idx = _model_clouds(model, resolution, views)
    nothing = PoseResult(np.eye(4), False, 0.0, 0.0, 0.0, method, None, 0.0)
    if len(scene) < 10:
        nothing.message = f"scene has {len(scene)} finite points; need at least 10"
        nothing.seconds = time.perf_counter() - t_start
        return nothing
    scene_normals = estimate_normals(scene, radius=normal_radius, num_threads=num_threads)
    ok_n = np.all(np.isfinite(scene_normals), axis=1)
    cbd_overrides.setdefault("min_neighbors", 0)
    cbd_overrides.setdefault("num_threads", num_threads)
    scene_features = None
    if method == "cbd":
        st = _cbd_alignment_settings(cbd_settings, cbd_overrides, dict(ransac or {}, inlier_threshold=inlier_threshold,
                                                                        num_threads=num_threads), 1)
        scene_features = _cbd.compute(scene, st.cbd)
        if len(scene_features) < 3:
            nothing.message = (f"the object has {len(scene_features)} CBD keypoints (need 3): too few points or no "
                               f"curved/edge regions at radius {st.cbd.radius} m")
            nothing.seconds = time.perf_counter() - t_start
            return nothing
    from tqdm.auto import tqdm

    bar = tqdm(total=len(clouds), desc=f"pose ({method})", unit="view", file=sys.stderr, dynamic_ncols=True,
               disable=not progress or len(clouds) < 2)
    best: Optional[PoseResult] = None
    best_score = -1.0
    candidates: List[Dict[str, Any]] = []
    coarse_seconds = 0.0
    for pts, nrm, vi in zip(clouds, normals, idx):
        t0 = time.perf_counter()
        coarse = _coarse(method, pts, nrm, scene, scene_normals, ok_n, scene_features, st if method == "cbd" else None,
                         inlier_threshold, pcl_settings or {}, num_threads)
        coarse_seconds += time.perf_counter() - t0
        cand: Dict[str, Any] = {"view": vi, "found": coarse.found, "coarse_fitness": coarse.fitness}
        if coarse.found:
            r = icp(pts, scene[ok_n], scene_normals[ok_n], init=coarse.T_target_source,
                    max_correspondence_distance=icp_distance, num_threads=num_threads)
            T = np.asarray(r.T_target_source)
            fit, rmse = alignment_fitness(pts, scene, T, inlier_threshold, num_threads=num_threads)
            cov, _ = alignment_fitness(scene, pts, np.linalg.inv(T), inlier_threshold, num_threads=num_threads)
            score = 2 * fit * cov / (fit + cov) if fit + cov > 0 else 0.0
            cand.update(fitness=fit, coverage=cov, rmse=rmse, score=score)
            if best is None or score > best_score:
                best, best_score = PoseResult(T, True, fit, cov, rmse, method, vi, 0.0), score
        candidates.append(cand)
        bar.update(1)
    bar.close()
    result = best if best is not None else nothing
    if best is None:
        result.message = f"no model view aligned with {method} (coarse alignment found no consensus)"
    result.candidates = candidates
    result.seconds = time.perf_counter() - t_start
    result.coarse_seconds = coarse_seconds
    return result


def _coarse(method: str, pts: np.ndarray, nrm: np.ndarray, scene: np.ndarray, scene_normals: np.ndarray,
            ok_n: np.ndarray, scene_features: Optional[_cbd.CbdFeatures], st: Any, inlier_threshold: float,
            pcl_settings: Dict[str, Any], num_threads: int) -> CoarseAlignment:
    t0 = time.perf_counter()
    if method == "cbd":
        f = _cbd.compute(pts, st.cbd)
        if len(f) < 3:
            return CoarseAlignment(np.eye(4), False, 0.0, 0.0, "cbd", time.perf_counter() - t0,
                                   message="too few model keypoints")
        pairs, _ = _cbd.match(f, scene_features, variant=st.cbd.variant.name, num_threads=num_threads)
        r = ransac_rigid_motion(pts, scene, pairs, max_iterations=st.ransac.max_iterations,
                                inlier_threshold=inlier_threshold, edge_similarity=st.ransac.edge_similarity,
                                confidence=st.ransac.confidence, seed=st.ransac.seed, num_threads=num_threads)
        fit, rmse = alignment_fitness(pts, scene, r.T_target_source, inlier_threshold) if r.found else (0.0, 0.0)
        return CoarseAlignment(r.T_target_source, r.found, fit, rmse, "cbd", time.perf_counter() - t0,
                               feature_seconds=f.seconds, details={"match_inliers": len(r.inliers)},
                               message=r.message)
    if method == "flags":
        r = align_flags(pts, nrm, scene[ok_n], scene_normals[ok_n])
        fit, rmse = alignment_fitness(pts, scene, r.T_target_source, inlier_threshold) if r.valid else (0.0, 0.0)
        return CoarseAlignment(r.T_target_source, r.valid, fit, rmse, "flags", time.perf_counter() - t0,
                               message=r.message)
    kw = dict(pcl_settings)
    kw.setdefault("inlier_threshold", inlier_threshold)
    kw.setdefault("num_threads", num_threads)
    return pcl_feature_alignment(pts, scene, method, **kw)


@dataclass
class ObjectPoses:
    """Result of :func:`find_objects`.

    Attributes:
        poses: one :class:`PoseResult` per object cluster (largest cluster first).
        objects: the clusters as int64 index arrays into the scene.
        plane: the table plane (:class:`scanalign.segmentation.PlaneResult`).
        seconds: wall time.
    """

    poses: List[PoseResult]
    objects: List[np.ndarray]
    plane: Any
    seconds: float


def find_objects(model: object, scene: np.ndarray, *, method: Method = "cbd", max_objects: int = 5,
                 table_threshold: float = 0.005, cluster_tolerance: float = 0.01, min_cluster_size: int = 200,
                 viewpoint: Sequence[float] = (0.0, 0.0, 0.0), up: Optional[Sequence[float]] = None,
                 progress: bool = False, **pose_kwargs: Any) -> ObjectPoses:
    """Poses of a part in a table scene (paper 3 / paper 5 pipeline): RANSAC table plane in
    CGA, remove it and everything below it, Euclidean clusters, then :func:`estimate_pose`
    per cluster (at most ``max_objects``, largest first).

    Args:
        model: as :func:`estimate_pose`.
        scene: (N, 3) scan in the camera frame, metres.
        table_threshold, cluster_tolerance: metres; min_cluster_size: points.
        viewpoint / up: orient the table normal (camera centre, or an "up" vector).
        **pose_kwargs: passed to :func:`estimate_pose`.
    """
    from . import cad, io
    from .segmentation import segment_table

    t0 = time.perf_counter()
    pts = as_points(scene, "scene", np.dtype(np.float64))
    if int(max_objects) < 1:
        raise ValueError("max_objects must be >= 1")
    plane, objects = segment_table(pts, threshold=table_threshold, cluster_tolerance=cluster_tolerance,
                                   min_cluster_size=min_cluster_size, viewpoint=viewpoint, up=up)
    objects = objects[: int(max_objects)]
    if isinstance(model, (str, Path)):
        model = io.read_mesh(model)
    if objects and not isinstance(model, (np.ndarray, list)):
        # Render the model views once for all objects.
        model = cad.render_views(model, resolution=int(pose_kwargs.get("resolution", 150)))
    poses = []
    for k, idx in enumerate(objects):
        if progress:
            sys.stderr.write(f"object {k + 1}/{len(objects)} ({len(idx)} points)\n")
        poses.append(estimate_pose(model, pts[idx], method=method, progress=progress, **pose_kwargs))
    return ObjectPoses(poses, objects, plane, time.perf_counter() - t0)


def write_pose_outputs(model: object, scene: np.ndarray, result: PoseResult, prefix: Union[str, Path], *,
                       object_indices: Optional[np.ndarray] = None, samples: int = 20000) -> Dict[str, Path]:
    """Files to inspect a pose: ``<prefix>_model.ply`` (the model surface, sampled, placed in
    the scene frame by ``T_scene_model``; open it together with the scan in a viewer),
    ``<prefix>_scene.ply`` (the scene, the object in orange, the rest grey, the model in
    blue) and ``<prefix>_overlay.png`` (three orthographic projections of object and model).

    Args:
        model: a mesh (or (vertices, faces), or an (N, 3) model cloud), metres.
        scene: (M, 3) scene points, metres.
        result: the :class:`PoseResult` to draw.
        object_indices: the object's points in ``scene`` (default all).
    """
    from . import io as _io
    from .datasets import sample_mesh

    prefix = Path(prefix)
    prefix.parent.mkdir(parents=True, exist_ok=True)
    scene = as_points(scene, "scene", np.dtype(np.float64))
    if isinstance(model, (str, Path)):
        model = _io.read_mesh(model)
    if isinstance(model, np.ndarray):
        mp = as_points(model, "model", np.dtype(np.float64))
    else:
        mp, _ = sample_mesh(model, samples, seed=0)
    T = np.asarray(result.T_scene_model, dtype=np.float64)
    placed = mp @ T[:3, :3].T + T[:3, 3]
    paths = {"model_ply": prefix.with_name(prefix.name + "_model.ply"),
             "scene_ply": prefix.with_name(prefix.name + "_scene.ply"),
             "overlay_png": prefix.with_name(prefix.name + "_overlay.png")}
    _io.write_ply(paths["model_ply"], placed.astype(np.float32))
    idx = np.arange(len(scene)) if object_indices is None else np.asarray(object_indices, dtype=np.int64)
    colours = np.full((len(scene), 3), 160, np.uint8)
    colours[idx] = (240, 140, 40)
    _io.write_ply(paths["scene_ply"], np.vstack([scene, placed]).astype(np.float32),
                  colors=np.vstack([colours, np.tile(np.array([[40, 90, 230]], np.uint8), (len(placed), 1))]))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    obj = scene[idx]
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.4))
    for ax, (i, j, name) in zip(axes, ((0, 1, "x-y"), (0, 2, "x-z"), (1, 2, "y-z"))):
        ax.scatter(1000 * obj[::3, i], 1000 * obj[::3, j], s=0.3, c="tab:orange", label="object (scan)")
        ax.scatter(1000 * placed[::3, i], 1000 * placed[::3, j], s=0.3, c="tab:blue", alpha=0.4,
                   label="model at T_scene_model")
        ax.set_title(f"{name} (mm)")
        ax.set_aspect("equal")
    axes[0].legend(loc="upper right", markerscale=12, fontsize=8)
    fig.suptitle(f"{result.method}: fitness {result.fitness:.3f}, coverage {result.coverage:.3f}, "
                 f"inlier RMSE {1000 * result.inlier_rmse:.3f} mm, {result.seconds:.2f} s")
    fig.tight_layout()
    fig.savefig(paths["overlay_png"], dpi=110)
    plt.close(fig)
    return paths

"""Pose of a known part from its CAD model (Kleppe, PhD thesis, NTNU 2018, ch. 6-7; papers 4-5).

Everything runs in C++ (``cpp/include/scanalign/pose``); this module converts arrays and
keyword arguments. Building blocks:

* :func:`estimate_motor` -- Valkenburg-Dorst motor estimation from point pairs, equal to
  :func:`estimate_rigid_svd` (Kabsch) to numerical precision.
* :func:`ransac_rigid_motion` -- RANSAC over putative pairs with a motor refit.
* :func:`align_cbd` -- curvature-based descriptor matching + RANSAC (paper 5).
* :func:`align_flags` -- paper 4's correspondence-free initial alignment with motors
  (centroid + average normal line; partial views only, closed surfaces are refused).
* :func:`pcl_feature_alignment` -- the stock PCL baselines of the thesis (FPFH, SHOT, 3DSC
  with SampleConsensusPrerejective or SAC-IA, and PPF) with its preset.

Pipeline: :func:`estimate_pose` matches a model (a mesh rendered from the 42 vertices of a
tessellated sphere, see :mod:`scanalign.pose.model_views`, or a cloud) against one object cloud, refines
with scanalign's ICP and keeps the best view; :func:`find_objects` first segments the table
and clusters the objects (paper 3); :func:`find_parts` does that for several known parts and
names the part in each cluster (``found`` / ``not_found`` / ``ambiguous``).

Frames and units: metres and radians. Every transform is ``T_target_source``
(``p_target = T @ p_source``); for the pipeline that is ``T_scene_model``: it maps model
(CAD) coordinates into the scene (camera) frame.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from typing import Any, Dict, List, Literal, Optional, Sequence, Tuple, Union

import numpy as np

from scanalign import _core
from scanalign.pose import cbd as _cbd
from scanalign.common.arrays import as_points, as_transform, foreign_kind
from scanalign.common.settings import fields_of, set_fields
from scanalign import io
from scanalign.pose import model_views as cad
from scanalign.features import estimate_normals

__all__ = [
    "MotorEstimationResult", "CorrespondenceRansacResult", "CbdAlignmentResult", "NormalLineFlag", "FlagAlignmentResult",
    "PclFeatureAlignmentResult", "PoseSettings", "PoseResult", "PoseCandidate", "FindObjectsResult", "DetectionStatus",
    "PartDetection", "FindPartsResult", "find_parts", "find_parts_settings",
    "estimate_motor", "estimate_rigid_svd", "motor_to_matrix", "ransac_rigid_motion", "align_cbd",
    "normal_line_flag", "align_flags", "pcl_feature_alignment", "alignment_fitness", "estimate_pose",
    "find_objects", "METHODS", "THESIS_PCL_PRESET",
]

_P = _core.pose
MotorEstimationResult = _P.MotorEstimationResult
CorrespondenceRansacResult = _P.CorrespondenceRansacResult
CbdAlignmentResult = _P.CbdAlignmentResult
NormalLineFlag = _P.NormalLineFlag
FlagAlignmentResult = _P.FlagAlignmentResult
PclFeatureAlignmentResult = _P.PclFeatureAlignmentResult
PoseSettings = _P.PoseSettings
PoseResult = _P.PoseResult
PoseCandidate = _P.PoseCandidate
FindObjectsResult = _P.FindObjectsResult
DetectionStatus = _P.DetectionStatus
PartDetection = _P.PartDetection
FindPartsResult = _P.FindPartsResult

Method = Literal["cbd", "fpfh", "fpfh_sac_ia", "shot", "3dsc", "ppf", "flags"]
METHODS: Tuple[str, ...] = ("cbd", "fpfh", "fpfh_sac_ia", "shot", "3dsc", "ppf", "flags")
# PCL baseline name -> (descriptor, matcher)
_PCL_METHODS = {"fpfh": ("fpfh", "prerejective"), "fpfh_sac_ia": ("fpfh", "sac_ia"), "shot": ("shot", "prerejective"),
                "3dsc": ("shape_context_3d", "prerejective"), "ppf": ("ppf", "prerejective")}


def _pcl_preset(method: str) -> Any:
    descriptor, matcher = _PCL_METHODS[method]
    return _P.thesis_pcl_preset(getattr(_P.PclDescriptor, descriptor), getattr(_P.PclMatcher, matcher))


#: The thesis's baseline settings per PCL method (read-only copies of the C++ presets).
THESIS_PCL_PRESET: Dict[str, Any] = {m: _pcl_preset(m) for m in _PCL_METHODS}


# --- motors and RANSAC -------------------------------------------------------------------------

def _pairs(source: object, target: object) -> Tuple[np.ndarray, np.ndarray]:
    return as_points(source, "source", np.dtype(np.float64)), as_points(target, "target", np.dtype(np.float64))


def estimate_motor(source: np.ndarray, target: np.ndarray, weights: Optional[np.ndarray] = None, *,
                   normalize: bool = True) -> MotorEstimationResult:
    """Valkenburg-Dorst motor from pairs ``source[i] <-> target[i]`` ((N, 3) each, metres;
    paper 5, (36)-(44)): the unit motor maximising ``Σ w_k ⟨M̃ Y_k M X_k⟩``, optionally
    weighted; ``normalize`` centres and scales first (only rounding changes). ``valid`` is
    False (identity) for fewer than 3 pairs or collinear data; ValueError for unpaired or
    non-finite pairs and bad weights."""
    s, t = _pairs(source, target)
    return _P.estimate_motor(s, t, weights, bool(normalize))


def estimate_rigid_svd(source: np.ndarray, target: np.ndarray, weights: Optional[np.ndarray] = None) -> MotorEstimationResult:
    """Kabsch/Umeyama (SVD) estimate from the same pairs: the oracle of :func:`estimate_motor`."""
    s, t = _pairs(source, target)
    return _P.estimate_rigid_svd(s, t, weights)


def motor_to_matrix(motor: Sequence[float]) -> np.ndarray:
    """(4, 4) transform of an 8-coefficient motor (normalised first)."""
    return _P.motor_to_matrix(np.asarray(motor, dtype=np.float64))


def _ransac_settings(base: Any = None, **fields: Any) -> Any:
    s = _P.CorrespondenceRansacSettings()
    if base is not None:
        set_fields(s, fields_of(base), "RANSAC")
    if "seed" in fields:
        fields["seed"] = int(fields["seed"]) & (2**64 - 1)
    return set_fields(s, fields, "RANSAC")


def ransac_rigid_motion(source: np.ndarray, target: np.ndarray, pairs: np.ndarray, *, max_iterations: int = 1000,
                        inlier_threshold: float = 0.005, edge_similarity: float = 0.9, confidence: float = 0.999,
                        seed: int = 0, num_threads: int = 0) -> CorrespondenceRansacResult:
    """Rigid motion from putative pairs ``(K, 2)`` (indices into source and target, metres)
    with outliers: RANSAC over 3-pair samples prerejected unless their edge lengths agree
    within ``edge_similarity``, Kabsch hypotheses ranked by MSAC cost, adaptive stop at
    ``confidence``, a motor refit on the inliers (``inlier_threshold`` m). Deterministic for a
    ``seed`` whatever the thread count."""
    s, t = _pairs(source, target)
    p = np.asarray(pairs)
    if p.size and not np.issubdtype(p.dtype, np.integer):
        raise ValueError(f"pairs: expected an integer (K, 2) array, got {p.dtype}")
    settings = _ransac_settings(max_iterations=max_iterations, inlier_threshold=inlier_threshold,
                                edge_similarity=edge_similarity, confidence=confidence, seed=seed,
                                num_threads=num_threads)
    return _P.ransac_rigid_motion(s, t, p.astype(np.int64).reshape(-1, 2), settings)


def alignment_fitness(source: np.ndarray, target: np.ndarray, T_target_source: np.ndarray,
                      threshold: float = 0.005, *, num_threads: int = 0) -> Tuple[float, float]:
    """``(fitness, inlier_rmse)``: the fraction of finite source points whose nearest target
    point lies within ``threshold`` metres after ``T_target_source``, and their RMS distance (m)."""
    s, t = _pairs(source, target)
    return _core.registration.alignment_fitness(s, t, as_transform(T_target_source, "T_target_source"), threshold,
                                num_threads)


# --- coarse alignment ---------------------------------------------------------------------------

def _cbd_alignment_settings(cbd_settings: Optional[_cbd.CbdSettings], cbd_overrides: Dict[str, object],
                            ransac: Optional[Dict[str, Any]], base: Optional[Any] = None) -> Any:
    s = base if base is not None else _P.CbdAlignmentSettings()
    s.cbd = _cbd.make_settings(cbd_settings if cbd_settings is not None else s.cbd, **cbd_overrides)
    s.ransac = _ransac_settings(s.ransac, **(ransac or {}))
    return s


def align_cbd(source: np.ndarray, target: np.ndarray, settings: Optional[_cbd.CbdSettings] = None, *,
              ransac: Optional[Dict[str, Any]] = None, matches_per_keypoint: int = 1, hypotheses: int = 3,
              **cbd_overrides: object) -> CbdAlignmentResult:
    """Coarse alignment of ``source`` (e.g. a model view) onto ``target`` (e.g. a scene object),
    (N, 3) metres, with the curvature-based descriptor (paper 5): CBD on both clouds
    (:class:`scanalign.pose.cbd.CbdSettings` or field overrides; thesis defaults), nearest-descriptor
    matches (``matches_per_keypoint``), RANSAC (``ransac``: :func:`ransac_rigid_motion`
    keywords; 10000 iterations) and a motor refit, repeated on the pairs left for up to
    ``hypotheses`` poses, the best fit of the whole source cloud winning (1: classic RANSAC).
    ``found`` is False with a message when there are too few keypoints or no consensus."""
    s = as_points(source, "source")
    t = as_points(target, "target", s.dtype)
    if len(s) == 0 or len(t) == 0:
        raise ValueError("align_cbd: source and target must not be empty")
    st = _cbd_alignment_settings(settings, cbd_overrides, ransac)
    st.matches_per_keypoint = matches_per_keypoint
    st.hypotheses = hypotheses
    return _P.align_cbd(s, t, st)


def normal_line_flag(points: np.ndarray, normals: np.ndarray) -> NormalLineFlag:
    """The flag of a cloud (paper 4): centroid, average normal line (direction and foot, m),
    ``mean_normal_length`` (|mean unit normal|, ~0 for a closed surface), pitch (m), count."""
    return _P.normal_line_flag(as_points(points, "points", np.dtype(np.float64)),
                               as_points(normals, "normals", np.dtype(np.float64)))


def align_flags(source: np.ndarray, source_normals: np.ndarray, target: np.ndarray, target_normals: np.ndarray, *,
                min_mean_normal_length: float = 0.05, max_iterations: int = 100) -> FlagAlignmentResult:
    """Paper 4 initial alignment: the motor mapping the source flag (centroid + average normal
    line) onto the target's, by Levenberg-Marquardt on the motor manifold. Partial views only:
    refused (``valid`` False) when a mean unit normal is shorter than
    ``min_mean_normal_length`` (a closed surface's normals average to zero)."""
    clouds = [as_points(a, name, np.dtype(np.float64)) for a, name in
              ((source, "source"), (source_normals, "source_normals"), (target, "target"),
               (target_normals, "target_normals"))]
    s = set_fields(_P.FlagAlignmentSettings(), dict(min_mean_normal_length=min_mean_normal_length,
                                                    max_iterations=max_iterations), "flag alignment")
    return _P.align_flags(*clouds, s)


def _pcl_settings(method: str, overrides: Dict[str, object]) -> Any:
    if method not in _PCL_METHODS:
        raise ValueError(f"method: expected one of {sorted(_PCL_METHODS)}, got {method!r}")
    return set_fields(_pcl_preset(method), overrides, "PCL")


def pcl_feature_alignment(source: np.ndarray, target: np.ndarray, method: str = "fpfh",
                          **settings: object) -> PclFeatureAlignmentResult:
    """A stock PCL 1.13 coarse registration of ``source`` onto ``target`` ((N, 3) metres, run in
    float32), the thesis's baselines (§7.6): ``"fpfh"`` (FPFHEstimationOMP +
    SampleConsensusPrerejective), ``"fpfh_sac_ia"`` (SAC-IA), ``"shot"``, ``"3dsc"`` or ``"ppf"``
    (PPFRegistration). ``**settings`` override fields of the method's
    :data:`THESIS_PCL_PRESET` (``PclFeatureAlignmentSettings``, each field with its unit)."""
    st = _pcl_settings(method, settings)
    s = as_points(source, "source", np.dtype(np.float32))
    t = as_points(target, "target", np.dtype(np.float32))
    if len(s) == 0 or len(t) == 0:
        raise ValueError("pcl_feature_alignment: source and target must not be empty")
    return _P.pcl_feature_alignment(s, t, st)


# --- pipeline -----------------------------------------------------------------------------------

def _model_views(model: object, views: Any) -> Tuple[List[Any], bool]:
    """The model as views: rendered from a mesh (or mesh file) with ``views`` (the
    ``ModelViewSettings`` of the pose settings), given views, or one cloud."""
    if isinstance(model, list) and model and all(isinstance(v, cad.ModelView) for v in model):
        return model, False
    if isinstance(model, (str, Path)):
        model = io.read_mesh(model)
    if isinstance(model, np.ndarray) or foreign_kind(model) == "cloud":  # or an Open3D / trimesh cloud
        p = as_points(model, "model", np.dtype(np.float64))
        if len(p) == 0:
            raise ValueError("model: empty cloud")
        n = estimate_normals(p, radius=0.005, viewpoint=p.mean(axis=0) + np.array([0, 0, 1.0]))
        return [cad.ModelView(p, n)], True
    return _P.render_model_views(*cad._mesh_arrays(model), views), False


class _Progress:
    """A tqdm bar per object, fed by the C++ progress callback (done, total)."""

    def __init__(self, desc: str, enabled: bool):
        self.desc, self.enabled, self.bar = desc, enabled, None

    def __call__(self, done: int, total: int) -> None:
        from tqdm.auto import tqdm

        if done == 1:
            self.bar = tqdm(total=total, desc=self.desc, unit="view", file=sys.stderr, dynamic_ncols=True,
                            disable=total < 2)
        self.bar.update(1)
        if done == total:
            self.bar.close()


def _pose_settings(method: str, inlier_threshold: float, icp_distance: float, normal_radius: float,
                   cbd_settings: Optional[_cbd.CbdSettings], ransac: Optional[Dict[str, Any]], num_threads: int,
                   cbd_overrides: Dict[str, object], base: Any = None, *, resolution: Optional[int] = None,
                   pcl_overrides: Optional[Dict[str, object]] = None) -> Any:
    """PoseSettings from these values over ``base`` (the defaults of the C++ struct that holds
    them, e.g. ``FindPartsSettings.pose``; a fresh ``PoseSettings`` when None). A PCL method
    (``"fpfh"``...) is ``method="pcl"`` with ``pcl`` its thesis preset and ``pcl_overrides``;
    ``resolution`` (None: the base's) and ``num_threads`` also set how a mesh is rendered
    (``views``)."""
    limits = {k: cbd_overrides.pop(k) for k in ("min_fitness", "min_coverage") if k in cbd_overrides}
    hypotheses = cbd_overrides.pop("hypotheses", None)
    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    cbd_overrides.setdefault("min_neighbors", 0)  # automatic: scan density varies
    s = set_fields(_P.PoseSettings() if base is None else base, dict(method=method if method in ("cbd", "flags") else "pcl",
                                           inlier_threshold=inlier_threshold, icp_distance=icp_distance,
                                           normal_radius=normal_radius, num_threads=num_threads, **limits), "pose")
    if method in _PCL_METHODS:
        s.pcl = _pcl_settings(method, pcl_overrides or {})
    set_fields(s.views, dict(num_threads=num_threads) if resolution is None else
               dict(resolution=int(resolution), num_threads=num_threads), "view")
    s.cbd = _cbd_alignment_settings(cbd_settings, cbd_overrides, ransac, s.cbd)
    if hypotheses is not None:
        c = s.cbd
        c.hypotheses = hypotheses
        s.cbd = c
    return s


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
            :class:`scanalign.pose.model_views.ModelView` that :func:`scanalign.pose.model_views.render_views` returned
            (rendered once, reused across objects), or an (N, 3) cloud.
        scene: (M, 3) the object's points in the scene (camera) frame, metres.
        method: coarse method, one of :data:`METHODS` (``"cbd"`` default).
        views: subset of view indices to try (default all 42).
        resolution: model view image size, pixels (thesis: 90 to 400).
        inlier_threshold: metres, for fitness and coverage (thesis: 5 mm).
        icp_distance: ICP max correspondence distance, metres.
        normal_radius: scene normal radius for point-to-plane ICP and flags, metres.
        cbd_settings / **cbd_overrides: CBD settings (``min_neighbors`` defaults to 0 here:
            automatic, since scan density varies); also ``min_fitness`` / ``min_coverage`` (0.5)
            and ``hypotheses`` (3: RANSAC poses per view, see :func:`align_cbd`).
        ransac: RANSAC keywords for CBD; ``pcl_settings``: PCL baseline overrides.
        progress: print a progress bar over the views on stderr.

    Returns:
        :class:`PoseResult`: ``found`` False with a message when no view aligned or the best
        one's fitness or coverage is below ``min_fitness`` / ``min_coverage``.
    """
    settings = _pose_settings(method, inlier_threshold, icp_distance, normal_radius, cbd_settings, ransac, num_threads,
                              cbd_overrides, resolution=resolution, pcl_overrides=pcl_settings)
    model_views, is_cloud = _model_views(model, settings.views)
    scene = as_points(scene, "scene", np.dtype(np.float64))
    r = _P.estimate_pose(model_views, scene, settings, [int(i) for i in views or []],
                         _Progress(f"pose ({method})", True) if progress else None)
    if is_cloud:
        r.view = None
    return r


def _table_settings(s: Any, method: str, max_objects: int, table_threshold: float, cluster_tolerance: float,
                    min_cluster_size: int, viewpoint: Sequence[float], up: Optional[Sequence[float]], num_threads: int,
                    resolution: int, pose_kwargs: Dict[str, Any]) -> None:
    """Fills find_objects / find_parts settings ``s``."""
    s.max_objects = int(max_objects)
    pcl_overrides = pose_kwargs.pop("pcl_settings", None)
    s.pose = _pose_settings(method, pose_kwargs.pop("inlier_threshold", 0.005), pose_kwargs.pop("icp_distance", 0.01),
                            pose_kwargs.pop("normal_radius", 0.005), pose_kwargs.pop("cbd_settings", None),
                            pose_kwargs.pop("ransac", None), num_threads, pose_kwargs, s.pose, resolution=resolution,
                            pcl_overrides=pcl_overrides)
    t = s.table
    t.plane.threshold, t.cluster_tolerance, t.min_cluster_size = table_threshold, cluster_tolerance, min_cluster_size
    t.plane.num_threads = num_threads
    t.viewpoint = np.asarray(viewpoint, dtype=np.float64)
    t.up = np.zeros(3) if up is None else np.asarray(up, dtype=np.float64)
    s.table = t


def find_objects(model: object, scene: np.ndarray, *, method: Method = "cbd", max_objects: int = 5,
                 table_threshold: float = 0.005, cluster_tolerance: float = 0.01, min_cluster_size: int = 200,
                 viewpoint: Sequence[float] = (0.0, 0.0, 0.0), up: Optional[Sequence[float]] = None,
                 progress: bool = False, resolution: int = 150, views: Optional[Sequence[int]] = None,
                 num_threads: int = 0, **pose_kwargs: Any) -> FindObjectsResult:
    """Poses of a part in a table scene (paper 3 / paper 5 pipeline): RANSAC table plane in
    CGA, remove it and everything below it, Euclidean clusters, then the pose per cluster as
    :func:`estimate_pose` (at most ``max_objects``, largest first).

    Args:
        model: as :func:`estimate_pose` (a mesh is rendered once for all objects).
        scene: (N, 3) scan in the camera frame, metres.
        table_threshold, cluster_tolerance: metres; min_cluster_size: points.
        viewpoint / up: orient the table normal (camera centre, or an "up" vector).
        **pose_kwargs: the other keywords of :func:`estimate_pose`.

    Returns:
        :class:`FindObjectsResult` (``poses``, ``objects`` as index arrays, the table ``plane``).
    """
    s = _P.FindObjectsSettings()
    _table_settings(s, method, max_objects, table_threshold, cluster_tolerance, min_cluster_size, viewpoint, up,
                    num_threads, resolution, pose_kwargs)
    pts = as_points(scene, "scene", np.dtype(np.float64))
    model_views, is_cloud = _model_views(model, s.pose.views)
    found = _P.find_objects(model_views, pts, s, [int(i) for i in views or []],
                            _Progress(f"pose ({method})", True) if progress else None)
    if is_cloud:  # a model cloud has no views to name
        poses = found.poses
        for r in poses:
            r.view = None
        found.poses = poses
    return found


def find_parts(models: Sequence[object], scene: np.ndarray, *, symmetries: Optional[Sequence[Any]] = None,
               method: Method = "cbd", max_objects: int = 5, table_threshold: float = 0.005,
               cluster_tolerance: float = 0.01, min_cluster_size: int = 200,
               viewpoint: Sequence[float] = (0.0, 0.0, 0.0), up: Optional[Sequence[float]] = None,
               progress: bool = False, resolution: int = 100, views: Optional[Sequence[int]] = None,
               num_threads: int = 0, ambiguity_margin: float = 0.02, ambiguity_rmse_ratio: float = 1.5,
               same_pose_angle: float = math.radians(5),
               same_pose_distance: float = 0.005, max_size_ratio: float = 1.5, min_size_ratio: float = 0.5,
               voxel_size: float = 0.0, score_tie: float = 0.01, polish_distance: float = 0.003,
               max_table_penetration: float = 0.005, surface_polish: bool = True, cbd_radius_fraction: float = 0.0,
               min_surface_coverage: float = 0.97,
               **pose_kwargs: Any) -> FindPartsResult:
    """Which of several known parts lies in each object cluster of a table scene, and its
    pose: the table and clusters as :func:`find_objects` (segmented once), then every part's
    views aligned to each cluster (its normals and descriptors computed once), the best part
    by score, and a :class:`DetectionStatus`: ``found``, ``not_found`` (no part passes
    ``min_fitness`` / ``min_coverage``) or ``ambiguous`` (a runner-up -- another part, or a
    pose of the same part that its symmetry does not make equivalent -- scores at least
    ``(1 - ambiguity_margin)`` x the best with an inlier RMSE at most ``ambiguity_rmse_ratio``
    x the best's).

    Args:
        models: one model per part, each as :func:`estimate_pose` takes it (a mesh, its
            rendered views, or a cloud); render meshes once with :func:`scanalign.pose.model_views.render_views`
            when calling repeatedly.
        scene: (N, 3) scan, metres (camera or base frame; ``T_scene_model`` is in that frame).
        symmetries: one ``PartSymmetry`` (``axis``, ``point`` m, ``order``; e.g. from
            :data:`scanalign.data.parts.BUILTIN_PARTS`) or None per part; default none symmetric.
        ambiguity_margin / ambiguity_rmse_ratio: a runner-up makes the detection ambiguous if it
            scores at least ``(1 - ambiguity_margin)`` x the best and its inlier RMSE is at most
            ``ambiguity_rmse_ratio`` x the best's (0: no RMSE test).
        same_pose_angle / same_pose_distance: rad / m; two poses of one part closer than both
            (over its symmetry) are the same pose, never a runner-up.
        max_size_ratio / min_size_ratio: skip a part, before any alignment, for a cluster
            larger than ``max_size_ratio`` x the part's size or smaller than ``min_size_ratio`` x
            its smallest view (sizes: largest extent along the principal axes; 0 = no bound).
        score_tie: candidates of the best part within this of its best score are ties, the
            smallest inlier RMSE wins (scores saturate when the noise is far below
            ``inlier_threshold``).
        polish_distance: m; the reported pose is refined again by ICP with this
            correspondence distance and a tight stop (0: no polish).
        voxel_size: m; each cluster is reduced to one point per voxel before its pose (0: all).
        max_table_penetration: m; poses that put the part's surface further below the table
            plane are dropped (a resting part cannot be in the table; ``math.inf``: no check).
        surface_polish: refine the reported pose against the part's whole surface (every
            view merged): each cluster point onto the model, within ``polish_distance``.
        cbd_radius_fraction: CBD radius per part, ``max(radius, fraction x part size)`` (the
            part's views together; 0: the fixed ``radius``; 0.15 suits merged scans of parts
            of 3 to 10 cm). Tied to the part, its view descriptors are computed once
            (:mod:`scanalign.grasp.part_library`).
        min_surface_coverage: fraction of a cluster's points within ``polish_distance`` of
            the part's whole surface a detection needs (0.97; 0: no check): rejects another
            part or a part of another size whose view alone still scores well.
        resolution: model view size, pixels (100 here: as accurate as 150 on the built-in
            parts, 2 to 3 times faster; see docs/api/pose.md).
        other keywords: as :func:`find_objects` (``views`` applies to every part).

    Returns:
        :class:`FindPartsResult`: per cluster a :class:`PartDetection` (``status``, ``part``,
        ``pose``, runner-up, ``indices``, ``parts``: the :class:`PoseResult` of every part).
    """
    if isinstance(models, (str, bytes)) or not isinstance(models, Sequence) or len(models) == 0:
        raise ValueError("models: expected a non-empty list with one model per part")
    s = find_parts_settings(
        method=method, max_objects=max_objects, table_threshold=table_threshold, cluster_tolerance=cluster_tolerance,
        min_cluster_size=min_cluster_size, viewpoint=viewpoint, up=up, num_threads=num_threads,
        ambiguity_margin=ambiguity_margin, ambiguity_rmse_ratio=ambiguity_rmse_ratio, same_pose_angle=same_pose_angle,
        same_pose_distance=same_pose_distance,
        max_size_ratio=max_size_ratio, min_size_ratio=min_size_ratio, voxel_size=voxel_size, score_tie=score_tie,
        polish_distance=polish_distance, max_table_penetration=max_table_penetration, surface_polish=surface_polish,
        cbd_radius_fraction=cbd_radius_fraction, min_surface_coverage=min_surface_coverage, resolution=resolution,
        **pose_kwargs)
    pts = as_points(scene, "scene", np.dtype(np.float64))
    model_views = [_model_views(m, s.pose.views)[0] for m in models]
    return _P.find_parts(model_views, pts, s, None if symmetries is None else list(symmetries),
                         [int(i) for i in views or []], _Progress(f"parts ({method})", True) if progress else None)


def find_parts_settings(*, method: Method = "cbd", max_objects: int = 5, table_threshold: float = 0.005,
                        cluster_tolerance: float = 0.01, min_cluster_size: int = 200,
                        viewpoint: Sequence[float] = (0.0, 0.0, 0.0), up: Optional[Sequence[float]] = None,
                        num_threads: int = 0, resolution: Optional[int] = None, **keywords: Any) -> Any:
    """The ``FindPartsSettings`` that :func:`find_parts` builds from these keywords (its own,
    same defaults; a PCL method's settings in ``pose.pcl``, ``resolution`` None: the struct's
    ``pose.views.resolution``): e.g. to describe part views once with
    ``_core.pose.part_pose_settings`` (see :mod:`scanalign.grasp.part_library`)."""
    names = ("ambiguity_margin", "ambiguity_rmse_ratio", "same_pose_angle", "same_pose_distance", "max_size_ratio", "min_size_ratio",
             "voxel_size", "score_tie", "polish_distance", "max_table_penetration", "surface_polish",
             "cbd_radius_fraction", "min_surface_coverage")
    fields = {k: keywords.pop(k) for k in names if k in keywords}
    s = _P.FindPartsSettings()
    _table_settings(s, method, max_objects, table_threshold, cluster_tolerance, min_cluster_size, viewpoint, up,
                    num_threads, resolution, keywords)
    set_fields(s, fields, "find_parts")
    return s

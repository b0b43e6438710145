"""Pose of a known part from its CAD model (Kleppe, PhD thesis, NTNU 2018, ch. 6-7; papers 4-5).

Everything runs in C++ (``cpp/include/scanalign/pose``); this module converts arrays and keyword arguments. Building
blocks: Valkenburg-Dorst motors from point pairs (:func:`estimate_motor`), RANSAC over putative pairs
(:func:`ransac_rigid_motion`) and the coarse alignments :func:`align_cbd` (curvature-based descriptors, paper 5),
:func:`align_flags` (paper 4's normal-line flags) and :func:`pcl_feature_alignment` (the thesis's PCL baselines).

Pipeline: :func:`estimate_pose` matches a model (a mesh rendered from the 42 vertices of a tessellated sphere, see
:mod:`scanalign.pose.model_views`, or a cloud) against one object cloud, refines with scanalign's ICP and keeps the best
view; :func:`find_objects` first segments the table and clusters the objects (paper 3); :func:`find_parts` does that for
several known parts and names the part in each cluster (``found`` / ``not_found`` / ``ambiguous``).

Frames and units: metres and radians. Every transform is ``T_target_source`` (``p_target = T @ p_source``); for the
pipeline that is ``T_scene_model``: it maps model (CAD) coordinates into the scene (camera) frame.
"""

from __future__ import annotations

import sys
from typing import Any, Callable, Dict, List, Literal, Optional, Sequence, Tuple

import numpy as np

from scanalign import _core
from scanalign.common.arrays import as_points, as_transform
from scanalign.common.settings import (UnknownSettingError, field_names, is_struct, set_fields, set_path, update,
                                      with_overrides)
from scanalign.pose import cbd as _cbd
from scanalign.pose import model_views as cad

#: The bound C++ result and settings types, as they are (each field documented there).
_BOUND = ("MotorEstimationResult", "CorrespondenceRansacResult", "CbdAlignmentResult", "NormalLineFlag",
          "FlagAlignmentResult", "PclFeatureAlignmentResult", "PoseSettings", "PoseResult", "PoseCandidate",
          "FindObjectsResult", "DetectionStatus", "PartDetection", "FindPartsResult", "FindPartsSettings")
__all__ = [*_BOUND, "find_parts", "pose_task_settings", "POSE_KEYWORDS", "TABLE_KEYWORDS", "estimate_motor",
           "estimate_rigid_svd", "motor_to_matrix", "ransac_rigid_motion", "align_cbd", "normal_line_flag",
           "align_flags", "pcl_feature_alignment", "alignment_fitness", "estimate_pose", "find_objects", "METHODS",
           "THESIS_PCL_PRESET"]

_P = _core.pose
globals().update({name: getattr(_P, name) for name in _BOUND})

Method = Literal["cbd", "fpfh", "fpfh_sac_ia", "shot", "3dsc", "ppf", "pfh", "rsd", "gasd", "vfh", "flags"]
METHODS: Tuple[str, ...] = ("cbd", "fpfh", "fpfh_sac_ia", "shot", "3dsc", "ppf", "pfh", "rsd", "gasd", "vfh", "flags")
# PCL baseline name -> (descriptor, matcher)
_PCL_METHODS = {"fpfh": ("fpfh", "prerejective"), "fpfh_sac_ia": ("fpfh", "sac_ia"), "shot": ("shot", "prerejective"),
                "3dsc": ("shape_context_3d", "prerejective"), "ppf": ("ppf", "prerejective"),
                **{m: (m, "prerejective") for m in ("pfh", "rsd", "gasd", "vfh")}}


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
    """Valkenburg-Dorst motor from pairs ``source[i] <-> target[i]`` ((N, 3) each, metres; paper 5, (36)-(44)): the unit
    motor maximising ``Σ w_k ⟨M̃ Y_k M X_k⟩``, optionally weighted; ``normalize`` centres and scales first (only
    rounding changes). ``valid`` is False (identity) for fewer than 3 pairs or collinear data; ValueError for unpaired
    or non-finite pairs and bad weights."""
    s, t = _pairs(source, target)
    return _P.estimate_motor(s, t, weights, bool(normalize))


def estimate_rigid_svd(source: np.ndarray, target: np.ndarray,
                       weights: Optional[np.ndarray] = None) -> MotorEstimationResult:
    """Kabsch/Umeyama (SVD) estimate from the same pairs: the oracle of :func:`estimate_motor`."""
    s, t = _pairs(source, target)
    return _P.estimate_rigid_svd(s, t, weights)


def motor_to_matrix(motor: Sequence[float]) -> np.ndarray:
    """(4, 4) transform of an 8-coefficient motor (normalised first)."""
    return _P.motor_to_matrix(np.asarray(motor, dtype=np.float64))


def _ransac_settings(base: Any = None, overrides: Optional[Dict[str, Any]] = None) -> Any:
    fields = dict(overrides or {})
    if "seed" in fields:  # any Python int seeds the 64-bit stream
        fields["seed"] = int(fields["seed"]) & (2**64 - 1)
    return with_overrides(_P.CorrespondenceRansacSettings, base, fields, "RANSAC")


def ransac_rigid_motion(source: np.ndarray, target: np.ndarray, pairs: np.ndarray,
                        settings: Optional[Any] = None, **overrides: Any) -> CorrespondenceRansacResult:
    """Rigid motion from putative pairs ``(K, 2)`` (indices into source and target, metres) with outliers: RANSAC over
    3-pair samples prerejected unless their edge lengths agree within ``edge_similarity``, Kabsch hypotheses ranked by
    MSAC cost, adaptive stop at ``confidence``, a motor refit on the inliers (``inlier_threshold`` m). ``settings``: a
    ``CorrespondenceRansacSettings`` (default its C++ defaults) with keyword ``overrides``. Deterministic for a ``seed``
    whatever the thread count."""
    s, t = _pairs(source, target)
    p = np.asarray(pairs)
    if p.size and not np.issubdtype(p.dtype, np.integer):
        raise ValueError(f"pairs: expected an integer (K, 2) array, got {p.dtype}")
    return _P.ransac_rigid_motion(s, t, p.astype(np.int64).reshape(-1, 2), _ransac_settings(settings, overrides))


def alignment_fitness(source: np.ndarray, target: np.ndarray, T_target_source: np.ndarray,
                      threshold: float = 0.005, *, num_threads: int = 0) -> Tuple[float, float]:
    """``(fitness, inlier_rmse)``: the fraction of finite source points whose nearest target
    point lies within ``threshold`` metres after ``T_target_source``, and their RMS distance (m)."""
    s, t = _pairs(source, target)
    return _core.registration.alignment_fitness(s, t, as_transform(T_target_source, "T_target_source"), threshold,
                                num_threads)


# --- coarse alignment ---------------------------------------------------------------------------

_ALIGNMENT_FIELDS = frozenset(field_names(_P.CbdAlignmentSettings)) - {"cbd", "ransac"}


def _cbd_alignment_settings(settings: Any, overrides: Dict[str, object], ransac: Optional[Dict[str, Any]]) -> Any:
    s = _P.CbdAlignmentSettings()
    if isinstance(settings, _P.CbdAlignmentSettings):
        s, settings = _P.CbdAlignmentSettings(settings), None
    update(s, {k: v for k, v in overrides.items() if k in _ALIGNMENT_FIELDS}, what="CBD alignment")
    cbd_overrides = {k: v for k, v in overrides.items() if k not in _ALIGNMENT_FIELDS}
    s.cbd = _cbd.make_settings(settings if settings is not None else s.cbd, **cbd_overrides)
    s.ransac = _ransac_settings(s.ransac, ransac)
    return s


def align_cbd(source: np.ndarray, target: np.ndarray, settings: Optional[Any] = None, *,
              ransac: Optional[Dict[str, Any]] = None, **overrides: object) -> CbdAlignmentResult:
    """Coarse alignment of ``source`` (e.g. a model view) onto ``target`` (e.g. a scene object), (N, 3) metres, with the
    curvature-based descriptor (paper 5): CBD on both clouds, nearest-descriptor matches (``matches_per_keypoint``),
    RANSAC (``ransac``: a dict of :func:`ransac_rigid_motion` keywords) and a motor refit, repeated on the pairs left
    for up to ``hypotheses`` poses, the best fit of the whole source cloud winning (1: classic RANSAC). ``settings``: a
    ``CbdAlignmentSettings`` or a :class:`scanalign.pose.cbd.CbdSettings` (default: the C++ defaults, the thesis's);
    keyword ``overrides`` name fields of either. ``found`` is False with a message when there are too few keypoints or
    no consensus."""
    s = as_points(source, "source")
    t = as_points(target, "target", s.dtype)
    if len(s) == 0 or len(t) == 0:
        raise ValueError("align_cbd: source and target must not be empty")
    return _P.align_cbd(s, t, _cbd_alignment_settings(settings, overrides, ransac))


def normal_line_flag(points: np.ndarray, normals: np.ndarray) -> NormalLineFlag:
    """The flag of a cloud (paper 4): centroid, average normal line (direction and foot, m),
    ``mean_normal_length`` (|mean unit normal|, ~0 for a closed surface), pitch (m), count."""
    return _P.normal_line_flag(as_points(points, "points", np.dtype(np.float64)),
                               as_points(normals, "normals", np.dtype(np.float64)))


def align_flags(source: np.ndarray, source_normals: np.ndarray, target: np.ndarray, target_normals: np.ndarray,
                settings: Optional[Any] = None, **overrides: Any) -> FlagAlignmentResult:
    """Paper 4 initial alignment: the motor mapping the source flag (centroid + average normal line) onto the target's,
    by Levenberg-Marquardt on the motor manifold. ``settings``: a ``FlagAlignmentSettings`` (default its C++ defaults)
    with keyword ``overrides``. Partial views only: refused (``valid`` False) when a mean unit normal is shorter than
    ``min_mean_normal_length`` (a closed surface's normals average to zero)."""
    clouds = [as_points(a, name, np.dtype(np.float64)) for a, name in
              ((source, "source"), (source_normals, "source_normals"), (target, "target"),
               (target_normals, "target_normals"))]
    return _P.align_flags(*clouds, with_overrides(_P.FlagAlignmentSettings, settings, overrides, "flag alignment"))


def pcl_feature_alignment(source: np.ndarray, target: np.ndarray, method: str = "fpfh",
                          **settings: object) -> PclFeatureAlignmentResult:
    """A stock PCL 1.13 coarse registration of ``source`` onto ``target`` ((N, 3) metres, run in float32), the thesis's
    baselines (§7.6): ``"fpfh"`` (FPFHEstimationOMP + SampleConsensusPrerejective), ``"fpfh_sac_ia"`` (SAC-IA),
    ``"shot"``, ``"3dsc"``, ``"ppf"`` (PPFRegistration), ``"pfh"`` and ``"rsd"`` (as FPFH), ``"gasd"`` (the two
    clouds' GASD canonical frames) or ``"vfh"`` (OUR-CVFH: the paired clusters' SGURFs; plain VFH gives no pose).
    ``**settings`` override fields of the method's :data:`THESIS_PCL_PRESET` (``PclFeatureAlignmentSettings``, each
    field with its unit)."""
    if method not in _PCL_METHODS:
        raise ValueError(f"method: expected one of {sorted(_PCL_METHODS)}, got {method!r}")
    st = set_fields(_pcl_preset(method), settings, "PCL")
    s = as_points(source, "source", np.dtype(np.float32))
    t = as_points(target, "target", np.dtype(np.float32))
    if len(s) == 0 or len(t) == 0:
        raise ValueError("pcl_feature_alignment: source and target must not be empty")
    return _P.pcl_feature_alignment(s, t, st)


# --- pipeline -----------------------------------------------------------------------------------

def _model_views(model: object, views: Any) -> List[Any]:
    """The model as views (:func:`scanalign.pose.model_views.model_views`): rendered from a mesh, the visible subsets of
    a model cloud, from a model file, or given; ``views``: the ``ModelViewSettings`` of the pose settings."""
    return cad.model_views(model, views)


def _progress(what: str, pose_settings: Any, enabled: bool) -> Optional[Callable[[int, int], None]]:
    """When ``enabled``, the C++ progress callback (done, total): a tqdm bar per object on stderr."""
    if not enabled:
        return None
    method = getattr(pose_settings.method, "name", pose_settings.method)
    bar: Any = None

    def update(done: int, total: int) -> None:
        nonlocal bar
        from tqdm.auto import tqdm

        if done == 1:
            bar = tqdm(total=total, desc=f"{what} ({method})", unit="view", file=sys.stderr, dynamic_ncols=True,
                       disable=total < 2)
        bar.update(1)
        if done == total:
            bar.close()
    return update


#: Short keywords of :func:`estimate_pose`, :func:`find_objects` and :func:`find_parts`: field
#: paths under the pose settings (``PoseSettings``) and, for the two table searches, under
#: their settings struct. Any other field is given by its own name (``icp_distance``,
#: ``max_objects``, ``min_surface_coverage``) or nested (``pose={"cbd": {"hypotheses": 2}}``);
#: a field of ``CbdSettings`` (``radius``, ``gamma``, ...) sets the pose's CBD descriptor.
POSE_KEYWORDS = {"resolution": "views.resolution", "hypotheses": "cbd.hypotheses", "ransac": "cbd.ransac",
                 "cbd_settings": "cbd.cbd", "matches_per_keypoint": "cbd.matches_per_keypoint", "pcl_settings": "pcl"}
TABLE_KEYWORDS = {"table_threshold": "table.plane.threshold", "cluster_tolerance": "table.cluster_tolerance",
                  "min_cluster_size": "table.min_cluster_size", "viewpoint": "table.viewpoint", "up": "table.up"}
_CBD_FIELDS = frozenset(field_names(_cbd.CbdSettings))


def _path(s: Any, key: str, pose: str) -> str:
    """The field path of an override ``key`` under settings ``s`` whose pose settings are at ``pose``."""
    if key in field_names(s):
        return key
    if key in TABLE_KEYWORDS and hasattr(s, "table"):
        return TABLE_KEYWORDS[key]
    if key in field_names(PoseSettings):
        return pose + key
    if key in POSE_KEYWORDS:
        return pose + POSE_KEYWORDS[key]
    if key in _CBD_FIELDS:
        return pose + "cbd.cbd." + key
    known = sorted({*field_names(s), *(TABLE_KEYWORDS if hasattr(s, "table") else ()), *field_names(PoseSettings),
                    *POSE_KEYWORDS, *_CBD_FIELDS})
    raise UnknownSettingError(f"{key}: unknown pose setting; known: {', '.join(known)}")


def pose_task_settings(cls: type, settings: Any = None, **overrides: Any) -> Any:
    """A copy of ``settings`` (a ``cls``: :class:`PoseSettings`, ``FindObjectsSettings`` or ``FindPartsSettings``;
    default its C++ defaults) with ``overrides`` applied: field names (nested as dicts), the short keywords of
    :data:`POSE_KEYWORDS` and :data:`TABLE_KEYWORDS`, ``method`` (``"cbd"``, ``"flags"``, ``"pcl"`` or a PCL baseline of
    :data:`METHODS`, which sets ``method="pcl"`` and ``pcl`` to its :data:`THESIS_PCL_PRESET`) and ``num_threads``
    (every step's). Raises UnknownSettingError / TypeError / ValueError naming the field."""
    s = with_overrides(cls, settings, (), "pose")
    pose = "" if cls is PoseSettings else "pose."
    if (method := overrides.pop("method", None)) is not None:
        if method not in METHODS and method != "pcl":
            raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
        set_path(s, pose + "method", method if method in ("cbd", "flags", "pcl") else "pcl")
        if method in _PCL_METHODS:
            set_path(s, pose + "pcl", _pcl_preset(method))
    if (threads := overrides.pop("num_threads", None)) is not None:  # every step's
        table = ["table.plane.num_threads"] if hasattr(s, "table") else []
        for path in [pose + "num_threads", pose + "views.num_threads", *table]:
            set_path(s, path, threads)
    # whole structs first (cbd_settings=CbdSettings(...)), then the fields that refine them
    for key, value in sorted(overrides.items(), key=lambda kv: not is_struct(kv[1])):
        set_path(s, _path(s, key, pose), value)
    return s


def estimate_pose(model: object, scene: np.ndarray, settings: Optional[PoseSettings] = None, *,
                  views: Optional[Sequence[int]] = None, progress: bool = False, **overrides: Any) -> PoseResult:
    """Pose of ``model`` in one object cloud: coarse alignment of every model view (or the model cloud) to the object,
    ICP refinement (point-to-plane, scanalign's engine), and the candidate with the best score
    ``2 fitness coverage / (fitness + coverage)``.

    ``model``: a mesh (:class:`scanalign.io.Mesh`, ``(vertices, faces)`` or a mesh file path; metres) rendered from the
    42 vertices of a tessellated sphere with ``settings.views``, the list of
    :class:`scanalign.pose.model_views.ModelView` that :func:`scanalign.pose.model_views.render_views` returned
    (rendered once, reused across objects), or an (N, 3) cloud. ``scene``: (M, 3) the object's points in the scene
    (camera) frame, metres. ``settings``: :class:`PoseSettings` (default its C++ defaults); keyword ``overrides`` as
    :func:`pose_task_settings` takes them (``method="fpfh"``, ``icp_distance=0.02``, ``resolution=100``,
    ``radius=0.012`` for the CBD neighbourhood, ...). ``views``: the view indices to try (default all 42); ``progress``:
    a progress bar over the views on stderr.

    Returns a :class:`PoseResult`: ``found`` False with a message when no view aligned or the best one's fitness or
    coverage is below ``min_fitness`` / ``min_coverage``.
    """
    s = pose_task_settings(PoseSettings, settings, **overrides)
    model_views = _model_views(model, s.views)
    scene = as_points(scene, "scene", np.dtype(np.float64))
    return _P.estimate_pose(model_views, scene, s, [int(i) for i in views or []], _progress("pose", s, progress))


def find_objects(model: object, scene: np.ndarray, settings: Optional[Any] = None, *,
                 views: Optional[Sequence[int]] = None, progress: bool = False, **overrides: Any) -> FindObjectsResult:
    """Poses of a part in a table scene (paper 3 / paper 5 pipeline): RANSAC table plane in CGA, remove it and
    everything below it, Euclidean clusters, then the pose per cluster as :func:`estimate_pose` (at most
    ``max_objects``, largest first), of ``model`` as :func:`estimate_pose` takes it (a mesh is rendered once for all
    objects) in ``scene``, an (N, 3) scan in the camera frame, metres.

    ``settings``: ``FindObjectsSettings`` (``table``, ``max_objects``, ``pose``); keyword ``overrides`` as
    :func:`pose_task_settings` takes them (``table_threshold``, ``cluster_tolerance`` m, ``min_cluster_size``,
    ``viewpoint`` / ``up`` to orient the table normal, and every keyword of :func:`estimate_pose`). Returns a
    :class:`FindObjectsResult` (``poses``, ``objects`` as index arrays, the table ``plane``).
    """
    s = pose_task_settings(_P.FindObjectsSettings, settings, **overrides)
    pts = as_points(scene, "scene", np.dtype(np.float64))
    model_views = _model_views(model, s.pose.views)
    return _P.find_objects(model_views, pts, s, [int(i) for i in views or []], _progress("pose", s.pose, progress))


def find_parts(models: Sequence[object], scene: np.ndarray, settings: Optional[FindPartsSettings] = None, *,
               symmetries: Optional[Sequence[Any]] = None, views: Optional[Sequence[int]] = None,
               progress: bool = False, **overrides: Any) -> FindPartsResult:
    """Which of several known parts lies in each object cluster of a table scene, and its pose: the table and clusters
    as :func:`find_objects` (segmented once), then every part's views aligned to each cluster (its normals and
    descriptors computed once), the best part by score, and a :class:`DetectionStatus`: ``found``, ``not_found`` (no
    part passes ``min_fitness`` / ``min_coverage``) or ``ambiguous`` (a runner-up -- another part, or a pose of the same
    part that its symmetry does not make equivalent -- scores nearly as well; see
    ``FindPartsSettings.ambiguity_margin``).

    ``models``: one model per part, each as :func:`estimate_pose` takes it (a mesh, its rendered views, or a cloud;
    render meshes once with :func:`scanalign.pose.model_views.render_views` when calling repeatedly). ``scene``: (N, 3)
    scan, metres (camera or base frame; ``T_scene_model`` is in that frame). ``settings``: :class:`FindPartsSettings`
    (default its C++ defaults; every field with its unit and meaning: ``help(FindPartsSettings)``,
    ``scanalign dump-config pose``); keyword ``overrides`` as :func:`pose_task_settings` takes them (``max_objects=3``,
    ``up=(0, 0, 1)``, ``cbd_radius_fraction=0.15``, ``method="fpfh"``, ...). ``symmetries``: one ``PartSymmetry``
    (``axis``, ``point`` m, ``order``; e.g. from :data:`scanalign.data.parts.BUILTIN_PARTS`) or None per part (default:
    none symmetric). ``views``: view indices tried for every part (default all 42).

    Returns a :class:`FindPartsResult`: per cluster a :class:`PartDetection` (``status``, ``part``, ``pose``, runner-up,
    ``indices``, ``parts``: the :class:`PoseResult` of every part).
    """
    if isinstance(models, (str, bytes)) or not isinstance(models, Sequence) or len(models) == 0:
        raise ValueError("models: expected a non-empty list with one model per part")
    s = pose_task_settings(FindPartsSettings, settings, **overrides)
    pts = as_points(scene, "scene", np.dtype(np.float64))
    model_views = [_model_views(m, s.pose.views) for m in models]
    return _P.find_parts(model_views, pts, s, None if symmetries is None else list(symmetries),
                         [int(i) for i in views or []], _progress("parts", s.pose, progress))

"""Rigid registration: the fast ICP engine and stock PCL baselines.

The engine follows the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929) (Algorithm 1, §3.1-3.4): a k-d
tree over the target, nearest neighbours, box and distance rejection, and Low's point-to-plane linear least squares (or
closed-form point-to-point: SVD or dual quaternion), iterated until PCL's convergence criteria hold.
:class:`IcpSettings`, :class:`IcpResult` and :class:`Box` are the C++ structs; their fields carry their docs.

Frames and units: points in metres; ``source`` is in the source frame (e.g. the camera of
a new frame), ``target`` in the target frame (e.g. the model). Every transform returned
is ``T_target_source`` (4x4): ``p_target = T_target_source @ p_source``.

Example::

    from scanalign.registration import icp
    result = icp(source, target, target_normals, max_correspondence_distance=0.01)
    if result.converged:
        T_model_camera = result.T_target_source
"""

from __future__ import annotations

from typing import Literal, Optional, Sequence, Union

import numpy as np

from scanalign import _core
from scanalign.common.arrays import as_points, as_transform, foreign_attribute
from scanalign.common.settings import set_fields

Box = _core.registration.Box
IcpSettings = _core.registration.IcpSettings
IcpResult = _core.registration.IcpResult

Estimator = Literal["point_to_plane", "point_to_point", "dual_quaternion"]
Backend = Literal["cpu", "cuda"]
PclVariant = Literal["svd", "dual_quaternion", "point_to_plane_lls", "scanalign_point_to_plane_lls"]
BoxLike = Union[Box, Sequence[float], None]

__all__ = ["Box", "IcpSettings", "IcpResult", "Icp", "icp", "pcl_icp", "KdTree", "point_to_plane_lls",
           "pcl_point_to_plane_lls", "box_rejector_keep", "make_settings", "cuda_devices"]

_F32 = np.dtype(np.float32)


def make_settings(settings: Optional[IcpSettings] = None, **overrides: object) -> IcpSettings:
    """A copy of ``settings`` (or the defaults) with :class:`IcpSettings` fields overridden by keyword (``box`` also
    takes 6 numbers, metres). TypeError: an unknown field or a value of the wrong type; ValueError: an invalid value
    (the message names the field)."""
    s = set_fields(IcpSettings() if settings is None else IcpSettings(settings), overrides, "ICP")
    s.validate()
    return s


class Icp(_core.registration.Icp):
    """Reusable ICP against one target (the model): the k-d tree is built once.

    For frame-to-model registration, where many frames are aligned to the same model::

    engine = Icp(model_points, model_normals, max_correspondence_distance=0.01) result = engine.align(frame_points,
    init=T_model_camera_previous)

    ``target``: (N, 3) float32/float64 target points, metres, target frame; ``target_normals``: their (N, 3) unit
    normals (required for point-to-plane; points whose normal is non-finite or zero are left out; default: the normals
    of an Open3D ``target`` cloud that has them); ``settings``: an :class:`IcpSettings`, keyword overrides applied on
    top. The tree keeps the target's dtype (float32 if both arrays are: half the memory, faster); sources are cast to
    it. ``settings`` (a copy; assign a new one to change them), ``target_size`` and ``tree_build_seconds`` are
    properties. Raises as :func:`icp`.
    """

    def __init__(self, target: np.ndarray, target_normals: Optional[np.ndarray] = None,
                 settings: Optional[IcpSettings] = None, **overrides: object) -> None:
        if target_normals is None:  # an Open3D cloud's own normals, when it has them
            target_normals = foreign_attribute(target, "normals")
        n = None if target_normals is None else as_points(target_normals, "target_normals")
        super().__init__(as_points(target, "target"), n, make_settings(settings, **overrides))

    def align(self, source: np.ndarray, init: Optional[np.ndarray] = None) -> IcpResult:
        """Aligns ``source`` ((N, 3), metres, source frame; non-finite rows ignored) to the
        target from ``init`` (``T_target_source``, 4x4 rigid; identity by default).
        Check ``converged`` / ``status`` of the :class:`IcpResult`."""
        return super().align(as_points(source, "source"), np.eye(4) if init is None else as_transform(init))


def icp(source: np.ndarray, target: np.ndarray, target_normals: Optional[np.ndarray] = None,
        init: Optional[np.ndarray] = None, *, max_correspondence_distance: Optional[float] = None,
        box: BoxLike = None, estimator: Optional[Estimator] = None, max_iterations: Optional[int] = None,
        transformation_epsilon: Optional[float] = None, fitness_epsilon: Optional[float] = None,
        backend: Optional[Backend] = None, settings: Optional[IcpSettings] = None, **overrides: object) -> IcpResult:
    """Registers ``source`` ((N, 3) float32/float64 points in the source frame, metres) to ``target`` ((M, 3), the
    target frame, metres) with scanalign's ICP engine; returns an :class:`IcpResult` with ``T_target_source`` (check
    ``converged``/``status``: e.g. "degenerate").

    ``target_normals``: (M, 3) unit target normals, required for point-to-plane (default: those of an Open3D ``target``
    cloud that has them). ``init``: initial ``T_target_source`` (4x4 rigid), identity by default. The keywords are
    :class:`IcpSettings` fields, None taking the value of ``settings`` (or the C++ defaults):
    ``max_correspondence_distance`` (m; farther pairs are rejected), ``box`` (in the source camera frame: :class:`Box`
    or 6 numbers, m), ``estimator`` (``"point_to_plane"``, eye-in-hand paper §3.2; ``"point_to_point"``, SVD; or
    ``"dual_quaternion"``, the same least squares by Walker et al. 1991, the paper's variant (b)), the
    PCL-style convergence criteria ``max_iterations``, ``transformation_epsilon``, ``fitness_epsilon`` (eye-in-hand
    paper §3.3), ``backend`` (``"cpu"``, or ``"cuda"``: the passes on an NVIDIA GPU, the paper's Algorithm 1, with the
    CPU engine's poses; see :func:`cuda_devices`), and in ``overrides`` any other field, e.g. ``num_threads=1``.

    TypeError: non-float arrays, unknown settings. ValueError: wrong shapes, empty clouds, mismatched or missing
    normals, bad settings or a non-rigid ``init``. RuntimeError: ``backend="cuda"`` in a build without CUDA (the
    message names ``SCANALIGN_WITH_CUDA``) or on a machine without a CUDA device. KeyboardInterrupt: Ctrl-C, between
    iterations.
    """
    s = _settings(settings, overrides, max_correspondence_distance=max_correspondence_distance, box=box,
                  estimator=estimator, max_iterations=max_iterations, transformation_epsilon=transformation_epsilon,
                  fitness_epsilon=fitness_epsilon, backend=backend)
    return Icp(target, target_normals, s).align(source, init)


def cuda_devices() -> list:
    """The CUDA devices ``backend="cuda"`` can use (``"0: NVIDIA H200 (compute capability 9.0, 143166 MiB)"``); empty
    without a device or driver, or when scanalign was built without ``SCANALIGN_WITH_CUDA``
    (``scanalign._core.built_with_cuda`` says which)."""
    return list(_core.registration.cuda_devices())


def _settings(settings: Optional[IcpSettings], overrides: dict, **named: object) -> IcpSettings:
    """make_settings with the named keyword arguments that were given (not None)."""
    return make_settings(settings, **{k: v for k, v in named.items() if v is not None}, **overrides)


def pcl_icp(source: np.ndarray, target: np.ndarray, target_normals: Optional[np.ndarray] = None,
            init: Optional[np.ndarray] = None, *, variant: PclVariant = "point_to_plane_lls",
            max_correspondence_distance: Optional[float] = None, box: BoxLike = None,
            max_iterations: Optional[int] = None, transformation_epsilon: Optional[float] = None,
            fitness_epsilon: Optional[float] = None, settings: Optional[IcpSettings] = None,
            **overrides: object) -> IcpResult:
    """Stock PCL 1.13 ICP on the same inputs and criteria, for evaluation (eye-in-hand paper §4).

    Variants: ``"svd"`` (``IterativeClosestPoint`` + SVD), ``"dual_quaternion"``, ``"point_to_plane_lls"``
    (``IterativeClosestPointWithNormals``, PCL's own LLS; needs ``target_normals``), and
    ``"scanalign_point_to_plane_lls"`` (the same with scanalign's ``PointToPlaneLLS`` plugged in). Clouds are converted
    to float32 PCL clouds. The result's fitness / RMSE are measured like the engine's; ``seconds`` times PCL's tree
    build and ``align``. Other arguments and errors as :func:`icp` (the estimator is the variant's;
    ``search_stack_depth`` and ``warm_start`` do not apply).
    """
    s = _settings(settings, overrides, max_correspondence_distance=max_correspondence_distance, box=box,
                  max_iterations=max_iterations, transformation_epsilon=transformation_epsilon,
                  fitness_epsilon=fitness_epsilon)
    target_normals = foreign_attribute(target, "normals") if target_normals is None else target_normals
    nrm = None if target_normals is None else as_points(target_normals, "target_normals", _F32)
    return _core.registration.pcl_icp(as_points(source, "source", _F32), as_points(target, "target", _F32), nrm,
                                      np.eye(4) if init is None else as_transform(init), s, variant)


def point_to_plane_lls(source: np.ndarray, target: np.ndarray, target_normals: np.ndarray,
                       degeneracy_threshold: float = 1e-10) -> tuple:
    """One point-to-plane LLS step (Low 2004, eye-in-hand paper §3.2) on given correspondences: row i of ``source`` is
    paired with row i of ``target`` / ``target_normals`` (metres, unit normals; ValueError unless all have the same
    number of rows). Runs ``scanalign::PointToPlaneLLS`` (the PCL plug-in, double precision). Needs at least 6
    well-spread pairs to constrain all motions. Returns ``(T_target_source, rank, conditioning, degenerate)``: the 4x4
    transform; the number of constrained motion directions (6 when well posed); lambda_min/lambda_max of the balanced
    normal matrix; whether directions were left unconstrained (they are then kept at zero motion rather than solved from
    round-off)."""
    T, rank, cond, degenerate, _ = _core.registration.point_to_plane_lls(
        *_paired(source, target, target_normals), degeneracy_threshold)
    return np.asarray(T), int(rank), float(cond), bool(degenerate)


def pcl_point_to_plane_lls(source: np.ndarray, target: np.ndarray, target_normals: np.ndarray) -> np.ndarray:
    """PCL's ``TransformationEstimationPointToPlaneLLS`` (double) on the same pairing as
    :func:`point_to_plane_lls`; the oracle it is tested against. Returns a 4x4."""
    return np.asarray(_core.registration.pcl_point_to_plane_lls(*_paired(source, target, target_normals))[0])


def _paired(source: np.ndarray, target: np.ndarray, normals: np.ndarray) -> tuple:
    return as_points(source, "source", _F32), as_points(target, "target", _F32), as_points(normals, "target_normals", _F32)


def box_rejector_keep(source: np.ndarray, query_indices: Sequence[int], box: BoxLike) -> np.ndarray:
    """Runs ``scanalign::BoxRejector`` (the PCL ``CorrespondenceRejector`` plug-in) on
    correspondences whose source indices are ``query_indices``; returns the kept ones
    (int64). ValueError for indices out of range or a missing / invalid box."""
    kept = _core.registration.box_rejector_keep(as_points(source, "source", _F32), query_indices, box)
    return np.asarray(kept, dtype=np.int64)


#: The left-balanced k-d tree of the eye-in-hand paper, §3.1: ``KdTree(points)`` ((N, 3)
#: float, metres); ``nearest(queries, max_distance=inf, stack_depth=20)`` returns (int64
#: indices, -1 for none in range; distances in metres; per-query exactness flags).
KdTree = _core.registration.KdTree

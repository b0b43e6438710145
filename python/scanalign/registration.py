"""Rigid registration: the fast ICP engine and stock PCL baselines.

The engine follows the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929)
(Algorithm 1, §3.1-3.4): a left-balanced k-d tree over the
target, nearest neighbours with a fixed-size search stack, box and distance rejection,
and Low's point-to-plane linear least squares (or closed-form point-to-point) reduced by
a summing tree, iterated until PCL's convergence criteria hold.

Frames and units: points in metres; ``source`` is expressed in the source frame (e.g.
the camera of a new frame), ``target`` in the target frame (e.g. the model). Every
transform returned is ``T_target_source``: a 4x4 homogeneous matrix with
``p_target = T_target_source @ p_source``.

Example::

    from scanalign.registration import icp
    result = icp(source, target, target_normals, max_correspondence_distance=0.01)
    if result.converged:
        T_model_camera = result.T_target_source
"""

from __future__ import annotations

from typing import Literal, Optional, Sequence, Union

import numpy as np

from . import _core
from ._arrays import as_points, as_transform, common_dtype

Box = _core.registration.Box
IcpSettings = _core.registration.IcpSettings
IcpResult = _core.registration.IcpResult

Estimator = Literal["point_to_plane", "point_to_point"]
PclVariant = Literal["svd", "dual_quaternion", "point_to_plane_lls", "scanalign_point_to_plane_lls"]
BoxLike = Union[Box, Sequence[float], None]

__all__ = [
    "Box",
    "IcpSettings",
    "IcpResult",
    "Icp",
    "icp",
    "pcl_icp",
    "KdTree",
    "point_to_plane_lls",
    "pcl_point_to_plane_lls",
    "box_rejector_keep",
    "make_settings",
]

Box.__doc__ = """Axis-aligned box ``(x_min, x_max, y_min, y_max, z_min, z_max)`` in metres, in the
source camera frame (x right, y down, z towards the object); eye-in-hand paper §3.4.

A correspondence is kept only when its source point lies inside the box (bounds
inclusive). The box is attached to the source frame, so it moves with the transform ICP
applies to the source. Presets: ``Box.free_hand_preset()`` (±0.20 m, 0.1 mm-10 m deep)
and ``Box.banana_preset()`` from the eye-in-hand paper."""

IcpSettings.__doc__ = """ICP settings (PCL semantics; defaults are those of the eye-in-hand paper, §3.3, where it gives one).

Fields:
    estimator: ``"point_to_plane"`` (Low 2004 LLS, default; needs target normals) or
        ``"point_to_point"`` (closed form, Horn/Umeyama).
    max_correspondence_distance: pairs farther apart are rejected, metres (default 0.05).
    max_iterations: iteration cap (default 50); reaching it gives status
        ``"max_iterations"`` and ``converged=False``.
    transformation_epsilon: converged when the last increment's squared translation is
        <= this (m²) and its rotation has cos(angle) >= 1 - this (default 1e-8).
    transformation_rotation_epsilon: if > 0, the rotation test uses cos(angle) >= this
        cosine instead (PCL's setTransformationRotationEpsilon; default 0).
    fitness_epsilon: converged when the relative change of the correspondence MSE is
        below this (PCL's Euclidean fitness epsilon; default 1e-8).
    absolute_mse_epsilon: converged when the MSE changes by less than this, m² (1e-12).
    robust_kernel: ``"none"`` (default, Low's plain least squares as the eye-in-hand paper),
        ``"huber"`` or ``"cauchy"``: an M-estimator on the point-to-plane residual, solved
        by iteratively reweighted least squares (point-to-plane only). Use it when the
        correspondence distance is large (sparse scans, large initial motion): on the
        small_gicp LiDAR pair (0.25 m voxels, 1 m distance) Huber at 0.1 m lands 6 mm from
        the reference instead of 27 mm.
    robust_scale: the kernel's scale, metres (default 0.01): residuals up to about this
        count fully; set it near the residual noise after convergence.
    box: optional :class:`Box` in the source camera frame.
    search: the target's nearest-neighbour structure: ``"bucket_kdtree"`` (default; a
        k-d tree with 32-point leaves and tight node boxes, the fastest on CPU cores, always
        exact) or ``"left_balanced_kdtree"`` (eye-in-hand paper §3.1: one point per node, searched
        with a fixed stack; the layout the eye-in-hand paper's GPU path uses).
    search_stack_depth: fixed search stack of the left-balanced tree (seed: 20); exact for
        targets of up to 2**21 - 1 points; ``IcpResult.exact_search`` reports otherwise.
    warm_start: seed each search with the last iteration's neighbour (exact speed-up).
    min_correspondences: stop with ``"not_enough_correspondences"`` below this (at least
        6 for point-to-plane, 3 for point-to-point are enforced).
    degeneracy_threshold: eigenvalue ratio below which a motion direction counts as
        unconstrained (planar scenes); such directions are not updated (default 1e-10:
        only numerically exact rank loss, because a small object on a large table gives
        ratios near 1e-7 that must still be solved).
    coarse_stride: coarse-to-fine when > 1: iterate first on every ``coarse_stride``-th
        source point (an even spatial subset) until that converges, then on all points
        until they converge; the answer is the full-resolution fixed point either way,
        reached with fewer full iterations (default 1 = off, as the eye-in-hand paper; skipped when the
        subset has fewer than 500 points).
    num_threads: OpenMP threads, 0 = all cores."""

IcpResult.__doc__ = """Outcome of an ICP run; quality figures are measured at the final transform.

Attributes:
    T_target_source: 4x4 float64, maps source coordinates into the target frame.
    converged: a convergence criterion (transform or MSE change) was met.
    status: ``"converged_transform"``, ``"converged_absolute_mse"``,
        ``"converged_relative_mse"``, ``"max_iterations"`` or
        ``"not_enough_correspondences"`` (the transform is then the last good estimate).
    iterations: full-resolution iterations run.
    coarse_iterations: iterations of the coarse phase (``coarse_stride`` > 1), each on a
        subset of the source.
    fitness: inlier correspondences / usable source points (finite and inside the box).
    inlier_rmse: RMS point-to-point distance of the inliers, metres.
    correspondence_count: inliers at the final transform.
    source_points_used: finite source points inside the box.
    mse: mean squared correspondence distance of the last iteration, m².
    degenerate / min_rank: some iteration could not constrain all 6 motions.
    exact_search: every nearest-neighbour search was exact.
    seconds: wall time of the alignment (target tree build excluded)."""


def make_settings(settings: Optional[IcpSettings] = None, **overrides: object) -> IcpSettings:
    """Copies ``settings`` (or the defaults) and applies keyword overrides by field name.

    ``box`` accepts a :class:`Box`, a 6-sequence ``(x_min, x_max, y_min, y_max, z_min,
    z_max)`` in metres, or None. Unknown names raise TypeError; invalid values ValueError.
    """
    s = IcpSettings()
    if settings is not None:
        for name in _SETTING_FIELDS:
            setattr(s, name, getattr(settings, name))
    for name, value in overrides.items():
        if name not in _SETTING_FIELDS:
            raise TypeError(f"unknown ICP setting {name!r}; valid: {', '.join(_SETTING_FIELDS)}")
        if name == "box":
            value = _as_box(value)  # type: ignore[arg-type]
        try:
            setattr(s, name, value)
        except TypeError as e:
            raise TypeError(f"ICP setting {name}: {e}") from None
    s.validate()
    return s


_SETTING_FIELDS = (
    "estimator",
    "max_correspondence_distance",
    "max_iterations",
    "transformation_epsilon",
    "transformation_rotation_epsilon",
    "fitness_epsilon",
    "absolute_mse_epsilon",
    "robust_kernel",
    "robust_scale",
    "box",
    "search",
    "search_stack_depth",
    "warm_start",
    "min_correspondences",
    "degeneracy_threshold",
    "coarse_stride",
    "num_threads",
)


def _as_box(box: BoxLike) -> Optional[Box]:
    if box is None or isinstance(box, Box):
        return box
    values = [float(v) for v in box]  # type: ignore[union-attr]
    if len(values) != 6:
        raise ValueError("box: expected (x_min, x_max, y_min, y_max, z_min, z_max)")
    b = Box(*values)
    if not b.valid:
        raise ValueError(f"box: bounds must be finite with min <= max, got {values}")
    return b


class Icp:
    """Reusable ICP against one target (the model): the k-d tree is built once.

    Use it for frame-to-model registration, where many frames are aligned to the same
    model, or to re-align after changing settings::

        engine = Icp(model_points, model_normals, max_correspondence_distance=0.01)
        result = engine.align(frame_points, init=T_model_camera_previous)

    Args:
        target: (N, 3) float32/float64 target points, metres, target frame.
        target_normals: (N, 3) unit normals of the target (required for point-to-plane).
            Points whose normal is non-finite or zero are left out.
        settings: an :class:`IcpSettings`; keyword overrides are applied on top.

    Float32 targets keep the tree in float32 (half the memory, faster); sources are cast
    to the target's dtype when needed.
    """

    def __init__(
        self,
        target: np.ndarray,
        target_normals: Optional[np.ndarray] = None,
        settings: Optional[IcpSettings] = None,
        **overrides: object,
    ) -> None:
        s = make_settings(settings, **overrides)
        t = as_points(target, "target")
        n = None if target_normals is None else as_points(target_normals, "target_normals")
        dtype = common_dtype(t, n)
        self._target = as_points(t, "target", dtype)
        self._normals = None if n is None else as_points(n, "target_normals", dtype)
        if self._normals is not None and self._normals.shape[0] != self._target.shape[0]:
            raise ValueError(
                f"target_normals: {self._normals.shape[0]} normals for {self._target.shape[0]} target points"
            )
        if self._target.shape[0] == 0:
            raise ValueError("target: empty point cloud")
        if s.estimator == "point_to_plane" and self._normals is None:
            raise ValueError("point-to-plane ICP needs target_normals (or use estimator='point_to_point')")
        self._dtype = dtype
        self._engine = (_core.registration.Icp64 if dtype == np.float64 else _core.registration.Icp32)(s)
        self._engine.set_target(self._target, self._normals)

    @property
    def settings(self) -> IcpSettings:
        """A copy of the current settings (assign a new one to change them)."""
        return self._engine.settings

    @settings.setter
    def settings(self, value: IcpSettings) -> None:
        s = make_settings(value)
        if s.estimator == "point_to_plane" and self._normals is None:
            raise ValueError("point-to-plane ICP needs target normals")
        self._engine.settings = s

    @property
    def target_size(self) -> int:
        """Points in the k-d tree (finite points with valid normals)."""
        return int(self._engine.target_size)

    @property
    def tree_build_seconds(self) -> float:
        """Time spent building the target's k-d tree and normal table, seconds."""
        return float(self._engine.tree_build_seconds)

    def align(self, source: np.ndarray, init: Optional[np.ndarray] = None) -> IcpResult:
        """Aligns ``source`` (N, 3, metres, source frame) to the target.

        Args:
            source: source points; non-finite rows are ignored.
            init: initial ``T_target_source`` (4x4 rigid), identity by default.

        Returns:
            :class:`IcpResult`; check ``converged`` / ``status``.

        Raises:
            TypeError / ValueError: bad dtype, shape, empty source, non-rigid ``init``.
        """
        src = as_points(source, "source", self._dtype)
        if src.shape[0] == 0:
            raise ValueError("source: empty point cloud")
        T0 = np.eye(4) if init is None else as_transform(init)
        return self._engine.align(src, T0)


def icp(
    source: np.ndarray,
    target: np.ndarray,
    target_normals: Optional[np.ndarray] = None,
    init: Optional[np.ndarray] = None,
    *,
    max_correspondence_distance: Optional[float] = None,
    box: BoxLike = None,
    estimator: Optional[Estimator] = None,
    max_iterations: Optional[int] = None,
    transformation_epsilon: Optional[float] = None,
    fitness_epsilon: Optional[float] = None,
    settings: Optional[IcpSettings] = None,
    **overrides: object,
) -> IcpResult:
    """Registers ``source`` to ``target`` with scanalign's ICP engine.

    Keyword arguments left as None take their value from ``settings`` (or the
    :class:`IcpSettings` defaults, shown in brackets).

    Args:
        source: (N, 3) float32/float64 points in the source frame, metres.
        target: (M, 3) points in the target frame, metres.
        target_normals: (M, 3) unit target normals; required for point-to-plane.
        init: initial ``T_target_source`` (4x4 rigid), identity by default.
        max_correspondence_distance: metres; farther pairs are rejected [0.05].
        box: optional box in the source camera frame (:class:`Box` or 6 numbers, metres).
        estimator: ``"point_to_plane"`` (eye-in-hand paper §3.2) or ``"point_to_point"``
            [point_to_plane].
        max_iterations, transformation_epsilon, fitness_epsilon: PCL-style convergence
            criteria [50, 1e-8, 1e-8: eye-in-hand paper §3.3].
        settings: base :class:`IcpSettings`.
        **overrides: any other :class:`IcpSettings` field, e.g. ``num_threads=1``.

    Returns:
        :class:`IcpResult` with ``T_target_source``.

    Raises:
        TypeError: non-float arrays, unknown settings.
        ValueError: wrong shapes, empty clouds, mismatched normals, bad settings or a
            non-rigid ``init``.
    """
    named = _given(
        max_correspondence_distance=max_correspondence_distance,
        box=box,
        estimator=estimator,
        max_iterations=max_iterations,
        transformation_epsilon=transformation_epsilon,
        fitness_epsilon=fitness_epsilon,
    )
    s = make_settings(settings, **named, **overrides)
    return Icp(target, target_normals, s).align(source, init)


def _given(**kwargs: object) -> dict:
    return {k: v for k, v in kwargs.items() if v is not None}


def pcl_icp(
    source: np.ndarray,
    target: np.ndarray,
    target_normals: Optional[np.ndarray] = None,
    init: Optional[np.ndarray] = None,
    *,
    variant: PclVariant = "point_to_plane_lls",
    max_correspondence_distance: Optional[float] = None,
    box: BoxLike = None,
    max_iterations: Optional[int] = None,
    transformation_epsilon: Optional[float] = None,
    fitness_epsilon: Optional[float] = None,
    settings: Optional[IcpSettings] = None,
    **overrides: object,
) -> IcpResult:
    """Stock PCL 1.13 ICP on the same inputs and criteria, for evaluation (eye-in-hand paper §4).

    Variants: ``"svd"`` (``IterativeClosestPoint`` + SVD), ``"dual_quaternion"``,
    ``"point_to_plane_lls"`` (``IterativeClosestPointWithNormals``, PCL's own LLS), and
    ``"scanalign_point_to_plane_lls"`` (the same PCL ICP with scanalign's
    ``PointToPlaneLLS`` plugged in). Clouds are converted to float32 PCL clouds. The
    result's fitness / RMSE are measured like the engine's; ``seconds`` times PCL's
    tree build and ``align``. Other arguments as :func:`icp` (the estimator is the
    variant's; ``search_stack_depth`` and ``warm_start`` do not apply).
    """
    named = _given(
        max_correspondence_distance=max_correspondence_distance,
        box=box,
        max_iterations=max_iterations,
        transformation_epsilon=transformation_epsilon,
        fitness_epsilon=fitness_epsilon,
    )
    s = make_settings(settings, **named, **overrides)
    src = as_points(source, "source", np.dtype(np.float32))
    tgt = as_points(target, "target", np.dtype(np.float32))
    nrm = None if target_normals is None else as_points(target_normals, "target_normals", np.dtype(np.float32))
    if src.shape[0] == 0 or tgt.shape[0] == 0:
        raise ValueError("source and target must not be empty")
    if "point_to_plane" in variant:
        if nrm is None:
            raise ValueError(f"variant {variant!r} needs target_normals")
        if nrm.shape[0] != tgt.shape[0]:
            raise ValueError(f"target_normals: {nrm.shape[0]} normals for {tgt.shape[0]} target points")
    T0 = np.eye(4) if init is None else as_transform(init)
    return _core.registration.pcl_icp(src, tgt, nrm, T0, s, variant)


def _paired(source: np.ndarray, target: np.ndarray, normals: np.ndarray) -> tuple:
    arrays = [as_points(a, n, np.dtype(np.float32)) for a, n in ((source, "source"), (target, "target"), (normals, "target_normals"))]
    if not arrays[0].shape[0] == arrays[1].shape[0] == arrays[2].shape[0]:
        raise ValueError("source, target and target_normals must have the same number of rows (row i pairs them)")
    return tuple(arrays)


def point_to_plane_lls(
    source: np.ndarray, target: np.ndarray, target_normals: np.ndarray, degeneracy_threshold: float = 1e-10
) -> tuple:
    """One point-to-plane LLS step (Low 2004, eye-in-hand paper §3.2) on given correspondences.

    Row i of ``source`` is paired with row i of ``target`` / ``target_normals`` (metres,
    unit normals). Runs ``scanalign::PointToPlaneLLS`` (the PCL plug-in, double precision).
    Needs at least 6 well-spread pairs to constrain all motions.

    Returns:
        ``(T_target_source, rank, conditioning, degenerate)``: the 4x4 transform; the
        number of constrained motion directions (6 when well posed); lambda_min/lambda_max
        of the balanced normal matrix; whether directions were left unconstrained (they
        are then kept at zero motion rather than solved from round-off).
    """
    s, t, n = _paired(source, target, target_normals)
    T, rank, cond, degenerate, _seconds = _core.registration.point_to_plane_lls(s, t, n, float(degeneracy_threshold))
    return np.asarray(T), int(rank), float(cond), bool(degenerate)


def pcl_point_to_plane_lls(source: np.ndarray, target: np.ndarray, target_normals: np.ndarray) -> np.ndarray:
    """PCL's ``TransformationEstimationPointToPlaneLLS`` (double) on the same pairing as
    :func:`point_to_plane_lls`; the oracle it is tested against. Returns a 4x4."""
    s, t, n = _paired(source, target, target_normals)
    T, _seconds = _core.registration.pcl_point_to_plane_lls(s, t, n)
    return np.asarray(T)


def box_rejector_keep(source: np.ndarray, query_indices: Sequence[int], box: BoxLike) -> np.ndarray:
    """Runs ``scanalign::BoxRejector`` (the PCL ``CorrespondenceRejector`` plug-in) on
    correspondences whose source indices are ``query_indices``; returns the kept ones."""
    b = _as_box(box)
    if b is None:
        raise ValueError("box_rejector_keep needs a box")
    src = as_points(source, "source", np.dtype(np.float32))
    idx = np.asarray(query_indices, dtype=np.int64)
    if idx.size and (idx.min() < 0 or idx.max() >= src.shape[0]):
        raise ValueError("query_indices out of range of source")
    return np.asarray(_core.registration.box_rejector_keep(src, idx.tolist(), b), dtype=np.int64)


class KdTree:
    """The left-balanced k-d tree of the eye-in-hand paper, §3.1 (the engine's search structure).

    Args:
        points: (N, 3) float32/float64 points; non-finite rows are skipped.
    """

    def __init__(self, points: np.ndarray) -> None:
        self._points = as_points(points, "points")
        self._tree = (_core.registration.KdTree64 if self._points.dtype == np.float64 else _core.registration.KdTree32)(
            self._points
        )

    @property
    def size(self) -> int:
        return int(self._tree.size)

    @property
    def height(self) -> int:
        """Levels below the root; the fixed-stack search is exact when stack_depth >= height."""
        return int(self._tree.height)

    def nearest(
        self, queries: np.ndarray, max_distance: float = float("inf"), stack_depth: int = 20
    ) -> tuple:
        """Nearest neighbour of each query within ``max_distance`` (metres, exclusive).

        Returns:
            ``(indices, distances, exact)``: int64 indices into ``points`` (-1: none in
            range), Euclidean distances (inf where none), and per-query flags telling
            whether the fixed-size stack sufficed for an exact answer.
        """
        if not (max_distance > 0):
            raise ValueError("max_distance must be positive")
        if not 1 <= int(stack_depth) <= 64:
            raise ValueError("stack_depth must be in [1, 64]")
        q = as_points(queries, "queries", self._points.dtype)
        idx, d2, exact = self._tree.nearest(q, float(max_distance), int(stack_depth))
        return np.asarray(idx), np.sqrt(np.asarray(d2, dtype=np.float64)), np.asarray(exact)

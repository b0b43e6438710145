"""Eye-in-hand reconstruction: depth images to clouds, frame-to-model registration, and the voxel grid that keeps the
model bounded (the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929), §3, Algorithm 1).

Frames: a frame's points are in its camera frame (x right, y down, z forward, metres). The model lives in the *model
frame*: the first camera's frame by default, or any frame given as ``T_model_camera0`` (e.g. the robot base frame via
the first frame's ``T_base_camera``). Every estimated pose is ``T_model_camera`` (camera -> model).
:class:`FrameToModelSettings` is the C++ struct; its fields carry their docs.

Example::

    from scanalign.reconstruction import Reconstructor
    rec = Reconstructor()                       # ReconstructionSettings' defaults: 10 mm normals, 1 mm grid
    for frame in frames:                        # scanalign.reconstruction.camera.Frame objects
        record = rec.integrate(frame)
        if not record.merged:
            print("skipped", record.index, record.status)
    rec.model.write_ply("model.ply")
    rec.trajectory.write_tum("trajectory.txt")
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, List, Optional, Union

import numpy as np

from scanalign import _core
from scanalign.common.arrays import as_points, as_transform
from scanalign.common.settings import field_names, update, with_overrides
from scanalign.evaluation.trajectory import Trajectory
from scanalign.io import write_ply
from scanalign.reconstruction.camera import Frame, Intrinsics

__all__ = ["VoxelGridResult", "voxel_grid", "depth_to_cloud", "undistorted_rays", "frame_to_cloud", "DepthToCloudSettings",
           "BilateralFilterSettings", "bilateral_filter_depth", "FrameToModelSettings", "ReconstructionSettings",
           "make_reconstruction_settings", "FrameResult", "Model", "Reconstructor", "REGISTRATION_METHODS"]


@dataclass(frozen=True)
class VoxelGridResult:
    """One point per occupied voxel: ``points`` (M, 3) voxel centroids, metres, in the input dtype; ``normals`` (M, 3)
    mean unit normals (re-normalised) or None; ``colors`` (M, 3) mean colours in the input colour dtype or None;
    ``counts`` (M,) input points per voxel."""

    points: np.ndarray
    normals: Optional[np.ndarray]
    colors: Optional[np.ndarray]
    counts: np.ndarray


def voxel_grid(points: np.ndarray, leaf_size: float = 0.001, *, normals: Optional[np.ndarray] = None,
               colors: Optional[np.ndarray] = None, min_points_per_voxel: int = 1) -> VoxelGridResult:
    """Downsamples a cloud to one centroid per cubic voxel, like ``pcl::VoxelGrid``.

    Voxels are aligned to the cloud's minimum corner exactly as PCL does, and output in PCL's order, so results match
    PCL's voxel for voxel. Eye-in-hand paper §3.6 uses a 1 mm grid on the accumulated model after every merge so its
    size stays bounded.

    ``points``: (N, 3) float32/float64, metres; non-finite rows are dropped. ``leaf_size``: voxel edge, metres. Optional
    (N, 3) ``normals`` are averaged per voxel and re-normalised, optional (N, 3) ``colors`` (uint8 or float) averaged
    per voxel; voxels with fewer than ``min_points_per_voxel`` points are dropped. ValueError: bad leaf (not positive,
    or over 2**21 voxels along an axis of the cloud), min_points_per_voxel < 1, attributes with the wrong number of
    rows. NotRealError (a TypeError and a ValueError): normals or colours that are not real (strings, complex).
    """
    p = as_points(points, "points")
    attributes = []
    for name, a in (("normals", normals), ("colors", colors)):
        if a is not None and (np.shape(a) != (p.shape[0], 3) or np.asarray(a).dtype.kind not in "biuf"):
            raise (ValueError if np.asarray(a).dtype.kind in "biuf" else _core.reconstruction.NotRealError)(
                f"{name}: expected real ({p.shape[0]}, 3) values, got {np.asarray(a).dtype} {np.shape(a)}")
        attributes += [] if a is None else [np.asarray(a, dtype=np.float64)]
    centroids, means, counts = _core.reconstruction.voxel_grid(
        p, leaf_size, np.hstack(attributes) if attributes else None, min_points_per_voxel)  # types checked in C++
    out_normals = out_colors = None
    if normals is not None:  # the mean normal re-normalised (NaN where the normals cancel)
        with np.errstate(invalid="ignore", divide="ignore"):
            out_normals = (means[:, :3] / np.linalg.norm(means[:, :3], axis=1, keepdims=True)).astype(p.dtype)
    if colors is not None:
        c, cdtype = means[:, -3:], np.asarray(colors).dtype
        out_colors = np.clip(np.rint(c), 0, 255).astype(cdtype) if np.issubdtype(cdtype, np.integer) else c.astype(cdtype)
    return VoxelGridResult(centroids, out_normals, out_colors, counts)


def undistorted_rays(intrinsics: Intrinsics) -> np.ndarray:
    """(H, W, 2) float64: the normalised coordinates ``(x, y) = (X/Z, Y/Z)`` of the ray through
    every pixel centre ``(u, v)`` (``[v, u]``), as :func:`depth_to_cloud` uses them.

    Pinhole (zero distortion): ``((u - cx) / fx, (v - cy) / fy)``. With Brown-Conrady distortion
    ``(k1, k2, p1, p2, k3)`` each pixel is undistorted by OpenCV's ``undistortPoints`` fixed-point iteration until a
    step changes nothing (at most 100 steps: ``cv2.undistortPointsIter``); a pixel whose ray does not re-project onto it
    within 1e-3 pixels (diverged, or beyond the field of view where the radial factor folds over) is NaN and gives no
    point. Computed once per intrinsics (under 0.1 s for 640x480) and cached in C++ (8 cameras); a copy is returned."""
    if not isinstance(intrinsics, Intrinsics):
        raise TypeError("intrinsics must be a scanalign.reconstruction.camera.Intrinsics")
    if intrinsics.has_distortion:
        return _core.reconstruction.undistorted_rays(intrinsics)
    u = (np.arange(intrinsics.width) - intrinsics.cx) / intrinsics.fx
    v = (np.arange(intrinsics.height) - intrinsics.cy) / intrinsics.fy
    return np.stack(np.broadcast_arrays(u[None, :], v[:, None]), axis=-1)


DepthToCloudSettings = _core.reconstruction.DepthToCloudSettings


def depth_to_cloud(depth: np.ndarray, intrinsics: Intrinsics, settings: Optional[DepthToCloudSettings] = None, *,
                   rgb: Optional[np.ndarray] = None, return_pixels: bool = False, **overrides: Any):
    """Back-projects a depth image into a cloud in the camera frame.

    ``p = (z (u - cx) / fx, z (v - cy) / fy, z)`` for every valid pixel ``(u, v)`` (column, row); invalid pixels (0,
    NaN, outside ``[min_depth, max_depth]``) are dropped. With lens distortion ``p = (z x, z y, z)``, ``(x, y)`` the
    pixel's undistorted ray (:func:`undistorted_rays`, cached in C++: a frame costs what a pinhole frame costs); a pixel
    without a valid ray is dropped.

    ``depth``: (H, W) uint16 in units of ``depth_scale`` metres, or float32/float64 in metres; (H, W) must equal
    ``intrinsics.shape`` (the depth image's intrinsics, with its lens distortion, if any). ``settings``:
    ``DepthToCloudSettings`` (default its C++ defaults); keyword ``overrides`` name its fields: ``depth_scale`` (metres
    per unit of an integer image; TUM: 1/5000), ``min_depth`` / ``max_depth`` (valid range along z, m), ``stride``.
    ``rgb``: optional (H, W, 3) uint8 colour image registered to the depth image.

    Returns ``(points, colors)`` -- (N, 3) float32 metres and (N, 3) uint8 or None -- plus ``pixels`` (N,) int32, the
    flat pixel index ``row * W + column`` of each point, when ``return_pixels``. TypeError: unsupported depth dtype.
    ValueError: image size not matching the intrinsics, bad range, stride or ``depth_scale`` (outside (0, 1] m per
    unit).
    """
    if not isinstance(intrinsics, Intrinsics):
        raise TypeError("intrinsics must be a scanalign.reconstruction.camera.Intrinsics")
    s = with_overrides(DepthToCloudSettings, settings, overrides, "depth")
    points, colors, pixels = _core.reconstruction.depth_to_cloud(np.asarray(depth), intrinsics, s, rgb)
    return (points, colors, pixels) if return_pixels else (points, colors)


#: Bilateral smoothing of depth images before back-projection (KinectFusion-style): ``radius`` (pixels), ``sigma_space``
#: (pixels), ``sigma_depth`` (m). When to use it: axial sensor noise (about 1 mm at 0.4 m for an SR300) tilts 5 mm PCA
#: normals by several degrees, and since each normal's error is correlated with the noise of the points it was fitted
#: to, point-to-plane ICP drifts; the filter removes most of that noise while keeping depth edges, but rounds small
#: curved features slightly (it smooths along each camera's rays). Measured on the synthetic scans (36-frame loops):
#: SR300 noise, 10 mm normals: ATE 12.6 mm without, 4.1 mm with; 0.3 mm noise at 320x240 on small spheres: worst pose
#: error 0.23 mm without, 2.0 mm with. On by default (``ReconstructionSettings.filter_depth``; the eye-in-hand paper's
#: pipeline had none).
BilateralFilterSettings = _core.reconstruction.BilateralFilterSettings


def bilateral_filter_depth(depth: np.ndarray, settings: Optional[BilateralFilterSettings] = None, *,
                           depth_scale: float = 0.001, num_threads: int = 0) -> np.ndarray:
    """Bilateral-filters a depth image (see :data:`BilateralFilterSettings`; default its defaults): ``depth`` (H, W)
    uint16 in units of ``depth_scale`` metres (0 = invalid) or float metres (0 / NaN = invalid) becomes (H, W) float32
    metres, NaN where the input was invalid (empty for an empty image). ValueError beyond 2**27 pixels (checked before
    allocating) or for bad settings (named)."""
    f = BilateralFilterSettings() if settings is None else settings
    return _core.reconstruction.bilateral_filter_depth(np.asarray(depth), settings=f, depth_scale=depth_scale,
                                                       num_threads=num_threads)


def frame_to_cloud(frame: Frame, settings: Optional[DepthToCloudSettings] = None, **overrides: Any):
    """:func:`depth_to_cloud` of a :class:`scanalign.reconstruction.camera.Frame` (its depth scale and
    colour image). Returns ``(points, colors)``."""
    return depth_to_cloud(frame.depth, frame.intrinsics, settings, rgb=frame.rgb,
                          **{**overrides, "depth_scale": frame.depth_scale})


FrameToModelSettings = _core.reconstruction.FrameToModelSettings
ReconstructionSettings = _core.reconstruction.ReconstructionSettings

#: Registration methods of the pipeline: scanalign's engine (its estimator set in
#: ``frame_to_model.icp.estimator``) and stock PCL ICP variants for comparison (eye-in-hand paper §3.7).
REGISTRATION_METHODS = ("scanalign", "pcl_svd", "pcl_dual_quaternion", "pcl_point_to_plane_lls")
_ENGINE_FIELDS = frozenset(field_names(FrameToModelSettings))


def make_reconstruction_settings(settings: Union[ReconstructionSettings, FrameToModelSettings, None] = None,
                                 **overrides: Any) -> ReconstructionSettings:
    """A copy of ``settings`` with fields overridden by keyword, validated. ``settings``: a
    :class:`ReconstructionSettings` (default: its C++ defaults) or a :class:`FrameToModelSettings` (the engine's, with
    the other fields at their defaults). ``overrides`` name fields of :class:`ReconstructionSettings` or, for short, of
    its ``frame_to_model`` (``crop_box=(6 numbers)``, ``icp=dict(max_iterations=30)``); ``depth_filter`` also takes
    ``"default"`` (filter on, default filter) or None (off), ``initial_guess`` names
    ``frame_to_model.motion_model`` and ``backend`` names ``frame_to_model.icp.backend`` (``"cpu"`` or ``"cuda"``: the
    registration on an NVIDIA GPU, the model's tree resident there between frames). TypeError: an unknown field or a value of the wrong type; ValueError: an invalid
    value (the message names the field)."""
    s = (ReconstructionSettings(frame_to_model=settings) if isinstance(settings, FrameToModelSettings)
         else with_overrides(ReconstructionSettings, settings, (), "reconstruction"))
    job, engine = {}, {}
    for key, value in overrides.items():
        if key == "depth_filter" and (value is None or isinstance(value, str)):
            if value not in (None, "default"):
                raise ValueError(f"depth_filter: expected a BilateralFilterSettings, 'default' or None, got {value!r}")
            job["filter_depth"] = value is not None
        elif key == "depth_filter":
            job.update(filter_depth=True, depth_filter=value)
        elif key == "initial_guess":
            try:
                update(s.frame_to_model, {"motion_model": value})
            except ValueError as e:
                raise ValueError(f"initial_guess: {e}") from None
        elif key == "backend":
            try:
                update(s.frame_to_model.icp, {"backend": value})
            except ValueError as e:
                raise ValueError(f"backend: {e}") from None
        elif key in _ENGINE_FIELDS and key not in field_names(ReconstructionSettings):
            engine[key] = value
        else:
            job[key] = value
    update(s, job, what="reconstruction")
    update(s.frame_to_model, engine, what="reconstruction")
    s.validate()
    return s


#: What the reconstruction did with one frame (the C++ result, bound directly): index,
#: timestamp (s), status, merged, T_model_camera (camera -> model; for a skipped frame the guess
#: it was tried from), the registration's figures and the wall times; ``to_dict()``.
FrameResult = _core.reconstruction.FrameResult


@dataclass
class Model:
    """The accumulated model: (M, 3) float32 points in the model frame (m), (M, 3) unit
    normals (NaN where opposite normals cancelled), and (M, 3) uint8 colours or None. One
    point per occupied voxel of the model grid, in the order the voxels were first occupied."""

    points: np.ndarray
    normals: np.ndarray
    colors: Optional[np.ndarray]

    def __len__(self) -> int:
        return int(self.points.shape[0])

    def write_ply(self, path: Any, binary: bool = True) -> None:
        """Writes the model as PLY with normals (NaN normals written as 0) and colours."""
        write_ply(path, self.points, normals=np.nan_to_num(self.normals, nan=0.0), colors=self.colors, binary=binary)


class Reconstructor:
    """Frame-to-model reconstruction (Algorithm 1 of the eye-in-hand paper), one frame at a time.

    Each :meth:`integrate` call back-projects the frame, crops and downsamples it, estimates normals, registers it to
    the model starting from the motion model's guess, checks the result, merges it and voxel-grids the model (1 mm). A
    frame that fails is recorded with a ``skipped_*`` status and leaves the model untouched.

    ``settings``: :class:`ReconstructionSettings` (default: its defaults, as ``reconstruct``'s), or a
    :class:`FrameToModelSettings` (the eye-in-hand paper's engine, the job's other fields at their defaults); keyword
    ``overrides`` as :func:`make_reconstruction_settings` takes them; :attr:`job` is the :class:`ReconstructionSettings`
    in use, :attr:`settings` its ``frame_to_model``. ``T_model_camera0``: pose of the first frame's camera in the model
    frame (4x4, camera -> model); identity (default): the model frame is the first camera's.
    """

    def __init__(self, settings: Union[ReconstructionSettings, FrameToModelSettings, None] = None, *,
                 T_model_camera0: Optional[np.ndarray] = None, **overrides: Any) -> None:
        self.job = make_reconstruction_settings(settings, **overrides)
        self.settings = self.job.frame_to_model
        self._core = _core.reconstruction.FrameToModel(self.settings)
        self.records: List[FrameResult] = []
        self.reset(T_model_camera0)

    def reset(self, T_model_camera0: Optional[np.ndarray] = None) -> None:
        """Empties the model and the records; the next accepted frame is placed at
        ``T_model_camera0`` (4x4 rigid, identity by default)."""
        T0 = np.eye(4) if T_model_camera0 is None else as_transform(T_model_camera0, "T_model_camera0")
        self._core.reset(T0)
        self.T_model_camera0 = T0
        self.records = []

    def integrate(self, frame: Frame, guess: Optional[np.ndarray] = None) -> FrameResult:
        """Back-projects and integrates one RGB-D frame (its depth image must match its intrinsics), starting from
        ``guess``, an initial ``T_model_camera`` (e.g. from the robot's kinematics; default ``settings.motion_model``,
        the last accepted pose). ValueError / TypeError: a malformed frame (wrong image size for the intrinsics, bad
        dtype). Frames that are merely unusable (empty, all-invalid depth, unregistrable) are returned as skipped
        records instead."""
        if not isinstance(frame, Frame):
            raise TypeError("integrate() takes a scanalign.reconstruction.camera.Frame; use integrate_points() for clouds")
        depth, job = frame.depth, self.job
        if job.filter_depth:
            depth = bilateral_filter_depth(depth, job.depth_filter, depth_scale=frame.depth_scale,
                                           num_threads=self.settings.num_threads)
        points, colors = depth_to_cloud(depth, frame.intrinsics, rgb=frame.rgb, depth_scale=frame.depth_scale,
                                        min_depth=job.min_depth, max_depth=job.max_depth, stride=job.pixel_stride)
        return self.integrate_points(points, colors, guess=guess, timestamp=frame.timestamp)

    def integrate_points(self, points: np.ndarray, colors: Optional[np.ndarray] = None, *,
                         guess: Optional[np.ndarray] = None, timestamp: Optional[float] = None) -> FrameResult:
        """Integrates a cloud given in the camera frame ((N, 3) metres; optional (N, 3)
        colours, uint8 or float in [0, 1]). See :meth:`integrate`."""
        p = as_points(points, "points", np.dtype(np.float32))
        c = None if colors is None else np.asarray(colors)
        if c is not None and c.dtype != np.uint8 and c.shape == (p.shape[0], 3):
            scale = 255.0 if np.issubdtype(c.dtype, np.floating) and c.size and c.max() <= 1.0 else 1.0
            c = np.clip(np.rint(c * scale), 0, 255).astype(np.uint8)
        rec = self._core.integrate(p, c, None if guess is None else as_transform(guess, "guess"), self.job.registration)
        rec.timestamp = float(rec.index) if timestamp is None else float(timestamp)
        self.records.append(rec)
        return rec

    @property
    def model(self) -> Model:
        """The current model (a copy)."""
        return Model(self._core.model_points(), self._core.model_normals(), self._core.model_colors())

    @property
    def model_size(self) -> int:
        return int(self._core.model_size)

    @property
    def last_pose(self) -> np.ndarray:
        """The last accepted ``T_model_camera`` (``T_model_camera0`` before any frame)."""
        return np.array(self._core.last_pose)

    @property
    def predicted_pose(self) -> np.ndarray:
        """The initial guess ``T_model_camera`` of the next frame integrated without one
        (``settings.motion_model`` applied to the last accepted poses)."""
        return np.array(self._core.predicted_pose)

    @property
    def trajectory(self) -> Trajectory:
        """Estimated camera poses ``T_model_camera`` of the merged frames."""
        merged = [r for r in self.records if r.merged]
        return Trajectory(np.array([r.timestamp for r in merged], dtype=np.float64),
                          np.array([r.T_model_camera for r in merged]).reshape(-1, 4, 4))

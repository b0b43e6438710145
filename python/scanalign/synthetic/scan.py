"""Rendering a scan: noisy depth and shaded colour per camera pose, with the exact truth."""

from __future__ import annotations

import concurrent.futures
import math
import os
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Union

import numpy as np

from scanalign import _core, io
from scanalign.common import rigid as se3
from scanalign.common.arrays import require_memory
from scanalign.evaluation.trajectory import Trajectory
from scanalign.reconstruction import depth_to_cloud
from scanalign.reconstruction.camera import Frame, Intrinsics
from scanalign.reconstruction.rendering import as_intrinsics
from scanalign.synthetic.noise import SensorNoise, as_noise
from scanalign.synthetic.scene import Scene
from scanalign.synthetic.trajectories import ScanTrajectory

__all__ = ["SyntheticScan", "render_scan"]


@dataclass
class SyntheticScan:
    """A rendered scan with its ground truth (``intrinsics``, ``noise``, ``scene`` and ``seed`` as rendered).

    Attributes:
        frames: one :class:`scanalign.reconstruction.camera.Frame` per pose (depth and registered rgb as stored by
            :func:`render_scan`, ``timestamp`` (s), the exact ``T_base_camera`` (camera -> base), ``index``); ``meta``
            holds ``noise``, ``T_base_flange``, ``joints`` (6, rad) and ``robot`` (its name) when known, and with
            ``keep_ground_truth`` ``depth_true`` (float32 m, NaN = no hit) and ``face_id`` (int32, into :attr:`mesh`).
        reference: the exact camera trajectory, ``T_base_camera`` per frame.
        mesh, object_mesh: the whole scene (objects and table), the objects only: base frame, m.
        T_flange_camera, T_base_flange, joints, robot, T_base_robot: those of the :class:`ScanTrajectory` rendered,
            else None.
    """

    frames: List[Frame]
    reference: Trajectory
    mesh: io.Mesh
    object_mesh: io.Mesh
    intrinsics: Intrinsics
    noise: SensorNoise
    T_flange_camera: Optional[np.ndarray]
    T_base_flange: Optional[np.ndarray]
    scene: Scene
    seed: int
    joints: Optional[np.ndarray] = None
    robot: Optional[Any] = None
    T_base_robot: Optional[np.ndarray] = None

    def __len__(self) -> int:
        return len(self.frames)

    def points(self, index: int, in_base: bool = False) -> np.ndarray:
        """(N, 3) float64 points (m) of frame ``index``'s valid depth pixels in the camera frame (the base frame with
        ``in_base``), back-projected by the C++ ``depth_to_cloud`` (so with its float32 rounding, ~1e-7 m)."""
        frame = self.frames[index]
        p = depth_to_cloud(frame.depth, self.intrinsics, depth_scale=frame.depth_scale, min_depth=0.0,
                           max_depth=math.inf)[0].astype(np.float64)
        return _core.common.transform_points(frame.T_base_camera, p) if in_base else p


def _camera_poses(poses: Union[ScanTrajectory, Trajectory, np.ndarray], frame_rate: float):
    """(N, 4, 4) rigid camera poses (camera -> base) and (N,) timestamps (s)."""
    if isinstance(poses, (ScanTrajectory, Trajectory)):
        T_cams, stamps = getattr(poses, "T_base_camera", getattr(poses, "poses", None)), poses.timestamps
    else:
        T_cams = np.asarray(poses, dtype=np.float64)
        T_cams = T_cams[None] if T_cams.ndim == 2 else T_cams
        if T_cams.ndim != 3 or T_cams.shape[1:] != (4, 4):
            raise ValueError(f"poses: expected (N, 4, 4) camera poses, got shape {T_cams.shape}")
        if not (math.isfinite(frame_rate) and frame_rate > 0):
            raise ValueError(f"frame_rate must be positive (Hz), got {frame_rate!r}")
        stamps = np.arange(len(T_cams)) / frame_rate
    if len(T_cams) == 0:
        raise ValueError("poses: no camera poses given")
    return np.array([se3.require_rigid(T, f"poses[{k}]") for k, T in enumerate(T_cams)]), np.array(stamps, float)


def render_scan(scene: Scene, poses: Union[ScanTrajectory, Trajectory, np.ndarray],
                intrinsics: Union[Intrinsics, str] = "sr300", noise: Union[SensorNoise, str, None] = "sr300",
                seed: int = 0, *, depth_unit: Union[float, str, None] = "auto", near: float = 0.01,
                keep_ground_truth: bool = False, frame_rate: float = 10.0, num_threads: int = 0) -> SyntheticScan:
    """Renders a scan: noisy depth and shaded colour for every camera pose.

    Args:
        poses: a :class:`ScanTrajectory` (its hand-eye transform, flange poses and robot are kept in the scan and each
            frame's meta), a :class:`Trajectory` of ``T_base_camera``, or an (N, 4, 4) array of ``T_base_camera``
            (camera -> base, m; timestamps ``k / frame_rate``, Hz).
        intrinsics: camera intrinsics or a preset name (:data:`scanalign.reconstruction.camera.INTRINSICS_PRESETS`).
        noise: a :class:`SensorNoise` or a preset name (``NOISE_PRESETS``); None = "none".
        seed: frame ``k``'s noise is seeded from ``numpy.random.SeedSequence(seed).spawn(N)[k]``: equal seeds give
            bit-identical frames, whatever the number of frames rendered.
        depth_unit: metres per unit of the stored uint16 depth (0, and depths over 65535 units, = missing); ``"auto"``:
            the sensor's own step if any (1/8 mm SR300, 1 mm D435), else 0.1 mm; None: float32 metres, NaN = missing.
        near: renderer near plane (m).
        keep_ground_truth: also store the noise-free depth and face ids in ``frame.meta``.
        num_threads: frames rendered concurrently (each on one thread); 0 = one per CPU.

    TypeError, ValueError: bad arguments (unknown preset, malformed poses, non-positive depth unit, frames that would
    not fit in half the machine's memory ...).
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"scene: expected Scene, got {type(scene)!r}")
    K = as_intrinsics(intrinsics)
    model = as_noise(noise)
    if isinstance(depth_unit, str):
        if depth_unit != "auto":
            raise ValueError(f"depth_unit must be a length in metres, 'auto' or None, got {depth_unit!r}")
        depth_unit = model.depth_unit if model.depth_unit > 0 else 1e-4
    elif depth_unit is not None and not (math.isfinite(depth_unit) and depth_unit > 0):
        raise ValueError(f"depth_unit must be a positive length in metres, 'auto' or None, got {depth_unit!r}")
    for name, v in (("seed", seed), ("num_threads", num_threads)):
        if int(v) != v or v < 0:
            raise ValueError(f"{name} must be a non-negative integer, got {v!r}")
    T_cams, stamps = _camera_poses(poses, frame_rate)
    need = len(T_cams) * K.width * K.height * (3 + (4 if depth_unit is None else 2) + 8 * keep_ground_truth)
    require_memory(need, f"{len(T_cams)} frames of {K.width}x{K.height}")  # frames are kept in memory
    # What a ScanTrajectory adds: the hand-eye transform, flange poses and the robot's joints.
    src = {k: getattr(poses, k, None) for k in ("T_flange_camera", "T_base_flange", "joints", "robot", "T_base_robot")}
    src = {k: v.copy() if isinstance(v, np.ndarray) else v for k, v in src.items()}
    children = np.random.SeedSequence(int(seed)).spawn(len(T_cams))
    scene._prepare_shading()  # build the shared caches before the worker threads read them

    def render_frame(k: int) -> Frame:
        T = T_cams[k]
        clean = scene.render(T, K, near=near, num_threads=1)
        z = _core.synthetic.apply_sensor_noise(model, clean.depth, clean.cos_incidence,
                                               int(children[k].generate_state(1, np.uint64)[0]))
        depth, scale = z, 1.0
        if depth_unit is not None:
            units = np.round(np.nan_to_num(z, nan=0.0) / depth_unit)
            units[(units > 65535) | (units < 0)] = 0
            depth, scale = units.astype(np.uint16), float(depth_unit)
        meta: Dict[str, Any] = {"noise": model.name}
        meta.update({key: src[key][k].copy() for key in ("T_base_flange", "joints") if src[key] is not None})
        if src["joints"] is not None and src["robot"] is not None:
            meta["robot"] = src["robot"].name
        if keep_ground_truth:
            meta.update(depth_true=clean.depth, face_id=clean.face_id)
        return Frame(depth=depth, intrinsics=K, rgb=scene.shade(clean, T, K), depth_scale=scale,
                     timestamp=float(stamps[k]), T_base_camera=T.copy(), index=k, meta=meta)

    # Independent frames on a pool of threads, each single-threaded (the renderer and NumPy
    # release the GIL): better than threads within a small frame on a busy machine.
    workers = max(1, min(int(num_threads) or os.cpu_count() or 1, len(T_cams)))
    if workers == 1:
        frames = [render_frame(k) for k in range(len(T_cams))]
    else:
        with concurrent.futures.ThreadPoolExecutor(max_workers=workers) as pool:
            frames = list(pool.map(render_frame, range(len(T_cams))))
    return SyntheticScan(frames=frames, reference=Trajectory(stamps, T_cams.copy()), mesh=scene.mesh,
                         object_mesh=scene.object_mesh, intrinsics=K, noise=model, scene=scene, seed=int(seed), **src)

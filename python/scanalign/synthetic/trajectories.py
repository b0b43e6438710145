"""Planned camera paths around the scene (a loop, hemisphere rings) and the flange poses
that carry the camera, optionally followed by a robot arm (:mod:`.mount`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional, Sequence, Tuple

import numpy as np

from .. import _core, se3
from ..trajectory import Trajectory

__all__ = ["DEFAULT_T_FLANGE_CAMERA", "ScanTrajectory", "loop_trajectory", "hemisphere_trajectory"]

#: Default hand-eye calibration ``T_flange_camera`` (camera -> flange): the camera beside the
#: gripper, 5 cm in front of the flange along its z axis and 3.5 cm off-axis along its x axis,
#: looking along the tool axis rotated by 3 deg about x, -2 deg about y and 1 deg about z (the
#: misalignment of a real bracket, so the hand-eye transform is not a pure offset).
DEFAULT_T_FLANGE_CAMERA: np.ndarray = se3.rigid([1.0, 0.0, 0.0], math.radians(3.0), [0.035, 0.0, 0.05])
DEFAULT_T_FLANGE_CAMERA[:3, :3] = (DEFAULT_T_FLANGE_CAMERA[:3, :3] @ se3.rotation_about([0.0, 1.0, 0.0], math.radians(
    -2.0)) @ se3.rotation_about([0.0, 0.0, 1.0], math.radians(1.0)))
DEFAULT_T_FLANGE_CAMERA.setflags(write=False)


@dataclass
class ScanTrajectory:
    """Robot poses of a scan and the camera poses they give.

    Attributes:
        T_base_flange: (N, 4, 4) flange poses (flange -> base), metres. With a robot, forward
            kinematics of :attr:`joints`: ``robot.fk(joints)``.
        T_flange_camera: (4, 4) hand-eye transform (camera -> flange).
        timestamps: (N,) seconds.
        joints: (N, 6) joint values of the robot (rad), or None when planned without a robot.
        robot: the :class:`scanalign.kinematics.Robot` that moves the camera, placed in the
            scene (base transform ``T_base_robot``, tool the flange), so that
            ``robot.fk(joints)`` is :attr:`T_base_flange`; None without a robot.
        T_base_robot: (4, 4) mounting of the robot base in the scene (robot base -> scene
            base), or None.
    """

    T_base_flange: np.ndarray
    T_flange_camera: np.ndarray
    timestamps: np.ndarray
    joints: Optional[np.ndarray] = None
    robot: Optional[Any] = None
    T_base_robot: Optional[np.ndarray] = None

    def __post_init__(self) -> None:
        n = len(self.T_base_flange)
        self.T_base_flange = _array(self.T_base_flange, (n, 4, 4), "T_base_flange")
        self.T_flange_camera = se3.require_rigid(self.T_flange_camera, "T_flange_camera")
        self.timestamps = _array(np.ravel(self.timestamps), (n,), "timestamps")
        self.joints = None if self.joints is None else _array(self.joints, (n, 6), "joints")
        if self.T_base_robot is not None:
            self.T_base_robot = se3.require_rigid(self.T_base_robot, "T_base_robot")

    def __len__(self) -> int:
        return len(self.T_base_flange)

    @property
    def T_base_camera(self) -> np.ndarray:
        """(N, 4, 4) camera poses ``T_base_flange @ T_flange_camera``."""
        return self.T_base_flange @ self.T_flange_camera

    @property
    def reference(self) -> Trajectory:
        """The exact camera trajectory (``T_base_camera`` per frame) as a :class:`Trajectory`."""
        return Trajectory(self.timestamps.copy(), self.T_base_camera)


def _array(value: Any, shape: Tuple[int, ...], name: str) -> np.ndarray:
    """``value`` as a finite float64 array of ``shape``; ValueError naming ``name`` otherwise."""
    a = np.asarray(value, dtype=np.float64)
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected finite values of shape {shape}, got shape {a.shape}")
    return a


def _planned(T_base_camera: np.ndarray, T_flange_camera: Optional[np.ndarray], frame_rate: float,
             jitter_translation: float, jitter_rotation: float, seed: int, robot: Any,
             T_base_robot: Optional[np.ndarray], q_start: Optional[Sequence[float]],
             center: np.ndarray) -> ScanTrajectory:
    """Flange poses ``T_base_camera @ inv(T_flange_camera)`` of planned camera poses,
    optionally jittered, then followed by ``robot`` when one is given."""
    Tfc = DEFAULT_T_FLANGE_CAMERA if T_flange_camera is None else se3.require_rigid(T_flange_camera, "T_flange_camera")
    if not (math.isfinite(frame_rate) and frame_rate > 0):
        raise ValueError(f"frame_rate must be positive (Hz), got {frame_rate!r}")
    if not (jitter_translation >= 0 and jitter_rotation >= 0):
        raise ValueError("jitter_translation, jitter_rotation: amplitudes must be non-negative (m, rad)")
    T_cam = np.array(T_base_camera, dtype=np.float64)
    if jitter_translation > 0 or jitter_rotation > 0:
        # Vibration-like perturbation of where the camera really is; the reference records
        # the perturbed pose, so it stays exact.
        rng = np.random.default_rng(seed)
        for T in T_cam:
            axis = rng.normal(size=3)
            T[:3, :3] = se3.rotation_about(axis, rng.normal() * jitter_rotation) @ T[:3, :3]
            T[:3, 3] += rng.normal(size=3) * jitter_translation
    traj = ScanTrajectory(T_cam @ se3.inverse(np.asarray(Tfc)), np.array(Tfc), np.arange(len(T_cam)) / frame_rate)
    if robot is None or (isinstance(robot, str) and robot == "none"):
        if T_base_robot is not None or q_start is not None:
            raise ValueError("T_base_robot and q_start need a robot")
        return traj
    from .mount import DEFAULT_ROBOT_HEIGHT, attach_robot, robot_mount  # mount builds on ScanTrajectory

    if T_base_robot is None:
        T_base_robot = robot_mount(float(center[0]), float(center[1]), float(center[2]) + DEFAULT_ROBOT_HEIGHT)
    return attach_robot(traj, robot, T_base_robot=T_base_robot, q_start=q_start)


def loop_trajectory(
    n_frames: int = 36,
    *,
    center: Sequence[float] = (0.5, 0.0, 0.0),
    height: float = 0.40,
    radius: float = 0.20,
    start_angle: float = 0.0,
    sweep: float = 2 * math.pi,
    target: Optional[Sequence[float]] = None,
    T_flange_camera: Optional[np.ndarray] = None,
    frame_rate: float = 10.0,
    jitter_translation: float = 0.0,
    jitter_rotation: float = 0.0,
    seed: int = 0,
    robot: Any = None,
    T_base_robot: Optional[np.ndarray] = None,
    q_start: Optional[Sequence[float]] = None,
) -> ScanTrajectory:
    """A loop around the object, as in the eye-in-hand paper (Comput. Electron. Agric. 180
    (2021) 105929, Fig. 4): the camera circles at ``height`` above the table, tilted to look
    at the target.

    Camera ``k`` sits at ``center + (radius cos a_k, radius sin a_k, height)`` with
    ``a_k = start_angle + sweep k / n_frames`` (a full loop by default, without repeating the
    first pose), its optical axis through ``target``, image up towards +z. Flange poses are
    ``T_base_camera @ inv(T_flange_camera)``. Timestamps are ``k / frame_rate``.

    Args:
        n_frames: number of poses (>= 1).
        center: loop centre on the table, base frame (m).
        height: camera height above ``center`` (m, > 0).
        radius: loop radius (m, >= 0).
        start_angle, sweep: first azimuth and swept angle (rad).
        target: point looked at (m); default ``center``.
        T_flange_camera: hand-eye transform; default :data:`DEFAULT_T_FLANGE_CAMERA`.
        frame_rate: Hz.
        jitter_translation, jitter_rotation: standard deviations (m, rad) of an optional
            random perturbation of each camera pose (the reference includes it). 0: smooth.
        seed: seed of the jitter.
        robot: None (default): the planned flange poses, no arm. A robot name ("ur5") or
            :class:`scanalign.kinematics.Robot`: the arm follows the path
            (:func:`~scanalign.synthetic.attach_robot`), the trajectory carries its joints, and
            its poses are forward kinematics of them.
        T_base_robot: with a robot, its mounting in the scene (robot base -> base, m); default
            :func:`~scanalign.synthetic.robot_mount` hanging ``DEFAULT_ROBOT_HEIGHT`` above ``center``.
        q_start: with a robot, joints (rad) to start from (default: chosen automatically, elbow up).
    """
    c = _array(center, (3,), "center")
    poses = _core.synthetic.loop_camera_poses(n_frames, c, height, radius, start_angle, sweep,
                                              c if target is None else _array(target, (3,), "target"))
    return _planned(poses, T_flange_camera, frame_rate, jitter_translation, jitter_rotation, seed, robot,
                    T_base_robot, q_start, c)


def hemisphere_trajectory(
    n_frames: int = 48,
    *,
    center: Sequence[float] = (0.5, 0.0, 0.0),
    distance: float = 0.45,
    elevations: Sequence[float] = (math.radians(35.0), math.radians(55.0), math.radians(75.0)),
    start_angle: float = 0.0,
    target: Optional[Sequence[float]] = None,
    T_flange_camera: Optional[np.ndarray] = None,
    frame_rate: float = 10.0,
    jitter_translation: float = 0.0,
    jitter_rotation: float = 0.0,
    seed: int = 0,
    robot: Any = None,
    T_base_robot: Optional[np.ndarray] = None,
    q_start: Optional[Sequence[float]] = None,
) -> ScanTrajectory:
    """Rings on a hemisphere of radius ``distance`` around the target, one per elevation.

    Frames are shared between rings in proportion to their circumferences (``cos(elevation)``,
    at least one each); successive rings run in opposite directions, each starting where the
    previous ended: one continuous serpentine. Every camera looks at ``target`` (default
    ``center``) with image up towards +z (outwards at 90 deg elevation).

    Args:
        n_frames: total number of poses (>= number of rings).
        center: centre of the hemisphere's base on the table, base frame (m).
        distance: camera distance to the target (m).
        elevations: ring elevations above the table plane (rad, in (0, pi/2]).
        start_angle: azimuth of the first pose (rad).
        target, T_flange_camera, frame_rate, jitter_translation, jitter_rotation, seed,
            robot, T_base_robot, q_start: as for :func:`loop_trajectory`.
    """
    c = _array(center, (3,), "center")
    poses = _core.synthetic.hemisphere_camera_poses(n_frames, c if target is None else _array(target, (3,), "target"),
                                                    distance, np.ravel(elevations), start_angle)
    return _planned(poses, T_flange_camera, frame_rate, jitter_translation, jitter_rotation, seed, robot,
                    T_base_robot, q_start, c)

"""Planned camera paths around the scene (a loop, hemisphere rings), the flange poses that
carry the camera, and the robot arm that follows them: where it is mounted, its joints by
inverse kinematics and its poses by forward kinematics."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any, Optional, Sequence, Tuple

import numpy as np

from scanalign import _core
from scanalign import kinematics as kin
from scanalign.common import rigid as se3
from scanalign.evaluation.trajectory import Trajectory

__all__ = ["DEFAULT_T_FLANGE_CAMERA", "ScanTrajectory", "loop_trajectory", "hemisphere_trajectory", "DEFAULT_ROBOT_HEIGHT", "robot_mount", "attach_robot"]

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

#: Default height (m) of the scan robot's base above the table top (:func:`robot_mount`).
DEFAULT_ROBOT_HEIGHT: float = 0.90


def robot_mount(x: float = 0.5, y: float = 0.0, z: float = DEFAULT_ROBOT_HEIGHT, roll: float = math.pi,
                pitch: float = 0.0, yaw: float = 0.0) -> np.ndarray:
    """``T_base_robot``: where a robot's own base frame sits in the scene (robot base ->
    scene base), from a position (m) and roll / pitch / yaw angles (rad, rotation
    ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``, as URDF).

    The default hangs the arm upside down (roll = pi: first joint axis down) 0.9 m above the
    centre of the default table, e.g. on a gantry. A camera circling an object all the way
    round circles the arm's first axis too: from a base beside the table, a UR5 (reach
    0.85 m) cannot reach the far side of the default hemisphere path, and the near side
    passes through the shoulder singularity (the wrist within d4 = 0.11 m of the first
    axis). From above, both default paths lie 0.15-0.47 m from the first axis and 0.3-0.7 m
    from the shoulder, inside the workspace and away from every singularity.
    """
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in (x, y, z, roll, pitch, yaw)):
        raise ValueError(f"robot_mount: expected finite numbers (m, rad), got {(x, y, z, roll, pitch, yaw)!r}")
    T = se3.rigid([0.0, 0.0, 1.0], yaw, [x, y, z])
    T[:3, :3] = T[:3, :3] @ se3.rotation_about([0.0, 1.0, 0.0], pitch) @ se3.rotation_about([1.0, 0.0, 0.0], roll)
    return T


def as_robot(robot: Any) -> Any:
    """A :class:`scanalign.kinematics.Robot`, or one by name (:meth:`Robot.by_name`)."""
    if isinstance(robot, str):
        return kin.Robot.by_name(robot)
    if not isinstance(robot, kin.Robot):
        raise TypeError(f"robot: expected a scanalign.kinematics.Robot or a robot name, got {type(robot)!r}")
    return robot


def attach_robot(
    trajectory: ScanTrajectory,
    robot: Any = "ur5",
    *,
    T_base_robot: Optional[np.ndarray] = None,
    q_start: Optional[Sequence[float]] = None,
    elbow: str = "up",
) -> ScanTrajectory:
    """Moves a planned camera path with a robot arm: joints by inverse kinematics, poses by
    forward kinematics.

    The planned flange poses are mapped into the robot's base frame,
    ``inv(T_base_robot) @ T_base_flange``; :meth:`Robot.ik_trajectory` takes at each step the
    solution closest to the previous joints; forward kinematics of those joints gives the
    returned flange poses, so the reference camera poses are the robot's own (equal to the
    planned ones to ~1e-15 m, the IK being exact).

    Unless ``q_start`` is given, the start is chosen among the first pose's solutions with
    the requested ``elbow`` ("up": the elbow away from the table, IK label +1 for an upright
    base and -1 for a hanging one; "down": the other; "any"), each with its first and last
    joint shifted by 0, -2 pi and +2 pi where the limits allow: the one whose trajectory
    reaches every pose with the smallest largest joint step wins (ties within 1e-9 rad: the
    lowest configuration index, then no shift, -2 pi, +2 pi). So a loop around the first axis
    starts where it can turn all the way within the joint limits, and no step switches branch.

    Args:
        trajectory: the planned path (its ``T_base_flange`` and ``T_flange_camera``).
        robot: a :class:`scanalign.kinematics.Robot` or a name for :meth:`Robot.by_name`
            ("ur5", ...); its tool becomes the flange (the hand-eye transform plays that
            role), its base ``T_base_robot`` (composed with the model's DH-frame-0 placement).
        T_base_robot: (4, 4) mounting of the robot base in the scene (robot base -> scene
            base, metres); default :func:`robot_mount` ``()``.
        q_start: (6,) joints (rad) to start from: the first step is the solution closest to it.
        elbow: "up", "down" or "any" (ignored with ``q_start``).

    Returns:
        A new :class:`ScanTrajectory` with ``joints``, ``robot`` (placed in the scene) and
        ``T_base_robot`` set.

    Raises:
        ValueError: a pose the robot cannot reach, or reaches only outside its joint limits
            (naming the frame, its time and the IK status), a bad ``elbow`` or ``q_start``, or
            a malformed ``T_base_robot``.
        TypeError: ``robot`` or ``trajectory`` of another type.
    """
    if not isinstance(trajectory, ScanTrajectory):
        raise TypeError(f"trajectory: expected ScanTrajectory, got {type(trajectory)!r}")
    if elbow not in ("up", "down", "any"):
        raise ValueError(f"elbow must be 'up', 'down' or 'any', got {elbow!r}")
    model = as_robot(robot).with_tool(np.eye(4))
    Tbr = robot_mount() if T_base_robot is None else se3.require_rigid(T_base_robot, "T_base_robot")
    # Flange poses in the robot's own base frame, which is what its controller (and IK) sees.
    T_robot_flange = se3.inverse(Tbr) @ trajectory.T_base_flange
    stamps = trajectory.timestamps

    def where(k: int) -> str:
        p = T_robot_flange[k, :3, 3]
        return (f"frame {k} (t = {stamps[k]:.3f} s, flange at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m in the "
                f"{model.name} base frame)")

    def run(q0: np.ndarray) -> Tuple[Any, float]:
        tr = model.ik_trajectory(T_robot_flange, q0)
        if not np.all(tr.ok):
            return tr, math.inf
        return tr, float(np.abs(np.diff(np.vstack([q0[None], tr.q]), axis=0)).max())

    if q_start is not None:  # Robot.ik_trajectory checks it (6 finite values, naming q_start)
        best, _ = run(np.asarray(q_start, dtype=np.float64))
    else:
        best = _best_start(model, Tbr, T_robot_flange[0], elbow, run, where)
    if not np.all(best.ok):
        k = int(np.flatnonzero(~np.asarray(best.ok, dtype=bool))[0])
        raise ValueError(f"robot {model.name} mounted at T_base_robot cannot follow the camera path: {where(k)} "
                         f"has IK status {best.status[k]!r} ({int(np.count_nonzero(best.ok))} of "
                         f"{len(T_robot_flange)} frames reachable); move the robot (T_base_robot) or the path")
    q = np.array(best.q, dtype=np.float64)
    placed = model.with_base(Tbr @ model.T_base_dh0)
    return ScanTrajectory(placed.fk(q), trajectory.T_flange_camera.copy(), stamps.copy(), joints=q, robot=placed,
                          T_base_robot=Tbr.copy())


def _best_start(model: Any, Tbr: np.ndarray, T_first: np.ndarray, elbow: str, run: Any, where: Any) -> Any:
    """The IK trajectory from the best start configuration (see :func:`attach_robot`)."""
    first = model.ik(T_first)
    ok = np.asarray(first.ok, dtype=bool)
    if not ok.any():
        status = sorted(set(first.status), key=("outside_limits", "unreachable", "invalid_input", "ok").index)
        raise ValueError(f"robot {model.name} mounted at T_base_robot cannot reach {where(0)}: IK status "
                         f"{status[0]!r} for every configuration; move the robot (T_base_robot) or the path")
    # Elbow label of "up" in the scene: +1 when the robot's z axis points upwards.
    z_up = (Tbr @ model.T_base_dh0)[2, 2] >= 0
    want = {"up": 1 if z_up else -1, "down": -1 if z_up else 1, "any": 0}[elbow]
    candidates = [k for k in range(8) if ok[k] and (want == 0 or int(first.config[k][1]) == want)]
    if not candidates:
        raise ValueError(f"robot {model.name}: no elbow-{elbow} solution within the joint limits for {where(0)}; "
                         f"use elbow='any' or another mount")
    best, best_step = None, math.inf
    for k, d1, d6 in itertools.product(candidates, *[(0.0, -2 * math.pi, 2 * math.pi)] * 2):
        q0 = np.array(first.q[k], dtype=np.float64) + [d1, 0, 0, 0, 0, d6]
        if np.any(q0 < model.limits[:, 0]) or np.any(q0 > model.limits[:, 1]):
            continue
        tr, step = run(q0)
        # Strictly smaller by more than rounding: equal steps keep the earlier candidate.
        if best is None or step < best_step - 1e-9 or (
                step == best_step == math.inf and np.count_nonzero(tr.ok) > np.count_nonzero(best.ok)):
            best, best_step = tr, step
    if best is None:
        raise ValueError(f"robot {model.name}: every start for {where(0)} lies outside the joint limits")
    return best

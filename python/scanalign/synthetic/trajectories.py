"""Planned camera paths around the scene (a loop, hemisphere rings), the flange poses that carry the camera, and the
robot arm that follows them: where it is mounted, its joints by inverse kinematics, its poses by forward kinematics."""

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

__all__ = ["DEFAULT_T_FLANGE_CAMERA", "ScanTrajectory", "loop_trajectory", "hemisphere_trajectory",
           "DEFAULT_ROBOT_HEIGHT", "robot_mount", "attach_robot"]

#: Default hand-eye calibration ``T_flange_camera`` (camera -> flange): the camera beside the gripper, 5 cm in front of
#: the flange along its z axis and 3.5 cm off-axis along its x axis, looking along the tool axis rotated by 3 deg about
#: x, -2 deg about y and 1 deg about z (the misalignment of a real bracket, so the hand-eye transform is not an offset).
DEFAULT_T_FLANGE_CAMERA: np.ndarray = se3.rigid([1.0, 0.0, 0.0], math.radians(3.0), [0.035, 0.0, 0.05])
DEFAULT_T_FLANGE_CAMERA[:3, :3] = (DEFAULT_T_FLANGE_CAMERA[:3, :3] @ se3.rotation_about([0.0, 1.0, 0.0], math.radians(
    -2.0)) @ se3.rotation_about([0.0, 0.0, 1.0], math.radians(1.0)))
DEFAULT_T_FLANGE_CAMERA.setflags(write=False)


@dataclass
class ScanTrajectory:
    """Robot poses of a scan and the camera poses they give.

    Attributes:
        T_base_flange: (N, 4, 4) flange poses (flange -> base), metres.
        T_flange_camera: (4, 4) hand-eye transform (camera -> flange).
        timestamps: (N,) seconds.
        joints: (N, 6) joint values of the robot (rad), or None when planned without a robot.
        robot: the :class:`scanalign.kinematics.Robot` that moves the camera, placed in the
            scene, its tool the flange: ``robot.fk(joints)`` is :attr:`T_base_flange`; or None.
        T_base_robot: (4, 4) mounting of the robot base in the scene (robot base -> base), or None.
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
        self.T_base_robot = None if self.T_base_robot is None else se3.require_rigid(self.T_base_robot, "T_base_robot")

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
    """Flange poses ``T_base_camera @ inv(T_flange_camera)`` of planned camera poses, optionally jittered, then
    followed by ``robot`` when one is given."""
    Tfc = DEFAULT_T_FLANGE_CAMERA if T_flange_camera is None else se3.require_rigid(T_flange_camera, "T_flange_camera")
    if not (math.isfinite(frame_rate) and frame_rate > 0):
        raise ValueError(f"frame_rate must be positive (Hz), got {frame_rate!r}")
    if not (jitter_translation >= 0 and jitter_rotation >= 0):
        raise ValueError("jitter_translation, jitter_rotation: amplitudes must be non-negative (m, rad)")
    T_cam = np.array(T_base_camera, dtype=np.float64)
    if jitter_translation > 0 or jitter_rotation > 0:
        rng = np.random.default_rng(seed)
        for T in T_cam:
            T[:3, :3] = se3.rotation_about(rng.normal(size=3), rng.normal() * jitter_rotation) @ T[:3, :3]
            T[:3, 3] += rng.normal(size=3) * jitter_translation
    traj = ScanTrajectory(T_cam @ se3.inverse(np.asarray(Tfc)), np.array(Tfc), np.arange(len(T_cam)) / frame_rate)
    if robot is None or (isinstance(robot, str) and robot == "none"):
        if T_base_robot is not None or q_start is not None:
            raise ValueError("T_base_robot and q_start need a robot")
        return traj
    if T_base_robot is None:
        T_base_robot = robot_mount(float(center[0]), float(center[1]), float(center[2]) + DEFAULT_ROBOT_HEIGHT)
    return attach_robot(traj, robot, T_base_robot=T_base_robot, q_start=q_start)


def loop_trajectory(n_frames: int = 36, *, center: Sequence[float] = (0.5, 0.0, 0.0), height: float = 0.40,
                    radius: float = 0.20, start_angle: float = 0.0, sweep: float = 2 * math.pi,
                    target: Optional[Sequence[float]] = None, T_flange_camera: Optional[np.ndarray] = None,
                    frame_rate: float = 10.0, jitter_translation: float = 0.0, jitter_rotation: float = 0.0,
                    seed: int = 0, robot: Any = None, T_base_robot: Optional[np.ndarray] = None,
                    q_start: Optional[Sequence[float]] = None) -> ScanTrajectory:
    """A loop around the object (eye-in-hand paper, Comput. Electron. Agric. 180 (2021) 105929, Fig. 4): camera ``k``
    (``n_frames`` >= 1) sits at ``center + (radius cos a_k, radius sin a_k, height)`` (base frame, m; ``height`` > 0,
    ``radius`` >= 0) with ``a_k = start_angle + sweep k / n_frames`` (rad; a full loop by default, without repeating
    the first pose), looking at ``target`` (default ``center``) with image up towards +z, at time ``k / frame_rate``
    (Hz). Flange poses are ``T_base_camera @ inv(T_flange_camera)`` (default :data:`DEFAULT_T_FLANGE_CAMERA`).

    Args:
        jitter_translation, jitter_rotation: standard deviations (m, rad) of an optional random perturbation of each
            camera pose (the reference includes it), seeded by ``seed``.
        robot: None: no arm; a robot name ("ur5") or :class:`scanalign.kinematics.Robot`: the arm follows the path
            (:func:`attach_robot`), its poses forward kinematics of its joints.
        T_base_robot, q_start: with a robot, its mounting (robot base -> base, m; default :func:`robot_mount` hanging
            ``DEFAULT_ROBOT_HEIGHT`` above ``center``) and the joints (rad) to start from (default: chosen, elbow up).
    """
    c = _array(center, (3,), "center")
    poses = _core.synthetic.loop_camera_poses(n_frames, c, height, radius, start_angle, sweep,
                                              c if target is None else _array(target, (3,), "target"))
    return _planned(poses, T_flange_camera, frame_rate, jitter_translation, jitter_rotation, seed, robot,
                    T_base_robot, q_start, c)


def hemisphere_trajectory(n_frames: int = 48, *, center: Sequence[float] = (0.5, 0.0, 0.0), distance: float = 0.45,
                          elevations: Sequence[float] = (math.radians(35.0), math.radians(55.0), math.radians(75.0)),
                          start_angle: float = 0.0, target: Optional[Sequence[float]] = None,
                          T_flange_camera: Optional[np.ndarray] = None, frame_rate: float = 10.0,
                          jitter_translation: float = 0.0, jitter_rotation: float = 0.0, seed: int = 0,
                          robot: Any = None, T_base_robot: Optional[np.ndarray] = None,
                          q_start: Optional[Sequence[float]] = None) -> ScanTrajectory:
    """Rings at ``distance`` (m) from ``target`` (default ``center``, base frame, m), one per elevation (rad, in
    (0, pi/2]), from azimuth ``start_angle`` (rad).  The ``n_frames`` (>= number of rings) are shared between rings in
    proportion to their circumferences (``cos(elevation)``, at least one each); successive rings run in opposite
    directions, each starting where the previous ended.  Cameras look at the target, image up towards +z (outwards at
    90 deg).  The other arguments are those of :func:`loop_trajectory`."""
    c = _array(center, (3,), "center")
    poses = _core.synthetic.hemisphere_camera_poses(n_frames, c if target is None else _array(target, (3,), "target"),
                                                    distance, np.ravel(elevations), start_angle)
    return _planned(poses, T_flange_camera, frame_rate, jitter_translation, jitter_rotation, seed, robot,
                    T_base_robot, q_start, c)

#: Default height (m) of the scan robot's base above the table top (:func:`robot_mount`).
DEFAULT_ROBOT_HEIGHT: float = 0.90


def robot_mount(x: float = 0.5, y: float = 0.0, z: float = DEFAULT_ROBOT_HEIGHT, roll: float = math.pi,
                pitch: float = 0.0, yaw: float = 0.0) -> np.ndarray:
    """``T_base_robot`` (robot base -> scene base) from a position (m) and roll / pitch / yaw (rad, rotation
    ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``, as URDF).

    The default hangs the arm (first joint axis down) 0.9 m above the default table's centre, as on a gantry: beside
    the table a UR5 (reach 0.85 m) misses the far side of the default hemisphere path and passes its shoulder
    singularity on the near side; from above, both default paths stay in the workspace, clear of singularities."""
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


def attach_robot(trajectory: ScanTrajectory, robot: Any = "ur5", *, T_base_robot: Optional[np.ndarray] = None,
                 q_start: Optional[Sequence[float]] = None, elbow: str = "up") -> ScanTrajectory:
    """A new :class:`ScanTrajectory` (``joints``, ``robot`` placed in the scene with the flange as its tool,
    ``T_base_robot`` set): the planned path moved by ``robot`` (a :class:`scanalign.kinematics.Robot` or a name),
    joints by inverse kinematics, poses by forward kinematics.  The planned flange poses in the robot's base frame,
    ``inv(T_base_robot) @ T_base_flange`` (``T_base_robot``: robot base -> scene base, m; default :func:`robot_mount`
    ``()``), go to :meth:`Robot.ik_trajectory` (each step the solution closest to the previous joints); forward
    kinematics of those joints gives the flange poses (the planned ones to ~1e-15 m).

    The start is ``q_start`` ((6,) rad) if given, else chosen among the first pose's solutions with the requested
    ``elbow`` ("up": away from the table; "down"; "any"), each with its first and last joint shifted by 0, -2 pi and
    +2 pi where the limits allow: the one that reaches every pose with the smallest largest joint step wins (ties
    within 1e-9 rad: the lowest configuration index, then no shift, -2 pi, +2 pi), so no step switches branch.

    ValueError: a pose it cannot reach, or only outside its joint limits (naming the frame, its time and the IK
    status), a bad ``elbow``, ``q_start`` or ``T_base_robot``; TypeError: ``robot`` or ``trajectory`` of wrong type."""
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
        return tr, float(np.abs(np.diff(np.vstack([q0[None], tr.q]), axis=0)).max()) if np.all(tr.ok) else math.inf

    # Robot.ik_trajectory checks q_start (6 finite values, naming q_start).
    best = (run(np.asarray(q_start, dtype=np.float64))[0] if q_start is not None
            else _best_start(model, Tbr, T_robot_flange[0], elbow, run, where))
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
    want = {"up": 1, "down": -1, "any": 0}[elbow] * (1 if z_up else -1)
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

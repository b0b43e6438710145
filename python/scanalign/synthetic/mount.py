"""The robot arm that carries the camera: where it is mounted in the scene, and how it
follows a planned camera path (joints by inverse kinematics, poses by forward kinematics)."""

from __future__ import annotations

import itertools
import math
from typing import Any, Optional, Sequence, Tuple

import numpy as np

from .. import se3
from .trajectories import ScanTrajectory

__all__ = ["DEFAULT_ROBOT_HEIGHT", "robot_mount", "attach_robot"]

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
    from .. import kinematics as kin  # only the robot-driven paths need the kinematics

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

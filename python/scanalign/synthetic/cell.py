"""The built-in pick cell: known parts at known poses on a table, a robot with a camera on its
hand that scans them, and the ground truth a pick is scored against.

Two cells, both with the parts of :data:`scanalign.grasp.parts.BUILTIN_PART_FILES` (the machined block, the angle
bracket and the hexagonal standoff) and the camera at :data:`~scanalign.synthetic.DEFAULT_T_FLANGE_CAMERA`:

* ``"ur5"``: a UR5 hanging 0.75 m above the table centre, as on a gantry; the parts lie
  0.16 m from its first axis, outside the shoulder singularity (wrist within d4 = 0.11 m).
* ``"kr6_r900_sixx"``: a KUKA KR6 R900 sixx standing upright beside the table (its base 0.6 m
  from the table centre, at the table top's height): it cannot fold its arm under its base.

The camera circles the parts 0.35 m above the table (radius 0.2 m): the UR5 all the way
round, the KR6 on a 270 degree arc without the quarter nearest to it (its wrist singularity).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from scanalign.common import rigid as se3
from scanalign.grasp import symmetric_pose_error
from scanalign.grasp.parts import load_part
from scanalign.synthetic.scan import SyntheticScan, render_scan
from scanalign.synthetic.scene import Scene
from scanalign.synthetic.trajectories import loop_trajectory, robot_mount

__all__ = ["CELL_MOUNTS", "CELL_SCAN_ARCS", "DEFAULT_PLACEMENTS", "PickCell", "pick_cell", "score_picks"]

#: Robot name -> its mounting ``T_base_robot`` (robot base -> cell base, m) in the built-in cell.
CELL_MOUNTS: Dict[str, np.ndarray] = {"ur5": robot_mount(0.5, 0.0, 0.75),
                                     "kr6_r900_sixx": robot_mount(-0.1, 0.0, 0.0, roll=0.0)}
#: Robot name -> (start angle, sweep) of its scan loop, rad (see the module docstring).
CELL_SCAN_ARCS: Dict[str, Tuple[float, float]] = {"ur5": (0.0, 2 * math.pi),
                                                  "kr6_r900_sixx": (1.25 * math.pi, 1.5 * math.pi)}
#: (part name, (x, y) on the table in m, yaw in rad) of the built-in cell's parts.
DEFAULT_PLACEMENTS: Tuple[Tuple[str, Tuple[float, float], float], ...] = (
    ("block", (0.36, -0.07), 0.3), ("bracket", (0.60, 0.12), 1.3), ("standoff", (0.58, -0.14), 0.5))


@dataclass
class PickCell:
    """A rendered cell with its truth.

    Attributes:
        scan: the robot's scan (frames with joints, flange poses, the hand-eye transform).
        parts: one :class:`scanalign.grasp.PartGrasps` (mesh, grasps, symmetry) per placed part.
        truth: part name (``PartGrasps.name``, as in the picks) -> true ``T_base_model`` (model -> base, m).
        robot: the arm, placed in the cell (``robot.T_base_dh0`` includes the mount), its tool the flange.
        scene: the rendered :class:`Scene` (table and parts, base frame, m).
    """

    scan: SyntheticScan
    parts: List[Any]
    truth: Dict[str, np.ndarray]
    robot: Any
    scene: Scene


def pick_cell(robot: str = "ur5", noise: str = "sr300", *, seed: int = 0, n_frames: int = 24,
              placements: Optional[Sequence[Tuple[str, Tuple[float, float], float]]] = None) -> PickCell:
    """Renders the built-in cell (see the module docstring) of ``robot``, ``"ur5"`` or ``"kr6_r900_sixx"`` (the keys
    of :data:`CELL_MOUNTS`), with a sensor ``noise`` preset (``"sr300"``, ``"zivid"``, ``"d435"``, ``"none"``) and its
    ``seed``, and ``placements`` (part, (x, y) m, yaw rad) per part (default :data:`DEFAULT_PLACEMENTS`): the part as
    :func:`scanalign.grasp.parts.load_part` takes it (a part file, a built-in name or a ``PartGrasps``), standing on
    the table (model +z up, its lowest point on the table top), the centre of its bounding box at (x, y) in the base
    frame, turned by yaw about the vertical. ValueError for two parts of one name (truth is keyed by part name)."""
    if robot not in CELL_MOUNTS:
        raise ValueError(f"robot: the built-in cells are {sorted(CELL_MOUNTS)}, got {robot!r}")
    scene = Scene(table_size=(0.6, 0.6))
    placed = [(load_part(source), xy, yaw) for source, xy, yaw in placements or DEFAULT_PLACEMENTS]
    if len(names := [part.name for part, _, _ in placed]) != len(set(names)):
        raise ValueError(f"placements: each part once (the truth is keyed by part name), got the parts {names}")
    truth = {part.name: np.array(scene.add_object(part.mesh, position=xy, yaw=yaw, name=part.name).T_base_object)
             for part, xy, yaw in placed}
    start, sweep = CELL_SCAN_ARCS[robot]
    traj = loop_trajectory(n_frames, center=(0.5, 0.0, 0.0), height=0.35, radius=0.2, robot=robot,
                           T_base_robot=CELL_MOUNTS[robot], start_angle=start, sweep=sweep)
    scan = render_scan(scene, traj, "sr300", noise=noise, seed=seed)
    return PickCell(scan, [p[0] for p in placed], truth, scan.robot, scene)


def score_picks(result: Any, truth: Dict[str, np.ndarray]) -> Dict[str, Dict[str, float]]:
    """Errors of a :class:`scanalign.pipelines.pick.PickResult` against the cell's truth, per picked part: ``tcp_m`` /
    ``tcp_deg``, the TCP pose at the chosen grasp against the same grasp on the truly placed part (the nearest of its
    symmetric copies), and ``pose_m`` / ``pose_deg``, the part's pose error (up to its symmetry). ``truth`` is keyed by
    part name (:attr:`PickCell.truth`); a truth entry for a part the pick did not know, or a picked part without
    one, is a ValueError (so a mismatch never scores as nothing picked)."""
    out = {}
    parts = {p.name: p for p in result.parts}
    if unknown := sorted(set(truth) - set(parts)):
        raise ValueError(f"truth: {unknown} name no part of the pick ({sorted(parts)}): key the truth by part name "
                         "(PartGrasps.name), as PickCell.truth is")
    for p in result.picks:
        if p.status != "picked":
            continue
        if p.part not in truth:
            raise ValueError(f"truth: part {p.part!r} was picked but has no true pose (truth holds {sorted(truth)})")
        part, c = parts[p.part], p.chosen
        G = np.asarray(part.grasps[c.grasp_index].T_model_grasp)
        tcp = min((se3.pose_error(np.asarray(c.T_base_tcp_grasp), truth[p.part] @ np.asarray(S) @ G)
                   for S in part.symmetry.transforms()), key=lambda e: (e[0], e[1]))
        rot, dist = symmetric_pose_error(p.T_base_model, truth[p.part], part.symmetry)
        out[p.part] = {"tcp_m": float(tcp[1]), "tcp_deg": math.degrees(float(tcp[0])), "pose_m": dist,
                       "pose_deg": math.degrees(rot)}
    return out

"""From scan to grasp to joint targets: reconstruction, part pose and inverse kinematics
joined (the eye-in-hand paper, Comput. Electron. Agric. 180 (2021) 105929, Algorithm 1, and
Kleppe, PhD thesis, NTNU 2018, ch. 6-7 and Paper 1). :func:`pick` runs the stages in order:

1. :func:`scan_model`: the scene in the robot's base frame (frames placed at
   ``T_base_camera = FK(q) T_flange_camera``, reconstructed), or an existing cloud;
2. :func:`scanalign.pose.find_parts`: table, clusters and each known part's ``T_base_model``;
3. :func:`plan_picks`: per found part, every grasp, symmetric copy and IK branch, rejected with
   a reason or ranked by joint motion (:func:`scanalign.grasp.plan_grasp`).

Frames (``T_a_b`` maps b-coordinates into a; metres, radians)::

    base --T_base_flange(q)--> flange --T_flange_camera--> camera      (scan)
    base --T_base_model--> model --T_model_grasp--> tcp                 (part, grasp)
    flange --T_flange_tcp--> tcp                                        (gripper)
    so the flange target is T_base_flange = T_base_model T_model_grasp inv(T_flange_tcp).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import sys
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Union

import numpy as np

from scanalign import _core, datasets, io, pose
from scanalign import grasp as _grasp
from scanalign.common import rigid as se3
from scanalign.common.arrays import as_points, foreign_kind
from scanalign.common.settings import is_struct, with_overrides
from scanalign.grasp.parts import load_part
from scanalign.kinematics import Robot
from scanalign.pipelines import reconstruct as pipeline
from scanalign.pose import model_views as cad

__all__ = ["PickSettings", "PartPick", "PickResult", "pick", "scan_model", "plan_picks", "read_joint_log", "table_plane",
           "read_transform", "part_models", "upper_views", "placed_parts", "print_picks"]

#: Settings of :func:`pick` (``scanalign dump-config pick`` lists every field): ``reconstruction``,
#: ``find_parts``, ``views`` (``"upper"`` or ``"all"``) and ``planner``.
PickSettings = _core.grasp.PickSettings


@dataclass
class PartPick:
    """The outcome for one detected part (or one known part not found).

    Attributes:
        part: the part's name; cluster: index of its object cluster (-1: not found).
        status: ``"picked"`` (joint targets below), ``"no_grasp"`` (found, but every grasp
            candidate was rejected: see ``plan.candidates``), ``"ambiguous"`` (two poses or
            parts scored alike: not picked), ``"not_found"`` (the part is not in the scene).
        message: why, in words.
        T_base_model: (4, 4) the part's pose (model -> base), or None.
        fitness, coverage: the pose's scores.
        plan: the :class:`scanalign.grasp.GraspPlanResult` (every candidate with its reason).
        gripper: the :class:`scanalign.grasp.Gripper` the plan used (its ``T_flange_tcp`` the tool).
    """

    part: str
    status: str
    message: str = ""
    cluster: int = -1
    T_base_model: Optional[np.ndarray] = None
    fitness: float = 0.0
    coverage: float = 0.0
    plan: Any = None
    grasp_names: List[str] = field(default_factory=list)
    gripper: Any = None

    @property
    def chosen(self) -> Any:
        """The chosen grasp candidate, or None."""
        return self.plan.candidates[self.plan.chosen] if self.status == "picked" else None

    def as_dict(self) -> Dict[str, Any]:
        d: Dict[str, Any] = {"part": self.part, "status": self.status, "message": self.message,
                             "cluster": self.cluster, "fitness": self.fitness, "coverage": self.coverage,
                             "T_base_model": None if self.T_base_model is None else self.T_base_model.tolist()}
        if self.plan is not None:
            d["candidates"] = [self._candidate(c) for c in self.plan.candidates]
            d["rejected"] = [c for c in d["candidates"] if c["reason"] != "ok"]
        if self.status == "picked":
            d["chosen"] = self._candidate(self.chosen)
        return d

    def _candidate(self, c: Any) -> Dict[str, Any]:
        ok = c.reason == "ok"
        return {"grasp": self.grasp_names[c.grasp_index], "grasp_index": c.grasp_index,
                "symmetry_index": c.symmetry_index, "ik_config": c.config_index, "reason": c.reason,
                "detail": c.detail, "cost": float(c.cost) if ok else None,
                "q_pregrasp": [float(v) for v in c.q_pregrasp] if np.all(np.isfinite(c.q_pregrasp)) else None,
                "q_grasp": [float(v) for v in c.q_grasp] if ok else None,
                **{k: np.asarray(getattr(c, k)).tolist() for k in ("T_base_tcp_pregrasp", "T_base_tcp_grasp",
                                                                  "T_base_flange_pregrasp", "T_base_flange_grasp")}}


@dataclass
class PickResult:
    """Outcome of :func:`pick`.

    Attributes:
        picks: one :class:`PartPick` per detected part, then one per known part not found.
        points: (N, 3) the scene in the base frame, metres.
        detections: the :func:`scanalign.pose.find_parts` result (table plane, clusters).
        robot: the picking robot, placed in the base frame, its tool the flange (DH frame 6): ``robot.fk(q)``
            is ``T_base_flange``; the TCP's pose is :meth:`tcp_robot` ``(pick).fk(q)``.
        q_current: (6,) the joints the motion cost was measured from, rad.
        parts: the parts as loaded, in the order given.
        seconds: wall time per stage (``scan``, ``detect``, ``plan``, ``total``).
        reconstruction: the :class:`ReconstructionResult` when frames were reconstructed.
    """

    picks: List[PartPick]
    points: np.ndarray
    detections: Any
    robot: Any
    q_current: np.ndarray
    parts: List[Any]
    seconds: Dict[str, float] = field(default_factory=dict)
    reconstruction: Any = None

    def tcp_robot(self, pick: PartPick) -> Any:
        """:attr:`robot` with the tool of the gripper that ``pick`` was planned with: its ``fk(q)`` is
        ``T_base_tcp`` (e.g. ``fk(pick.chosen.q_grasp)`` equals ``pick.chosen.T_base_tcp_grasp``)."""
        if pick.gripper is None:
            raise ValueError(f"pick of {pick.part!r} ({pick.status}) was not planned: it has no gripper")
        return self.robot.with_tool(np.asarray(pick.gripper.T_flange_tcp))

    def as_dict(self) -> Dict[str, Any]:
        return {"robot": self.robot.name, "q_current": self.q_current.tolist(), "seconds": self.seconds,
                "table_plane": [float(v) for v in table_plane(self.detections)],
                "picks": [p.as_dict() for p in self.picks],
                "unmatched_clusters": [{"cluster": d.cluster, "points": len(d.indices), "size_m": d.size,
                                        "message": d.message}
                                       for d in self.detections.detections if d.status.name == "not_found"]}

    def save(self, out_dir: Union[str, Path]) -> Dict[str, Path]:
        """Writes ``picks.json`` (every part, its pose, chosen grasp, joint targets and rejected
        candidates with their reasons), ``joints.csv`` (each chosen approach's joint path, rad)
        and ``scene.ply`` (the scene, each placed part coloured); returns their paths."""
        (out := Path(out_dir)).mkdir(parents=True, exist_ok=True)
        paths = {"picks": out / "picks.json", "joints": out / "joints.csv", "scene": out / "scene.ply"}
        with io.atomic_open(paths["picks"], "w", encoding="utf-8") as f:
            json.dump(self.as_dict(), f, indent=1)
        with io.atomic_open(paths["joints"], "w", newline="", encoding="utf-8") as f:
            csv.writer(f).writerows([["part", "step", "q1", "q2", "q3", "q4", "q5", "q6"]] + [
                [p.part, k] + [repr(float(v)) for v in q]
                for p in self.picks if p.status == "picked" for k, q in enumerate(p.plan.approach_q)])
        # the scene (grey) and every posed part's surface (one colour per pick)
        palette = np.array([[31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40], [148, 103, 189]], np.uint8)
        placed = placed_parts(self)
        io.write_ply(paths["scene"], np.vstack([self.points] + [v for _, v in placed]).astype(np.float32),
                     colors=np.vstack([np.full((len(self.points), 3), 150, np.uint8)]
                                      + [np.tile(palette[k % len(palette)], (len(v), 1)) for k, v in placed]))
        return paths


def read_joint_log(path: Union[str, Path]) -> Dict[float, np.ndarray]:
    """A joint log as ``scanalign synth`` writes it (``index,timestamp,q1,...,q6``, seconds and
    radians): {timestamp: (6,) joints}. Raises ValueError naming the file and line."""
    out: Dict[float, np.ndarray] = {}
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    if not rows or [c.strip() for c in rows[0][1:8]] != ["timestamp", "q1", "q2", "q3", "q4", "q5", "q6"]:
        raise ValueError(f"{path}: expected the header index,timestamp,q1,...,q6")
    for n, row in enumerate(rows[1:], start=2):
        try:
            t, q = float(row[1]), np.array([float(v) for v in row[2:8]])
        except (ValueError, IndexError):
            raise ValueError(f"{path}, line {n}: expected a timestamp and six joint values (rad)") from None
        if q.shape != (6,) or not np.all(np.isfinite(q)) or not math.isfinite(t):
            raise ValueError(f"{path}, line {n}: non-finite or missing joint values")
        out[t] = q
    return out


def read_transform(path: Optional[Union[str, Path]], what: str, rigid: bool = True) -> Optional[np.ndarray]:
    """A 4x4 matrix from a text file, checked to be rigid unless ``rigid`` is False (None
    for no path); ValueError naming ``what`` and the file otherwise."""
    if path is None:
        return None
    try:
        m = np.loadtxt(path, ndmin=2)
        return se3.require_rigid(m, what) if rigid else m.reshape(4, 4)
    except (OSError, ValueError) as e:
        kind = "rigid 4x4" if rigid else "4x4"
        raise ValueError(f"{what} {path}: expected a text file holding a {kind} matrix ({e})") from None


def _robot(robot: Any, T_base_robot: Optional[np.ndarray]) -> Any:
    r = Robot.by_name(robot) if isinstance(robot, str) else robot
    if not isinstance(r, Robot):
        raise TypeError(f"robot: expected a scanalign.kinematics.Robot or a robot name, got {type(robot)!r}")
    if T_base_robot is not None:
        r = r.with_base(se3.require_rigid(T_base_robot, "T_base_robot") @ r.T_base_dh0)
    return r


def _frames_with_robot_poses(frames: Sequence[Any], robot: Any, T_flange_camera: np.ndarray,
                             joints: Optional[Dict[float, np.ndarray]]) -> List[Any]:
    """Each frame's ``T_base_camera`` from the robot: FK of its joints (``meta["joints"]`` or
    the joint log at its timestamp, within 1 ms) and the hand-eye transform."""
    flange = robot.with_tool(np.eye(4))
    stamps = np.array(sorted(joints)) if joints else np.zeros(0)
    out = []
    for f in frames:
        q = (getattr(f, "meta", None) or {}).get("joints")
        if q is None and stamps.size:
            k = int(np.argmin(np.abs(stamps - f.timestamp)))
            q = joints[stamps[k]] if abs(stamps[k] - f.timestamp) <= 1e-3 else None
        if q is None:
            raise ValueError(f"frame {f.index} (t = {f.timestamp:.6f} s) has no robot joints: the pick pipeline "
                             "places every frame by the robot's forward kinematics (give a joint log)")
        out.append(dataclasses.replace(f, T_base_camera=flange.fk(np.asarray(q, dtype=np.float64)) @ T_flange_camera))
    return out


def scan_model(scene: Any, robot: Any = None, *, T_flange_camera: Optional[np.ndarray] = None,
               joints: Optional[Union[str, Path]] = None, settings: Optional[PickSettings] = None,
               progress: bool = True, on_frame: Any = None) -> tuple:
    """The scene in the robot's base frame, metres: ``(points (N, 3), reconstruction or None)``.

    ``scene`` is a :class:`scanalign.synthetic.SyntheticScan` (its robot and hand-eye transform are used unless given),
    a list of :class:`scanalign.reconstruction.camera.Frame` or a recording :func:`scanalign.datasets.open_source` reads
    (with ``joints``, a joint log, unless the frames carry their joints), a :class:`ReconstructionResult` built in the
    base frame, or a PLY / PCD file, (N, 3) array, Open3D or trimesh cloud in the base frame. ``on_frame``: the
    per-frame hook of :func:`scanalign.pipelines.reconstruct.reconstruct`."""
    s = with_overrides(PickSettings, settings, (), "pick")
    if isinstance(scene, pipeline.ReconstructionResult):
        return np.asarray(scene.model.points, dtype=np.float64), scene
    if isinstance(scene, (str, Path)) and not datasets.is_recording(scene):
        return io.read_cloud(scene)[0].astype(np.float64), None
    if isinstance(scene, np.ndarray) or foreign_kind(scene) == "cloud":
        return as_points(scene, "scene", np.dtype(np.float64)), None
    # a recording (a TUM folder, a ROS bag or an image folder), a synthetic scan or frames
    frames = datasets.open_source(scene) if isinstance(scene, (str, Path)) else getattr(scene, "frames", scene)
    T_flange_camera = getattr(scene, "T_flange_camera", None) if T_flange_camera is None else T_flange_camera
    if T_flange_camera is None:
        raise ValueError("T_flange_camera (camera -> flange, the hand-eye calibration) is needed to place the frames")
    if robot is None:
        raise ValueError("robot: the arm that moved the camera is needed to place the frames")
    log = read_joint_log(joints) if joints is not None else None
    placed = _frames_with_robot_poses(list(frames), robot, se3.require_rigid(T_flange_camera, "T_flange_camera"), log)
    rec = pipeline.reconstruct(placed, s.reconstruction, progress=progress, on_frame=on_frame)
    return np.asarray(rec.model.points, dtype=np.float64), rec


def table_plane(detections: Any) -> np.ndarray:
    """(n, d) of the table plane n.p + d = 0 in the base frame, n pointing up (+z)."""
    plane = detections.table.plane  # n.p = distance
    n, d = np.asarray(plane.normal, dtype=np.float64), -float(plane.distance)
    if n[2] < 0:
        n, d = -n, -d
    return np.append(n, d)


def plan_picks(detections: Any, parts: Sequence[Any], robot: Any, *, gripper: Any = None,
               q_current: Optional[Sequence[float]] = None, planner: Any = None,
               points: Optional[np.ndarray] = None) -> List[PartPick]:
    """A :class:`PartPick` per detection of :func:`scanalign.pose.find_parts` (base frame), the top-most first (the
    highest of its points in ``points``, the scene the detections index, above the table; without ``points``, the
    height of its pose), then a ``not_found`` one per part no cluster matched. ``q_current`` (rad) defaults to
    zeros; ``planner``: a ``GraspPlannerSettings`` or a dict of its fields."""
    planner = planner if planner is None or is_struct(planner) else with_overrides(
        _grasp.GraspPlannerSettings, None, planner, "planner")
    q0 = np.zeros(6) if q_current is None else np.asarray(q_current, dtype=np.float64)
    plane = table_plane(detections)
    out: List[PartPick] = []
    found = [d for d in detections.detections if d.status.name != "not_found"]  # the rest: picks.json's clusters
    for det in sorted(found, key=lambda d: -_top_height(d, plane, points)):
        part = parts[det.part]
        pp = PartPick(part.name, det.status.name, det.message, cluster=det.cluster,
                      T_base_model=np.array(det.pose.T_scene_model), fitness=det.pose.fitness,
                      coverage=det.pose.coverage, grasp_names=[g.name for g in part.grasps])
        if det.status.name == "found":
            pp.gripper = gripper or part.gripper
            pp.plan = _grasp.plan_grasp(robot, pp.T_base_model, part.grasps, symmetry=part.symmetry,
                                        gripper=pp.gripper, table_plane=plane, q_current=q0, settings=planner)
            pp.status, pp.message = ("picked", "") if pp.plan.found else ("no_grasp", pp.plan.message)
        out.append(pp)
    seen = {parts[d.part].name for d in found}
    out += [PartPick(p.name, "not_found", "no object cluster matched this part") for p in parts if p.name not in seen]
    return out


def _top_height(det: Any, plane: np.ndarray, points: Optional[np.ndarray]) -> float:
    """How high a detection reaches above the table (m): its highest point, or its pose's origin."""
    n, d = plane[:3], plane[3]  # n.p + d = 0, n up
    if points is not None and len(det.indices):
        return float((points[det.indices] @ n).max() + d)
    return float(np.asarray(det.pose.T_scene_model)[:3, 3] @ n + d)


def upper_views() -> List[int]:
    """The tessellated-sphere views seen from above (``PickSettings.views == "upper"``)."""
    directions, _ = cad.tessellated_sphere(1)
    return [i for i, d in enumerate(directions) if d[2] > 0]


def part_models(parts: Sequence[Any], library: Any = None) -> List[Any]:
    """What :func:`scanalign.pose.find_parts` matches per part: its described views from ``library`` (a
    :class:`scanalign.grasp.part_library.PartLibrary`) when it holds them, else its mesh."""
    return [library[p.name].views if library is not None and p.name in library else p.mesh for p in parts]


def pick(scene: Any, parts: Sequence[Any], robot: Any = None, *, T_base_robot: Optional[np.ndarray] = None,
         T_flange_camera: Optional[np.ndarray] = None, joints: Optional[Union[str, Path]] = None, gripper: Any = None,
         q_current: Optional[Sequence[float]] = None, settings: Optional[PickSettings] = None,
         progress: bool = True, library: Any = None, viewer: Any = None, **overrides: Any) -> PickResult:
    """Scan, find every known part, and plan the joint targets to pick each one.

    Args:
        scene: what :func:`scan_model` takes.
        parts: part files (JSON / YAML: mesh, grasps, symmetry), built-in part names ("block",
            "bracket", "standoff") or :class:`scanalign.grasp.PartGrasps`.
        robot: a :class:`scanalign.kinematics.Robot` or a name; default the synthetic scan's.
        T_base_robot: (4, 4) where the robot's own base sits in the base frame (robot base ->
            base, m); default the robot as given (or the synthetic scan's mount).
        T_flange_camera: (4, 4) the hand-eye calibration (camera -> flange, m); default the
            synthetic scan's (see :func:`scanalign.calibration.calibrate_hand_eye`).
        joints: a joint log for a TUM folder (:func:`read_joint_log`).
        gripper: a :class:`scanalign.grasp.Gripper` (default each part file's).
        q_current: (6,) the robot's joints now, rad (default the scan's last joints, else 0).
        settings: :data:`PickSettings` (default its C++ defaults); keyword ``overrides`` name
            its fields, nested as dicts (``find_parts={"max_objects": 3}``, ``views="all"``).
        library: a :class:`scanalign.grasp.part_library.PartLibrary` whose views replace rendering.
        viewer: a :class:`scanalign.viz.viewer.Viewer`: the scan streamed while it is
            reconstructed (drawn with the picking robot unless the viewer has one), then the result.

    Raises:
        ValueError: an empty scene or part list, a part larger than the robot's workspace,
            a malformed part file, frames without joints, a non-rigid transform.
        TypeError: an unknown robot type.
    """
    s = with_overrides(PickSettings, settings, overrides, "pick")
    t0 = time.perf_counter()
    if isinstance(parts, (str, Path)) or not parts:
        raise ValueError("parts: give a list of at least one part (a part file, a built-in part name or a PartGrasps)")
    part_list = [load_part(p) for p in parts]
    robot = getattr(scene, "robot", None) if robot is None else robot
    if robot is None:
        raise ValueError("robot: give the picking robot (a Robot or a name such as 'ur5')")
    arm = _robot(robot, T_base_robot).with_tool(np.eye(4))  # the flange: the planner puts each gripper's TCP on it
    reach = float(np.sum(np.abs(arm.a)) + np.sum(np.abs(arm.d)))
    for p in part_list:
        size = float(np.ptp(cad.surface_points(p.mesh, 5000), axis=0).max())
        if size > reach:
            raise ValueError(f"part {p.name!r} is {size:.3f} m across, larger than the {arm.name}'s workspace "
                             f"(sum of its link lengths {reach:.3f} m): check the part's scale (metres)")
    if viewer is not None and viewer.robot is None:
        viewer.robot = arm
    points, rec = scan_model(scene, arm, T_flange_camera=T_flange_camera, joints=joints, settings=s, progress=progress,
                             on_frame=None if viewer is None else viewer.on_frame)
    if len(points) == 0:
        raise ValueError("the scene has no points")
    t1 = time.perf_counter()
    detections = pose.find_parts(part_models(part_list, library), points, s.find_parts,
                                 symmetries=[p.symmetry for p in part_list],
                                 views=upper_views() if s.views == "upper" else None, progress=progress)
    t2 = time.perf_counter()
    if q_current is None:
        q_last = getattr(scene, "joints", None)
        q_current = q_last[-1] if q_last is not None and len(q_last) else np.zeros(6)
    picks = plan_picks(detections, part_list, arm, gripper=gripper, q_current=q_current, planner=s.planner,
                       points=points)
    t3 = time.perf_counter()
    result = PickResult(picks, points, detections, arm, np.asarray(q_current, dtype=np.float64), part_list,
                        {"scan": t1 - t0, "detect": t2 - t1, "plan": t3 - t2, "total": t3 - t0}, rec)
    if viewer is not None:
        viewer.log_pick(result)
    return result


def placed_parts(result: PickResult, samples: int = 5000) -> List[tuple]:
    """(pick index, (samples, 3) points of the part's surface at its found pose, base frame, m)
    for every part with a pose."""
    meshes = {p.name: p.mesh for p in result.parts}
    return [(k, se3.transform_points(p.T_base_model, cad.surface_points(meshes[p.part], samples)))
            for k, p in enumerate(result.picks) if p.T_base_model is not None]


def print_picks(result: PickResult, file: Any = sys.stdout) -> None:
    """One line per part: status, pose scores, chosen grasp and joint targets, rejections."""
    for p in result.picks:
        line = f"{p.part:<10} {p.status:<10}"
        if p.T_base_model is not None:
            t = p.T_base_model[:3, 3]
            line += f" at ({t[0]:.4f}, {t[1]:.4f}, {t[2]:.4f}) m, fitness {p.fitness:.2f} coverage {p.coverage:.2f}"
        print(line, file=file)
        if p.status == "picked":
            c = p.chosen
            print(f"{'':11}grasp {p.grasp_names[c.grasp_index]!r}, IK configuration {c.config_index}, q_grasp = "
                  + " ".join(f"{v:+.4f}" for v in c.q_grasp) + " rad", file=file)
        elif p.message:
            print(f"{'':11}{p.message}", file=file)
        if p.plan is not None:
            reasons = Counter(c.reason for c in p.plan.candidates)
            print(f"{'':11}candidates: " + ", ".join(f"{n} {r}" for r, n in sorted(reasons.items())), file=file)
    print(" ".join(f"{k} {v:.2f} s" for k, v in result.seconds.items()), file=file)

"""Assembly with the two-step pose (Kleppe et al., "Automated assembly using 3D and 2D cameras", Robotics 6 (2017) 14,
the thesis's Paper 3): find both parts in a fixed 3D camera's cloud (rough, §3.2), refine each with a hand camera on a
second arm (the 2D step, §3.3: :func:`scanalign.pipelines.refine2d.refine_2d`), then plan the gripper arm's pick of
part A and its place onto part B at the relative pose of A's part file (``assembly``; §4.3).

:func:`assemble` runs the stages:

1. :func:`scanalign.pose.find_parts` on the cloud; each part takes the cluster where its pose scores best (one part
   per cluster), so the 2D step verifies an identification that the single noisy view leaves uncertain;
2. the rough pose made upright on the table plane (yaw from the 3D pose, the part's lowest point on the table);
3. :func:`refine_2d` of each part (its ``reference_image``) with the camera arm;
4. :func:`scanalign.grasp.plan_grasp` of A at its refined pose with the gripper arm, then of the place: the same grasp
   with A at ``T_base_B @ assembly.T_onto_part`` (every IK branch judged, the branch nearest the grasp's joints).

Frames (``T_a_b`` maps b into a; metres, radians): one cell ``base`` for both arms and the 3D camera; the arms carry
their mounting in ``Robot.T_base_dh0``. With A held at ``T_tcp_A`` (fixed by the grasp), the placed part lies at
``T_base_tcp_place @ T_tcp_A``.
"""

from __future__ import annotations

import itertools
import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Dict, List, Optional, Sequence, Union

import numpy as np

from scanalign import _core, pose
from scanalign import grasp as _grasp
from scanalign.common.arrays import as_points, as_transform
from scanalign.common.settings import with_overrides
from scanalign.grasp.parts import load_part
from scanalign.pipelines.pick import table_plane, upper_views
from scanalign.pipelines.refine2d import Refine2dResult, refine_2d

__all__ = ["AssemblySettings", "PartPose", "AssemblyResult", "PickAndPlace", "assemble", "assemble_cell",
           "plan_pick_and_place", "upright_on_table"]

#: Settings of :func:`assemble` (``scanalign dump-config assemble`` lists every field): ``find_parts``, ``views``,
#: ``refine_2d``, ``view`` and ``planner``.
AssemblySettings = _core.grasp.AssemblySettings

#: KR6 R900 sixx home joints (rad): the flange 0.525 m out, 0.89 m up, clear of the table.
KR6_HOME = np.array([0.0, -np.pi / 2, np.pi / 2, 0.0, 0.0, 0.0])


@dataclass
class PartPose:
    """One part's poses through the two steps (base frame, m).

    ``status``: ``"refined"`` (the 2D step converged), ``"not_found"`` (no cluster fits it), ``"no_reference_image"``
    (its part file has none), or the 2D step's status (``refine.status``: "too_few_matches", "non_rigid",
    "unreachable", ...); unless refined, ``T_base_model`` is None."""

    part: str
    status: str
    reason: str = ""
    cluster: int = -1  #: its cluster in the detections
    score: float = 0.0  #: the 3D pose's score there (harmonic mean of fitness and coverage)
    T_base_model_3d: Optional[np.ndarray] = None  #: the 3D step's pose as found
    T_base_model_rough: Optional[np.ndarray] = None  #: upright on the table: where the 2D step starts
    refine: Optional[Refine2dResult] = None
    T_base_model: Optional[np.ndarray] = None  #: refined (None unless ``status == "refined"``)


@dataclass
class AssemblyResult:
    """``status``: ``"planned"`` (joint targets for both arms below), ``"not_found"``, ``"refine_failed"`` (a part's
    2D step gave no pose: see ``parts``), ``"no_grasp"`` or ``"no_place"`` (every candidate rejected: see ``pick`` /
    ``place``); ``reason`` says which part and why."""

    status: str
    reason: str
    parts: Dict[str, PartPose]
    part: str  #: A, the part placed
    onto: str  #: B
    T_base_target: Optional[np.ndarray] = None  #: where A goes: T_base_B @ T_onto_part (m)
    pick: Any = None  #: :class:`scanalign.grasp.GraspPlanResult` of A
    place: Any = None  #: of the place
    detections: Any = None  #: :class:`scanalign.pose.FindPartsResult`
    q_camera: List[np.ndarray] = field(default_factory=list)  #: the camera arm's joints per view (rad)
    seconds: Dict[str, float] = field(default_factory=dict)

    def __bool__(self) -> bool:
        return self.status == "planned"

    @property
    def q_gripper(self) -> Dict[str, np.ndarray]:
        """The gripper arm's joint targets (rad): pre_grasp, grasp, pre_place, place (empty unless planned)."""
        if self.status != "planned":
            return {}
        g, p = self.pick.candidates[self.pick.chosen], self.place.candidates[self.place.chosen]
        return {"pre_grasp": np.asarray(g.q_pregrasp), "grasp": np.asarray(g.q_grasp),
                "pre_place": np.asarray(p.q_pregrasp), "place": np.asarray(p.q_grasp)}

    @property
    def T_base_tcp_grasp(self) -> Optional[np.ndarray]:
        return None if self.pick is None or not self.pick.found else np.asarray(
            self.pick.candidates[self.pick.chosen].T_base_tcp_grasp)

    @property
    def T_base_tcp_place(self) -> Optional[np.ndarray]:
        return None if self.place is None or not self.place.found else np.asarray(
            self.place.candidates[self.place.chosen].T_base_tcp_grasp)

    def as_dict(self) -> Dict[str, Any]:
        def mat(T: Any) -> Any:
            return None if T is None else np.asarray(T, dtype=np.float64).tolist()

        parts = {n: {"status": p.status, "reason": p.reason, "cluster": p.cluster, "score": p.score,
                     "T_base_model_3d": mat(p.T_base_model_3d), "T_base_model_rough": mat(p.T_base_model_rough),
                     "T_base_model": mat(p.T_base_model),
                     "views": [] if p.refine is None else [
                         {"status": v.step.status, "inliers": v.step.match.inliers, "T_base_camera": mat(v.T_base_camera),
                          "q": None if v.q is None else v.q.tolist(), "correction_m": v.correction_m,
                          "correction_rad": v.correction_rad} for v in p.refine.views]}
                 for n, p in self.parts.items()}
        return {"status": self.status, "reason": self.reason, "part": self.part, "onto": self.onto, "parts": parts,
                "T_base_target": mat(self.T_base_target), "T_base_tcp_grasp": mat(self.T_base_tcp_grasp),
                "T_base_tcp_place": mat(self.T_base_tcp_place),
                "q_gripper": {k: v.tolist() for k, v in self.q_gripper.items()},
                "q_camera": [np.asarray(q).tolist() for q in self.q_camera], "seconds": self.seconds}

    def save(self, out_dir: Union[str, Path]) -> Dict[str, Path]:
        """``assembly.json`` (everything), ``joints_gripper.csv`` and ``joints_camera.csv`` (one target per row,
        rad) in ``out_dir``."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        paths = {"result": out / "assembly.json", "gripper": out / "joints_gripper.csv",
                 "camera": out / "joints_camera.csv"}
        paths["result"].write_text(json.dumps(self.as_dict(), indent=1) + "\n")
        header = "target," + ",".join(f"q{i + 1}_rad" for i in range(6))
        rows = [f"{k}," + ",".join(f"{v:.9f}" for v in q) for k, q in self.q_gripper.items()]
        paths["gripper"].write_text("\n".join([header] + rows) + "\n")
        rows = [f"view_{k + 1}," + ",".join(f"{v:.9f}" for v in q) for k, q in enumerate(self.q_camera)]
        paths["camera"].write_text("\n".join([header] + rows) + "\n")
        return paths


def upright_on_table(T_base_model: Any, mesh: Any, table_plane: Sequence[float]) -> np.ndarray:
    """The part at ``T_base_model`` (4x4, m) set upright on ``table_plane`` ((nx, ny, nz, d), n.p + d = 0, normal up,
    base frame): its yaw kept (the model x axis projected on the table), its model z along base z, its lowest mesh
    point (model frame) on the plane below its origin."""
    T = as_transform(T_base_model, "T_base_model")
    plane = np.asarray(table_plane, dtype=np.float64) if not isinstance(table_plane, str) else np.zeros(0)
    if plane.shape != (4,) or not np.isfinite(plane).all() or not 0.99 < np.linalg.norm(plane[:3]) < 1.01:
        raise ValueError(f"table_plane: expected (nx, ny, nz, d) with a unit normal, got {table_plane!r}")
    n, d = plane[:3], float(plane[3])
    if abs(n[2]) < 0.5:
        raise ValueError(f"table_plane: its normal {n.round(3).tolist()} is not near the base frame's +z")
    yaw = float(np.arctan2(T[1, 0], T[0, 0])) if np.hypot(T[0, 0], T[1, 0]) > 1e-6 else 0.0
    x, y = T[0, 3], T[1, 3]
    z_table = -(n[0] * x + n[1] * y + d) / n[2]
    out = np.eye(4)
    out[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
    out[:3, 3] = [x, y, z_table - float(np.asarray(mesh.vertices)[:, 2].min())]
    return out


def _score(r: Any) -> float:
    f, c = float(r.fitness), float(r.coverage)
    return 0.0 if f + c <= 0 else 2 * f * c / (f + c)


def _assign(detections: Any, n_parts: int) -> List[int]:
    """The cluster of each part: the one-to-one assignment with the highest total score (-1: no cluster left)."""
    scores = np.array([[_score(d.parts[k]) for k in range(n_parts)] for d in detections.detections])
    if len(scores) == 0:
        return [-1] * n_parts
    clusters = list(range(len(scores))) + [-1] * n_parts
    best = max(itertools.permutations(clusters, n_parts),
               key=lambda c: sum(scores[i, k] for k, i in enumerate(c) if i >= 0))
    return [i if i >= 0 and scores[i, k] > 0 else -1 for k, i in enumerate(best)]


def _detect(cloud: np.ndarray, parts: Sequence[Any], s: Any, progress: bool) -> tuple:
    detections = pose.find_parts([p.mesh for p in parts], cloud, s.find_parts,
                                 symmetries=[p.symmetry for p in parts],
                                 views=upper_views() if s.views == "upper" else None, progress=progress)
    plane = table_plane(detections)
    out = []
    for k, (p, cluster) in enumerate(zip(parts, _assign(detections, len(parts)))):
        if cluster < 0:
            out.append(PartPose(p.name, "not_found", f"no object cluster in the cloud fits {p.name!r}"))
            continue
        r = detections.detections[cluster].parts[k]
        out.append(PartPose(p.name, "found", "", cluster, _score(r), np.asarray(r.T_scene_model, dtype=np.float64)))
    return detections, plane, out


def _refine(p: PartPose, part: Any, plane: np.ndarray, capture: Callable, camera: Dict[str, Any], s: Any,
            q_camera: List[np.ndarray]) -> None:
    """Runs the 2D step on ``p`` (in place); the camera arm's joints of every view go to ``q_camera``."""
    p.T_base_model_rough = upright_on_table(p.T_base_model_3d, part.mesh, plane)
    ref = part.reference_image
    if ref is None:
        p.status, p.reason = "no_reference_image", f"part {part.name!r} has no reference_image in its part file"
        return
    q = q_camera[-1] if q_camera else camera["q_current"]
    p.refine = refine_2d(p.T_base_model_rough, ref.image, ref.geometry(), capture, intrinsics=camera["intrinsics"],
                         robot=camera["robot"], camera_mount=camera["mount"], table_plane=plane, q_current=q,
                         settings=s.refine_2d, view_settings=s.view)
    q_camera.extend(v.q for v in p.refine.views if v.q is not None)
    if p.refine.status == "ok":
        p.status, p.reason, p.T_base_model = "refined", p.refine.reason, np.asarray(p.refine.T_base_part)
    else:
        p.status, p.reason = p.refine.status, p.refine.reason


def assemble(cloud: Any, part: Any, *, capture: Callable[[np.ndarray], Any], gripper_robot: Any, camera_robot: Any,
             T_flange_camera: Any, intrinsics: Any, onto: Any = None, q_gripper: Optional[Sequence[float]] = None,
             q_camera: Optional[Sequence[float]] = None, settings: Optional[AssemblySettings] = None,
             progress: bool = False, **overrides: Any) -> AssemblyResult:
    """Plans the assembly of ``part`` (A: a part file, built-in name or ``PartGrasps`` with ``assembly`` and
    ``reference_image``) onto the part its ``assembly.onto`` names (B), from ``cloud`` ((N, 3) the fixed 3D camera's
    points in the cell's base frame, m) and the hand camera.

    ``capture(T_base_camera)``: moves the camera arm so that the camera is at that pose (4x4, m) and returns its image;
    ``camera_robot``, ``T_flange_camera`` (4x4, the webcam's hand-eye) and ``intrinsics``: the camera arm;
    ``gripper_robot``: the arm that picks (its gripper: A's part file's); both :class:`scanalign.kinematics.Robot`
    placed in the cell (``T_base_dh0``); ``q_gripper``, ``q_camera``: the arms' joints now (rad; default the KR6 home
    ``(0, -pi/2, pi/2, 0, 0, 0)``); ``onto``: part B (default the built-in part or the part file beside A's that
    ``assembly.onto`` names; its name must be that one). ``settings``: :data:`AssemblySettings`, keyword ``overrides`` its fields.
    Returns an :class:`AssemblyResult`; a part not found or not refined is a status, never a guess."""
    s = with_overrides(AssemblySettings, settings, overrides, "assemble")
    s.validate()
    a = load_part(part)
    if a.assembly is None:
        raise ValueError(f"part {a.name!r}: its part file has no 'assembly' (onto, T_onto_part, tolerances)")
    b = load_part(a.assembly.onto_source() if onto is None else onto)
    if b.name != a.assembly.onto:
        raise ValueError(f"onto: part {a.name!r} is assembled onto {a.assembly.onto!r}, not {b.name!r}")
    pts = as_points(cloud, "cloud", np.dtype(np.float64))
    t0 = time.perf_counter()
    detections, plane, poses = _detect(pts, [a, b], s, progress)
    result = AssemblyResult("not_found", "", {p.part: p for p in poses}, a.name, b.name, detections=detections)
    result.seconds["detect"] = time.perf_counter() - t0
    if missing := [p.part for p in poses if p.status == "not_found"]:
        result.reason = f"not found in the cloud: {', '.join(missing)}"
        return result
    camera = {"robot": camera_robot, "mount": _grasp.hand_camera_mount(T_flange_camera), "intrinsics": intrinsics,
              "q_current": KR6_HOME if q_camera is None else np.asarray(q_camera, np.float64)}
    for p, model in zip(poses, (a, b)):
        _refine(p, model, plane, capture, camera, s, result.q_camera)
    result.seconds["refine"] = time.perf_counter() - t0 - result.seconds["detect"]
    if failed := [p for p in poses if p.status != "refined"]:
        result.status = "refine_failed"
        result.reason = "; ".join(f"{p.part}: {p.status} ({p.reason})" for p in failed)
        return result
    plan = plan_pick_and_place(a, poses[0].T_base_model, poses[1].T_base_model, gripper_robot, table_plane=plane,
                               q_current=KR6_HOME if q_gripper is None else q_gripper, settings=s.planner)
    result.status, result.reason, result.T_base_target = plan.status, plan.reason, plan.T_base_target
    result.pick, result.place = plan.pick, plan.place
    result.seconds["plan"] = time.perf_counter() - t0 - result.seconds["detect"] - result.seconds["refine"]
    return result


@dataclass
class PickAndPlace:
    """The gripper arm's plans: ``status`` "planned", "no_grasp" or "no_place" with its ``reason``."""

    status: str
    reason: str
    T_base_target: np.ndarray  #: where the part goes (m)
    pick: Any  #: :class:`scanalign.grasp.GraspPlanResult` of the part at its pose
    place: Any = None  #: of the held part at the target (None without a grasp)


def plan_pick_and_place(part: Any, T_base_part: Any, T_base_onto: Any, robot: Any, *,
                        table_plane: Sequence[float] = (0.0, 0.0, 1.0, 0.0), q_current: Optional[Sequence[float]] = None,
                        settings: Any = None) -> PickAndPlace:
    """Plans the pick of ``part`` (a loaded ``PartGrasps`` with ``assembly``) at ``T_base_part`` and its place at
    ``T_base_onto @ part.assembly.T_onto_part`` (4x4, m) with ``robot`` (placed in the cell): every grasp, symmetric
    copy and IK branch of the pick judged by :func:`scanalign.grasp.plan_grasp` (``settings``: its
    ``GraspPlannerSettings``), then the chosen grasp held fixed, ``T_part_tcp``, at the target, planned from the
    grasp's joints (the IK branch nearest them)."""
    if getattr(part, "assembly", None) is None:
        raise ValueError(f"part {getattr(part, 'name', part)!r}: no 'assembly' (onto, T_onto_part, tolerances); "
                         "load its part file with scanalign.grasp.parts.load_part")
    T_part = as_transform(T_base_part, "T_base_part")
    target = as_transform(T_base_onto, "T_base_onto") @ np.asarray(part.assembly.T_onto_part, dtype=np.float64)
    pick = _grasp.plan_grasp(robot, T_part, part.grasps, symmetry=part.symmetry, gripper=part.gripper,
                             table_plane=table_plane, q_current=q_current, settings=settings)
    if not pick.found:
        return PickAndPlace("no_grasp", f"{part.name}: {pick.message}", target, pick)
    c = pick.candidates[pick.chosen]
    g = part.grasps[c.grasp_index]
    held = _grasp.Grasp(name=f"{g.name} (held)", T_model_grasp=np.linalg.solve(T_part, np.asarray(c.T_base_tcp_grasp)),
                        approach=np.asarray(g.approach), pre_grasp_distance=g.pre_grasp_distance)
    place = _grasp.plan_grasp(robot, target, [held], gripper=part.gripper, table_plane=table_plane,
                              q_current=np.asarray(c.q_grasp), settings=settings)
    if not place.found:
        return PickAndPlace("no_place", f"{part.name} onto {part.assembly.onto}: {place.message}", target, pick, place)
    return PickAndPlace("planned", f"{part.name} picked ({g.name}) and placed onto {part.assembly.onto}", target,
                        pick, place)


def assemble_cell(cell: Any, settings: Optional[AssemblySettings] = None, progress: bool = False,
                  **overrides: Any) -> AssemblyResult:
    """:func:`assemble` in a :class:`scanalign.synthetic.assembly_cell.AssemblyCell`: its cloud, its hand camera
    (``cell.capture``), its arms."""
    return assemble(cell.cloud(), cell.part, capture=cell.capture, gripper_robot=cell.gripper_robot,
                    camera_robot=cell.camera_robot, T_flange_camera=cell.T_flange_camera, intrinsics=cell.intrinsics,
                    settings=settings, progress=progress, **overrides)

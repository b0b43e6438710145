"""Grasps on CAD parts and grasp planning with the analytic IK (issue 17): which joint targets
pick a part at a known pose, and why every other candidate was rejected.

Frames (metres, radians; ``T_a_b`` maps b into a): ``T_base_tcp = T_base_model @ T_model_grasp``,
``T_base_flange = T_base_tcp @ inv(T_flange_tcp)``; the pre-grasp is the grasp moved back by
``pre_grasp_distance`` against ``approach`` (grasp frame). :func:`plan_grasp` tries every grasp
x symmetry copy x IK configuration; each :class:`GraspCandidate` has a ``reason``: ``"ok"``,
``"unreachable"``, ``"outside_limits"``, ``"near_singularity"``, ``"below_table"`` or
``"approach_branch_change"``, and a ``detail``. Grasp files (JSON or YAML):
:func:`read_part_grasps`, :func:`write_part_grasps`; schema in docs/api/grasp.md.
The classes are the C++ structs (``scanalign._core.grasp``; :class:`PartSymmetry` and
:func:`symmetric_pose_error` from ``scanalign._core.pose``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, List, Optional, Sequence

import numpy as np

from scanalign import _core, kinematics
from scanalign.common.rigid import require_rigid
from scanalign.common.settings import with_overrides
from scanalign.grasp.part_file_extras import (AssemblyTarget, ReferenceImage, dump_assembly, dump_reference_image,
                                              parse_assembly, parse_reference_image)

__all__ = ["Grasp", "Gripper", "PartSymmetry", "GraspPlannerSettings", "GraspCandidate", "GraspPlanResult",
           "PartGrasps", "plan_grasp", "read_part_grasps", "write_part_grasps", "symmetric_pose_error",
           "ViewPlannerSettings", "ViewPlan", "plan_camera_view", "camera_above", "hand_camera_mount",
           "ReferenceImage", "AssemblyTarget"]

_G = _core.grasp
Grasp, Gripper, GraspPlannerSettings = _G.Grasp, _G.Gripper, _G.GraspPlannerSettings
GraspCandidate, GraspPlanResult, PartSymmetry = _G.GraspCandidate, _G.GraspPlanResult, _core.pose.PartSymmetry
ViewPlannerSettings, ViewPlan = _G.ViewPlannerSettings, _G.ViewPlan
#: ``camera_above(T_base_part, top_height, height, yaw=0.0)`` -> (4, 4) T_base_camera looking straight down (m, rad).
camera_above = _G.camera_above
#: ``symmetric_pose_error(T_a, T_b, symmetry)`` -> (rad, m): the pose error of a part up to its
#: symmetry, translation measured at the symmetry point.
symmetric_pose_error = _core.pose.symmetric_pose_error


def plan_grasp(robot: Any, T_base_model: Any, grasps: Sequence[Grasp], *, symmetry: Optional[PartSymmetry] = None,
               gripper: Optional[Gripper] = None, table_plane: Sequence[float] = (0.0, 0.0, 1.0, 0.0),
               q_current: Optional[Sequence[float]] = None, settings: Optional[GraspPlannerSettings] = None,
               **overrides: Any) -> GraspPlanResult:
    """Joint targets to pick a part at ``T_base_model`` (4x4, m, base frame).

    ``robot``: a :class:`scanalign.kinematics.Robot` (its ``T_base_dh0`` places it in the cell; its
    tool is replaced by ``gripper.T_flange_tcp``) or a name. ``symmetry``: default none;
    ``gripper``: default :meth:`Gripper.parallel_jaw`; ``table_plane``: (nx, ny, nz, d), unit normal
    pointing up, ``n.p + d = 0`` in the base frame; ``q_current``: joints now (rad, default zeros);
    ``settings``: a :class:`GraspPlannerSettings` (default its C++ defaults), ``overrides`` its
    fields by name. Raises ValueError / TypeError naming the argument or field.
    """
    if isinstance(robot, str):
        robot = kinematics.Robot.by_name(robot)
    for value, name, cls in ((robot, "robot", kinematics.Robot), (symmetry, "symmetry", PartSymmetry),
                             (gripper, "gripper", Gripper)):
        if value is not None and not isinstance(value, cls):
            raise TypeError(f"{name}: expected {cls.__name__}, got {type(value).__name__}")
    s = with_overrides(GraspPlannerSettings, settings, overrides, "plan_grasp")
    if isinstance(grasps, Grasp) or not all(isinstance(g, Grasp) for g in grasps):
        raise TypeError("grasps: expected a list of scanalign.grasp.Grasp")
    return _G.plan_grasp(robot, T_base_model, list(grasps), PartSymmetry() if symmetry is None else symmetry,
                         Gripper.parallel_jaw() if gripper is None else gripper, table_plane,
                         np.zeros(6) if q_current is None else q_current, s)


def hand_camera_mount(T_flange_camera: Any, half_extents: Sequence[float] = (0.04, 0.04, 0.03)) -> Gripper:
    """A hand camera as the planner's tool: ``T_flange_tcp`` the hand-eye ``T_flange_camera`` (4x4, m), its body a
    box of ``half_extents`` (m, flange axes) from the flange face to the camera, kept above the table."""
    T = np.asarray(T_flange_camera, dtype=np.float64)
    z = max(float(T[2, 3]), 0.01) if T.shape == (4, 4) else 0.01
    return Gripper(T_flange_tcp=T, shape="box", box_centre=(0.0, 0.0, z / 2),
                   box_half_extents=(half_extents[0], half_extents[1], max(half_extents[2], z / 2)))


def plan_camera_view(robot: Any, T_base_part: Any, top_height: float, *, camera_mount: Gripper,
                     table_plane: Sequence[float] = (0.0, 0.0, 1.0, 0.0), q_current: Optional[Sequence[float]] = None,
                     settings: Optional[ViewPlannerSettings] = None, **overrides: Any) -> ViewPlan:
    """Where the hand camera looks at a part from (the view step of Kleppe et al. 2017's two-step pose): camera poses
    looking straight down from ``settings.height`` (m) above the part's top face (``top_height`` m above the origin of
    ``T_base_part``, 4x4, m), every analytic IK configuration judged as :func:`plan_grasp` judges a grasp.

    ``robot``: the arm carrying the camera (a :class:`scanalign.kinematics.Robot` or a name); ``camera_mount``: its
    body and ``T_flange_tcp`` = ``T_flange_camera`` (:func:`hand_camera_mount`); ``table_plane``, ``q_current``: as
    :func:`plan_grasp`; ``settings``: a :class:`ViewPlannerSettings`, ``overrides`` its fields. Returns a
    :class:`ViewPlan` (``found``, ``T_base_camera``, ``q``, ``message``)."""
    if isinstance(robot, str):
        robot = kinematics.Robot.by_name(robot)
    if not isinstance(robot, kinematics.Robot):
        raise TypeError(f"robot: expected Robot, got {type(robot).__name__}")
    if not isinstance(camera_mount, Gripper):
        raise TypeError(f"camera_mount: expected Gripper, got {type(camera_mount).__name__}")
    s = with_overrides(ViewPlannerSettings, settings, overrides, "plan_camera_view")
    return _G.plan_camera_view(robot, T_base_part, float(top_height), camera_mount, table_plane,
                               np.zeros(6) if q_current is None else q_current, s)


@dataclass
class PartGrasps:
    """A grasp file's content: the part and its grasps (schema in docs/api/grasp.md)."""
    name: str
    grasps: List[Grasp]
    symmetry: Optional[PartSymmetry] = None
    gripper: Optional[Gripper] = None
    #: a mesh file path (relative to the grasp file's folder) or "builtin:<name>"; in memory also an io.Mesh
    mesh: Any = None
    scale: float = 1.0  #: mesh units -> metres (grasps are always in metres)
    #: (4, 4) rigid, mesh -> model (m, applied after ``scale``): turns and moves the mesh into the
    #: model frame, in which the grasps and symmetry are given and whose +z is up on the table
    T_model_mesh: Any = None
    #: the top-face reference image of the two-step pose's 2D step (:class:`ReferenceImage`), or None
    reference_image: Optional[ReferenceImage] = None
    #: where this part goes when assembled onto another (:class:`AssemblyTarget`), or None
    assembly: Optional[AssemblyTarget] = None


_GRASP_KEYS = {"name", "T_model_grasp", "approach", "pre_grasp_distance"}
_GRIPPER_KEYS = {"T_flange_tcp", "shape", "box_centre", "box_half_extents", "capsule_a", "capsule_b", "capsule_radius",
                 "flange_radius"}


def _build(where: str, cls: Any, fields: dict, allowed: set, required: Sequence[str] = ()) -> Any:
    """cls(**fields), every error a ValueError naming ``where`` and the field."""
    if not isinstance(fields, dict):
        raise ValueError(f"{where}: expected a mapping, got {type(fields).__name__}")
    if (key := next((k for k in fields if k not in allowed), None)) is not None:
        raise ValueError(f"{where}: unknown field {key!r} (expected {sorted(allowed)})")
    if (key := next((k for k in required if k not in fields), None)) is not None:
        raise ValueError(f"{where}: missing field {key!r}")
    args = {}
    for key, value in fields.items():
        try:
            args[key] = np.asarray(value) if isinstance(value, list) else value
        except ValueError as e:  # a ragged list
            raise ValueError(f"{where}: field {key!r}: {e}") from None
    try:
        return cls(**args)  # the C++ checks name the field
    except (TypeError, ValueError) as e:
        raise ValueError(f"{where}: {e}") from None


def read_part_grasps(path: Any) -> PartGrasps:
    """Reads a grasp file (``.json``, ``.yaml`` or ``.yml``). ValueError naming the file, the
    grasp and the field for a missing field, a wrong type or a non-rigid matrix."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise ValueError(f"{p}: not UTF-8 text ({e})") from None
    try:
        data = json.loads(text) if p.suffix.lower() == ".json" else __import__("yaml").safe_load(text)
    except Exception as e:  # the parsers' own errors, with the file named
        raise ValueError(f"{p}: not valid {'JSON' if p.suffix.lower() == '.json' else 'YAML'}: {e}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{p}: expected a mapping at the top level")
    if unknown := set(data) - {"name", "mesh", "scale", "T_model_mesh", "symmetry", "gripper", "grasps",
                            "reference_image", "assembly"}:
        raise ValueError(f"{p}: unknown field(s) {sorted(unknown)}")
    grasps = data.get("grasps")
    if not isinstance(grasps, list) or not grasps:
        raise ValueError(f"{p}: field 'grasps' must be a non-empty list")
    out = [_build(f"{p}: grasps[{i}]" + (f" ({g['name']!r})" if isinstance(g, dict) and "name" in g else ""), Grasp, g,
                  _GRASP_KEYS, ["T_model_grasp"]) for i, g in enumerate(grasps)]
    scale = data.get("scale", 1.0)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not 0 < scale < float("inf"):
        raise ValueError(f"{p}: field 'scale' must be a positive number, got {scale!r}")
    for key in ("name", "mesh"):
        if key in data and not isinstance(data[key], str):
            raise ValueError(f"{p}: field {key!r} must be a string, got {data[key]!r}")
    sym, gripper, T = data.get("symmetry"), data.get("gripper"), data.get("T_model_mesh")
    try:
        T = None if T is None else require_rigid(T, "field 'T_model_mesh'")
    except (TypeError, ValueError) as e:
        raise ValueError(f"{p}: {e}") from None
    return PartGrasps(
        name=data.get("name", p.stem), grasps=out, mesh=data.get("mesh"), scale=float(scale), T_model_mesh=T,
        symmetry=None if sym is None else _build(f"{p}: symmetry", PartSymmetry, sym, {"axis", "point", "order"}),
        gripper=None if gripper is None else _build(f"{p}: gripper", Gripper, gripper, _GRIPPER_KEYS),
        reference_image=None if (r := data.get("reference_image")) is None else parse_reference_image(
            f"{p}: reference_image", r),
        assembly=None if (a := data.get("assembly")) is None else parse_assembly(f"{p}: assembly", a, p.parent))


def _list(a: Any) -> Any:
    return np.asarray(a, dtype=np.float64).tolist()


def write_part_grasps(path: Any, part: PartGrasps) -> None:
    """Writes ``part`` as JSON (``.json``) or YAML (``.yaml``, ``.yml``); read back by
    :func:`read_part_grasps` to the same values."""
    p = Path(path)
    data: dict = {"name": part.name, "scale": float(part.scale)}
    if part.mesh is not None:
        if not isinstance(part.mesh, str):
            raise ValueError(f"part.mesh: only a mesh file path or 'builtin:<name>' can be written, got "
                             f"{type(part.mesh).__name__}")
        data["mesh"] = part.mesh
    if part.T_model_mesh is not None:
        data["T_model_mesh"] = _list(part.T_model_mesh)
    if part.symmetry is not None:
        s = part.symmetry
        data["symmetry"] = {"axis": _list(s.axis), "point": _list(s.point), "order": int(s.order)}
    if part.gripper is not None:
        data["gripper"] = {k: (getattr(part.gripper, k) if k == "shape" else _list(getattr(part.gripper, k)))
                           for k in sorted(_GRIPPER_KEYS)}
    data["grasps"] = [{"name": g.name, "T_model_grasp": _list(g.T_model_grasp), "approach": _list(g.approach),
                       "pre_grasp_distance": float(g.pre_grasp_distance)} for g in part.grasps]
    if part.reference_image is not None:
        data["reference_image"] = dump_reference_image(part.reference_image)
    if part.assembly is not None:
        data["assembly"] = dump_assembly(part.assembly, p.parent)
    if p.suffix.lower() == ".json":
        p.write_text(json.dumps(data, indent=2) + "\n")
    elif p.suffix.lower() in (".yaml", ".yml"):
        p.write_text(__import__("yaml").safe_dump(data, sort_keys=False))
    else:
        raise ValueError(f"path: expected a .json, .yaml or .yml file name, got {p.name!r}")

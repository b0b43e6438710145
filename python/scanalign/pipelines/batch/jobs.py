"""Batch jobs: a small serialisable :class:`Job` in, one flat record of numbers and strings out.

:func:`run_job` is a pure function of the job and the part library: it writes files only into ``save`` and catches every
error into the record (``status`` ``"failed"``, ``error``), so one bad input never stops a batch. Kinds:

* ``reconstruct`` (:func:`scanalign.pipelines.reconstruct.reconstruct`) of a synthetic scan or a recording: ATE/RPE
  against the reference poses, and for synthetic scans the model's distance to the true surface;
* ``pose``: :func:`scanalign.pose.find_parts` on a cloud file (base frame) or the built-in
  pick cell seen from ``frames`` viewpoints; pose errors against the cell's truth;
* ``pick`` (:func:`scanalign.pipelines.pick.pick`) on the built-in cell, or on a TUM folder with ``joints``,
  ``hand_eye`` and ``robot_base`` files in ``settings``; grasp and pose errors against the cell's truth.
"""

from __future__ import annotations

import json
import math
import os
import platform
import time
import traceback
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Tuple

import numpy as np

from scanalign import io, pose, reconstruction
from scanalign.common.settings import with_overrides
from scanalign.datasets import open_source
from scanalign.grasp import symmetric_pose_error
from scanalign.grasp.parts import load_part
from scanalign.pipelines.pick import PickSettings, part_models, pick, read_transform, upper_views
from scanalign.pipelines.reconstruct import DEMO_SETTINGS, ReconstructionFailed, model_mesh_distance, reconstruct
from scanalign.reconstruction import make_reconstruction_settings
from scanalign.synthetic import SyntheticConfig
from scanalign.synthetic.cell import pick_cell, score_picks

__all__ = ["DEFAULT_PARTS", "Job", "KINDS", "LIBRARY_SETTINGS", "PICK_SETTINGS", "RECORD_FIELDS", "TEXT_FIELDS",
           "empty_record", "run_job"]

KINDS = ("reconstruct", "pose", "pick")
#: Parts of the built-in cell, used by pose and pick jobs that name none.
DEFAULT_PARTS = ("block", "bracket", "standoff")
_DEFAULT_FRAMES = {"reconstruct": 36, "pose": 4, "pick": 24}
#: Columns every record has, in table order (metrics not applying to a kind are NaN).
RECORD_FIELDS = (
    "id", "kind", "source", "robot", "noise", "seed", "frames", "status", "error", "attempts", "seconds", "worker",
    # reconstruct
    "merged", "model_points", "ate_rmse_m", "ate_max_m", "rpe_translation_rmse_m", "rpe_rotation_rmse_deg",
    "model_to_mesh_mean_m", "seconds_per_frame",
    # pose and pick
    "parts", "found", "pose_error_max_m", "pose_error_max_deg", "fitness_min",
    # pick
    "picked", "tcp_error_max_m", "tcp_error_max_deg",
    # per part, as JSON: {part: {status, pose_m, pose_deg[, tcp_m, tcp_deg]}}
    "detail")
#: Columns holding text; the others hold numbers (NaN where they do not apply).
TEXT_FIELDS = frozenset({"id", "kind", "source", "robot", "noise", "status", "error", "worker", "detail"})
#: Columns holding counts (integers; empty where they do not apply).
COUNT_FIELDS = frozenset({"seed", "frames", "attempts", "merged", "model_points", "parts", "found", "picked"})


def empty_record(job: "Job") -> Dict[str, Any]:
    """A record of ``job`` with nothing measured yet: text fields empty, numbers NaN."""
    record: Dict[str, Any] = {k: "" if k in TEXT_FIELDS else math.nan for k in RECORD_FIELDS}
    record.update(id=job.id, kind=job.kind, source=job.source, robot=job.robot, noise=job.noise, seed=job.seed,
                  frames=job.n_frames, attempts=1)
    return record


#: The settings of pose jobs (its ``find_parts``) and pick jobs, so that a pose job measures
#: what a pick finds; a job's ``settings`` override them.
PICK_SETTINGS = PickSettings()
#: find_parts keywords of the part library and every pose and pick job: the pick pipeline's
#: CBD radius per part, which the view descriptors depend on.
LIBRARY_SETTINGS = {"cbd_radius_fraction": PICK_SETTINGS.find_parts.cbd_radius_fraction}


@dataclass(frozen=True)
class Job:
    """What to run: one row of a batch manifest (see docs/batch.md).

    Attributes:
        id: unique name in the batch (the resume key).
        kind: ``"reconstruct"``, ``"pose"`` or ``"pick"``.
        source: ``"synthetic"`` or a path: a recording (TUM RGB-D folder, ROS bag or PNG folder:
            reconstruct; TUM folder: pick), a PLY or PCD cloud in the base frame, m (pose).
        robot, noise, seed: the synthetic scan: robot name, sensor noise preset, noise seed.
        frames: synthetic views (0: 36 for reconstruct, 4 for pose, 24 for pick).
        parts: part names (built-in) or part files (pose, pick); default :data:`DEFAULT_PARTS`.
        settings: fields over the kind's settings, nested as ``scanalign dump-config`` prints
            them: ``ReconstructionSettings`` (over ``DEMO_SETTINGS`` for synthetic scans),
            ``FindPartsSettings`` (pose; or :func:`scanalign.pose.find_parts`'s keywords) or
            ``PickSettings`` (plus ``joints``, ``hand_eye``, ``robot_base`` files of a real scan).
        save: a folder to write the job's outputs into (model, trajectories, picks), or "".
    """

    id: str
    kind: str
    source: str = "synthetic"
    robot: str = "ur5"
    noise: str = "sr300"
    seed: int = 0
    frames: int = 0
    parts: Tuple[str, ...] = ()
    settings: Dict[str, Any] = field(default_factory=dict)
    save: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.id, str) or not self.id or any(c in self.id for c in '/\\\n"'):
            raise ValueError(f"job id must be a non-empty string without / \\ \" or newlines, got {self.id!r}")
        if self.kind not in KINDS:
            raise ValueError(f"job {self.id!r}: kind must be one of {KINDS}, got {self.kind!r}")
        if not isinstance(self.seed, int) or isinstance(self.seed, bool) or self.seed < 0:
            raise ValueError(f"job {self.id!r}: seed must be an integer >= 0, got {self.seed!r}")
        if not isinstance(self.frames, int) or isinstance(self.frames, bool) or not 0 <= self.frames <= 10000:
            raise ValueError(f"job {self.id!r}: frames must be an integer in [0, 10000], got {self.frames!r}")
        if not isinstance(self.settings, dict):
            raise ValueError(f"job {self.id!r}: settings must be a mapping, got {type(self.settings).__name__}")
        object.__setattr__(self, "parts", tuple(str(p) for p in self.parts))

    @property
    def synthetic(self) -> bool:
        return self.source == "synthetic"

    @property
    def n_frames(self) -> int:
        return self.frames or _DEFAULT_FRAMES[self.kind]

    @property
    def part_names(self) -> Tuple[str, ...]:
        return self.parts or DEFAULT_PARTS


def run_job(job: Job, library: Any = None) -> Dict[str, Any]:
    """Runs one job and returns its record (every field of :data:`RECORD_FIELDS`); never
    raises: a failing job's record says ``"failed"`` with ``error`` (exception type, message,
    innermost frame). ``library``: a :class:`scanalign.grasp.part_library.PartLibrary` with
    the job's parts (without one, or for a part it lacks, the views are described here)."""
    record = empty_record(job)
    record.update(status="ok", worker=f"{platform.node()}:{os.getpid()}")
    t0 = time.perf_counter()
    try:
        record.update(_RUNNERS[job.kind](job, library))
    except Exception as e:  # noqa: BLE001 -- isolation is the point: the batch goes on
        where = traceback.extract_tb(e.__traceback__)[-1] if e.__traceback__ else None
        record.update(status="failed", error=f"{type(e).__name__}: {e}"
                      + (f" (at {Path(where.filename).name}:{where.lineno})" if where else ""))
    record["seconds"] = time.perf_counter() - t0
    return record


def _reconstruct(job: Job, library: Any) -> Dict[str, Any]:
    scan = (SyntheticConfig(n_frames=job.n_frames, noise=job.noise, seed=job.seed, robot=job.robot).build()
            if job.synthetic else None)
    frames: Any = scan.frames if scan is not None else open_source(job.source)  # a TUM folder, a bag or PNG folder
    # the demo's settings, with motion model 'previous' (the eye-in-hand paper's, as batch jobs always ran)
    base = make_reconstruction_settings(None, initial_guess="previous", **DEMO_SETTINGS) if job.synthetic else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ReconstructionFailed)  # the record's reconstruction_status says it
        result = reconstruct(frames, base, progress=False, **job.settings)
    s = result.summary()
    out = {"reconstruction_status": s["status"], "frames": s["frames"], "merged": s["merged"],
           "model_points": s["model_points"],
           "seconds_per_frame": s["seconds_per_frame_median"]}
    if "ate_m" in s:
        out.update(ate_rmse_m=s["ate_m"]["rmse"], ate_max_m=s["ate_m"]["max"],
                   rpe_translation_rmse_m=s["rpe_translation_m"]["rmse"],
                   rpe_rotation_rmse_deg=s["rpe_rotation_deg"]["rmse"])
    if scan is not None:
        out["model_to_mesh_mean_m"] = model_mesh_distance(result, scan.mesh.vertices, scan.mesh.faces)["mean"]
    if job.save:
        result.save(job.save)
    return out


def _cell(job: Job) -> Tuple[Any, Dict[str, np.ndarray]]:
    """The built-in pick cell of a synthetic job and its true part poses; (None, {}) for a recording."""
    if not job.synthetic:
        return None, {}
    cell = pick_cell(job.robot, noise=job.noise, seed=job.seed, n_frames=job.n_frames)
    return cell, cell.truth


def _scores(detail: Dict[str, Dict[str, Any]], **fields: Any) -> Dict[str, Any]:
    """``fields``, the per-part ``detail`` as JSON and the largest pose and TCP errors in it."""
    out = {**fields, "detail": json.dumps(detail)}
    for key in ("pose_m", "pose_deg", "tcp_m", "tcp_deg"):
        errors = [d[key] for d in detail.values() if key in d]
        if errors:
            what, unit = key.split("_")
            out[f"{what}_error_max_{unit}"] = max(errors)
    return out


def _pose(job: Job, library: Any) -> Dict[str, Any]:
    names = job.part_names
    parts = [load_part(n) for n in names]
    cell, truth = _cell(job)
    if cell is not None:
        points = np.concatenate([cell.scan.points(i, in_base=True) for i in range(len(cell.scan))])
        points = reconstruction.voxel_grid(points, 0.001).points  # one point per mm voxel, as a merged scan
    else:
        points, _ = io.read_cloud(job.source)
        points = points[np.isfinite(points).all(axis=1)]
    detections = pose.find_parts(part_models(parts, library), points, PICK_SETTINGS.find_parts,
                                 symmetries=[p.symmetry for p in parts], views=upper_views(), **job.settings)
    found = [d for d in detections.detections if d.status.name == "found"]
    detail: Dict[str, Dict[str, Any]] = {n: {"status": "not_found"} for n in names}
    for d in found:
        name = names[d.part]
        detail[name] = {"status": "found"}
        if name in truth:
            rot, dist = symmetric_pose_error(np.asarray(d.pose.T_scene_model), truth[name], parts[d.part].symmetry)
            detail[name].update(pose_m=dist, pose_deg=math.degrees(rot))
    out = _scores(detail, parts=len(names), found=len({d.part for d in found}),
                  fitness_min=min((d.pose.fitness for d in found), default=math.nan))
    if job.save:
        Path(job.save).mkdir(parents=True, exist_ok=True)
        io.write_ply(Path(job.save) / "scene.ply", points)
    return out


def _pick(job: Job, library: Any) -> Dict[str, Any]:
    settings = dict(job.settings)
    files = {k: settings.pop(k, None) for k in ("joints", "hand_eye", "robot_base")}
    s = with_overrides(PickSettings, PICK_SETTINGS, settings, "pick job")
    cell, truth = _cell(job)
    if cell is not None:
        result = pick(cell.scan, [p.name for p in cell.parts], cell.robot, settings=s, progress=False, library=library)
    else:
        result = pick(job.source, list(job.part_names), job.robot, joints=files["joints"],
                      T_flange_camera=read_transform(files["hand_eye"], "hand_eye"),
                      T_base_robot=read_transform(files["robot_base"], "robot_base"), settings=s, progress=False,
                      library=library)
    errors = score_picks(result, truth) if truth else {}
    found = [p for p in result.picks if p.status in ("picked", "no_grasp")]
    detail = {p.part: {"status": p.status, **errors.get(p.part, {})} for p in result.picks}
    out = _scores(detail, parts=len(result.parts), found=len(found),
                  picked=sum(p.status == "picked" for p in result.picks),
                  fitness_min=min((p.fitness for p in found), default=math.nan))
    if job.save:
        result.save(job.save)
    return out


_RUNNERS = {"reconstruct": _reconstruct, "pose": _pose, "pick": _pick}

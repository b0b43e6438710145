"""The reconstruction job: :func:`reconstruct` runs a :class:`scanalign.reconstruction.Reconstructor` over frames and
evaluates the trajectory against their reference poses (``Frame.T_base_camera``); :meth:`ReconstructionResult.save`
writes the model, trajectories, per-frame table and report.
"""

from __future__ import annotations

import csv
import json
import math
import sys
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, List, Optional, Union

import numpy as np
from tqdm.auto import tqdm

from scanalign.common.rigid import inverse, transform_points
from scanalign.common.settings import to_dict
from scanalign.evaluation import absolute_trajectory_error, mesh_distance_stats, relative_pose_error
from scanalign.evaluation.trajectory import Trajectory
from scanalign.io import atomic_open
from scanalign.reconstruction import (FrameResult, Model, ReconstructionSettings, Reconstructor,
                                      make_reconstruction_settings)
from scanalign.reconstruction.camera import Frame

__all__ = ["DEMO_SETTINGS", "ReconstructionFailed", "ReconstructionResult", "reconstruct", "write_joints_csv"]


class ReconstructionFailed(RuntimeWarning):
    """Warned by :func:`reconstruct` when a run failed (:attr:`ReconstructionResult.status`)."""

#: What ``scanalign demo`` and the batch's synthetic jobs change from the ``ReconstructionSettings``
#: defaults: frames cropped to the part's workspace (the defaults' ICP box, 20 x 20 cm), so that the
#: model holds no table and a run takes a few seconds (same ATE; the defaults merge the whole table).
DEMO_SETTINGS = {"frame_to_model": {"crop_box": (-0.1, 0.1, -0.1, 0.1, 0.1, 1.0)}}


@dataclass
class ReconstructionResult:
    """Outcome of :func:`reconstruct`.

    Attributes:
        model: the accumulated model (model frame).
        records: one :class:`FrameResult` per input frame, skipped ones included.
        estimate: estimated ``T_model_camera`` of the merged frames.
        reference: reference ``T_base_camera`` of the merged frames that have one, or None.
        T_model_camera0: pose given to the first frame (identity, or the first frame's
            reference pose when the model is built in the base frame).
        settings: the :class:`ReconstructionSettings` used.
        metrics: ATE / RPE summary (see :meth:`summary`).
        seconds: wall time of the whole run (frame loading included).
        joints: (len(records), 6) robot joints (rad) of every input frame from
            ``Frame.meta["joints"]`` (NaN rows for frames without); None when no frame has any.
        robot: the robot's name from ``Frame.meta["robot"]``, or None.
    """

    model: Model
    records: List[FrameResult]
    estimate: Trajectory
    reference: Optional[Trajectory]
    T_model_camera0: np.ndarray
    settings: ReconstructionSettings
    seconds: float
    metrics: Dict[str, Any] = field(default_factory=dict)
    joints: Optional[np.ndarray] = None
    robot: Optional[str] = None

    @property
    def skipped(self) -> List[FrameResult]:
        return [r for r in self.records if not r.merged]

    @property
    def status(self) -> str:
        """``"ok"``, or ``"failed"`` when fewer than ``settings.min_merged_fraction`` of the frames merged."""
        merged = sum(r.merged for r in self.records)
        return "ok" if merged >= self.settings.min_merged_fraction * len(self.records) else "failed"

    def failure(self) -> Optional[str]:
        """Why the run failed (None when :attr:`status` is ``"ok"``): the counts and what to try."""
        if self.status == "ok":
            return None
        skipped = self.summary()["skipped"]
        return (f"reconstruction failed: {len(self.records) - len(self.skipped)} of {len(self.records)} frames merged "
                f"(settings.min_merged_fraction {self.settings.min_merged_fraction:g}), skipped {skipped}. "
                "Frames that do not converge moved further than frame_to_model.icp.max_correspondence_distance "
                "between captures, or their noise needs a larger frame_to_model.normal_radius or filter_depth; "
                "the workspace box frame_to_model.icp.box must hold the scanned part")

    def summary(self) -> Dict[str, Any]:
        """JSON-able summary: counts, seconds per registered frame, model size, ATE/RPE when a reference exists."""
        registered = [r for r in self.records if r.status == "registered"]
        t = np.array([r.total_seconds for r in registered])
        out: Dict[str, Any] = {
            "status": self.status, "frames": len(self.records), "merged": sum(r.merged for r in self.records),
            "skipped": {s: sum(r.status == s for r in self.records) for s in sorted({r.status for r in self.skipped})},
            "registration": self.settings.registration, "model_points": len(self.model), "seconds_total": self.seconds,
            **{f"seconds_per_frame_{k}": float(f(t)) if t.size else None
               for k, f in (("median", np.median), ("mean", np.mean), ("max", np.max))},
            "iterations_median": float(np.median([r.iterations for r in registered])) if t.size else None}
        if self.joints is not None:
            out["robot"] = self.robot
        out.update(self.metrics)
        return out

    def save(self, out_dir: Union[str, Path]) -> Dict[str, Path]:
        """Writes model.ply, trajectory.txt, reference.txt (when known), frames.csv,
        joints.csv (with robot joints) and report.json into ``out_dir``; returns their paths."""
        (out := Path(out_dir)).mkdir(parents=True, exist_ok=True)
        paths = {"model": out / "model.ply", "trajectory": out / "trajectory.txt", "frames": out / "frames.csv"}
        self.model.write_ply(paths["model"])
        self.estimate.write_tum(paths["trajectory"], header="scanalign estimate: T_model_camera (camera -> model frame)")
        if self.reference is not None:
            paths["reference"] = out / "reference.txt"
            self.reference.write_tum(paths["reference"], header="reference: T_base_camera (camera -> robot base frame)")
        cols = [k for k in FrameResult().to_dict() if k != "T_model_camera"]
        with atomic_open(paths["frames"], "w", newline="", encoding="utf-8") as f:
            csv.writer(f).writerows([cols] + [[getattr(r, c) for c in cols] for r in self.records])
        if self.joints is not None:
            paths["joints"] = out / "joints.csv"
            write_joints_csv(paths["joints"], [r.index for r in self.records], [r.timestamp for r in self.records],
                             self.joints)
        report = {"summary": self.summary(), "settings": to_dict(self.settings),
                  "T_model_camera0": np.asarray(self.T_model_camera0).tolist(),
                  "frames": [{k: v for k, v in r.to_dict().items() if k != "T_model_camera"} for r in self.records],
                  "units": "metres, radians, seconds"}
        paths["report"] = out / "report.json"
        with atomic_open(paths["report"], "w", encoding="utf-8") as f:
            json.dump(_jsonable(report), f, indent=2)
        return paths

    def estimate_at_reference(self) -> Trajectory:
        """The estimated poses of exactly the frames in :attr:`reference` (same order)."""
        if self.reference is None:
            return self.estimate
        return self.estimate[np.nonzero(np.isin(self.estimate.timestamps, self.reference.timestamps))[0]]


def write_joints_csv(path: Union[str, Path], indices: Iterable[int], timestamps: Iterable[float],
                     joints: np.ndarray) -> Path:
    """Writes a joint trajectory as CSV ``index,timestamp,q1,...,q6`` (seconds, radians; 17
    significant digits, so the values read back exactly; empty cells for unknown joints)."""
    q = np.asarray(joints, dtype=np.float64)
    with atomic_open(path, "w", newline="", encoding="utf-8") as f:
        csv.writer(f).writerows([["index", "timestamp", "q1", "q2", "q3", "q4", "q5", "q6"]] + [
            [int(i), repr(float(t))] + [repr(float(v)) if math.isfinite(v) else "" for v in row]
            for i, t, row in zip(indices, timestamps, q)])
    return Path(path)


def _jsonable(v: Any) -> Any:
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, np.ndarray):
        return _jsonable(v.tolist())
    if isinstance(v, (np.floating, float)):
        f = float(v)
        return f if math.isfinite(f) else None
    return v.item() if isinstance(v, (np.integer, np.bool_)) else v  # Python int / bool


def reconstruct(frames: Iterable[Frame], settings: Optional[ReconstructionSettings] = None, *,
                progress: Union[bool, Callable[[FrameResult], None]] = True, evaluate: bool = True,
                on_frame: Optional[Callable[[Frame, FrameResult, Reconstructor], None]] = None,
                **overrides: Any) -> ReconstructionResult:
    """Reconstructs a sequence of RGB-D frames frame-to-model (Algorithm 1 of the eye-in-hand paper).

    Args:
        frames: the captures, in order (a list, a synthetic scan's frames, a TUM sequence).
        settings: :class:`scanalign.reconstruction.ReconstructionSettings` (default: its C++ defaults); keyword
            ``overrides`` as :func:`scanalign.reconstruction.make_reconstruction_settings` takes them. With motion model
            ``reference`` each frame starts from the robot's reference motion since the last merged frame (needs
            reference poses on every frame).
        progress: show a progress bar (True), none (False), or a callable per record.
        evaluate: compute ATE/RPE against the reference poses when available; when that
            fails (a reference that never moves), ``metrics["evaluation_error"]`` says why.
        on_frame: called after each frame with ``(frame, record, reconstructor)`` (e.g.
            :meth:`scanalign.viz.viewer.Viewer.on_frame`).

    Raises:
        ValueError: bad settings, ``model_frame="base"`` without a reference pose on the
        first frame, or a malformed frame (e.g. image size not matching the intrinsics).
        TypeError: an item of ``frames`` that is not a Frame.

    Warns:
        ReconstructionFailed: fewer than ``min_merged_fraction`` of the frames merged (the result's
        ``status`` is ``"failed"``; :meth:`ReconstructionResult.failure` says why).
    """
    job = make_reconstruction_settings(settings, **overrides)
    model_frame, by_reference = job.model_frame, job.frame_to_model.motion_model == "reference"
    t_start = time.perf_counter()
    rec: Optional[Reconstructor] = None
    ref_of: Dict[int, np.ndarray] = {}
    last_ref: Optional[np.ndarray] = None
    joints: List[Optional[np.ndarray]] = []
    robot_name: Optional[str] = None
    total = len(frames) if hasattr(frames, "__len__") else None  # type: ignore[arg-type]
    with tqdm(total=total, desc="reconstruct", unit="frame", file=sys.stderr, dynamic_ncols=True,
              disable=progress is not True) as bar:
        for k, frame in enumerate(frames):
            if not isinstance(frame, Frame):
                raise TypeError(f"frames: item {k} is a {type(frame).__name__}, not a scanalign.reconstruction.camera.Frame")
            if rec is None:
                base = frame.T_base_camera is not None and model_frame in ("auto", "base")
                if model_frame == "base" and frame.T_base_camera is None:
                    raise ValueError("model_frame='base' needs a reference pose (T_base_camera) on the first frame")
                T0 = np.asarray(frame.T_base_camera, dtype=np.float64) if base else np.eye(4)
                rec = Reconstructor(job, T_model_camera0=T0)
            guess = None
            if by_reference:
                if frame.T_base_camera is None:
                    raise ValueError(f"frame {frame.index}: motion model 'reference' (initial_guess) needs "
                                     "T_base_camera on every frame")
                if last_ref is not None and rec.model_size:
                    # The robot's relative motion since the last merged frame, applied to that frame's estimate.
                    guess = rec.last_pose @ inverse(last_ref) @ np.asarray(frame.T_base_camera)
            record = rec.integrate(frame, guess=guess)
            meta = getattr(frame, "meta", None) or {}
            q = meta.get("joints")
            joints.append(None if q is None else np.asarray(q, dtype=np.float64).reshape(6))
            if q is not None and robot_name is None and meta.get("robot") is not None:
                robot_name = str(meta["robot"])
            if frame.T_base_camera is not None:
                ref_of[record.index] = np.asarray(frame.T_base_camera, dtype=np.float64)
                if record.merged:
                    last_ref = ref_of[record.index]
            bar.set_postfix_str(f"{record.status} fit={record.fitness:.2f} model={record.model_points}", refresh=False)
            bar.update(1)
            if callable(progress):
                progress(record)
            if on_frame is not None:
                on_frame(frame, record, rec)
    if rec is None:
        raise ValueError("no frames to reconstruct")
    with_ref = [r for r in rec.records if r.merged and r.index in ref_of]
    reference = Trajectory(np.array([r.timestamp for r in with_ref]),
                           np.array([ref_of[r.index] for r in with_ref])) if with_ref else None
    result = ReconstructionResult(model=rec.model, records=rec.records, estimate=rec.trajectory, reference=reference,
                                  T_model_camera0=rec.T_model_camera0, settings=job,
                                  seconds=time.perf_counter() - t_start)
    if any(q is not None for q in joints):
        result.joints = np.array([np.full(6, np.nan) if q is None else q for q in joints])
        result.robot = robot_name
    if (why := result.failure()) is not None:
        warnings.warn(why, ReconstructionFailed, stacklevel=2)
    if evaluate and reference is not None and len(reference) >= 3:
        try:  # a failed evaluation (e.g. a reference that never moves) must not lose the reconstruction
            result.metrics.update(trajectory_metrics(result.estimate_at_reference(), reference))
        except (ValueError, RuntimeError, np.linalg.LinAlgError) as e:
            result.metrics["evaluation_error"] = f"{type(e).__name__}: {e}"
    return result


def _floats(stats: Any, names: Iterable[str] = ("rmse", "mean", "median", "std", "min", "max")) -> Dict[str, float]:
    return {k: float(getattr(stats, k)) for k in names}


def trajectory_metrics(estimate: Trajectory, reference: Trajectory) -> Dict[str, Any]:
    """ATE (after rigid alignment) and RPE (1-frame) of matching trajectories (m, degrees)."""
    ate = absolute_trajectory_error(estimate, reference)
    rpe = relative_pose_error(estimate, reference, delta=1)
    return {"ate_m": _floats(ate.translation), "rpe_translation_m": _floats(rpe.translation),
            "rpe_rotation_deg": _floats(rpe.rotation), "path_length_m": reference.path_length()}


def model_mesh_distance(result: ReconstructionResult, vertices_base: np.ndarray, faces: np.ndarray) -> Dict[str, float]:
    """Distance of the reconstructed model to the true surface (synthetic scans): mean,
    median, p95, max and rmse (m). The model is mapped into the mesh's base frame by the first
    merged frame's reference pose and model pose (identity when built in the base frame)."""
    T_base_model = np.eye(4)
    merged = [r for r in result.records if r.merged]
    if result.reference is not None and merged:
        ref, first = result.reference, merged[0]
        k = np.nonzero(np.isclose(ref.timestamps, first.timestamp, rtol=0, atol=1e-9))[0]
        if k.size:
            T_base_model = ref.poses[k[0]] @ inverse(first.T_model_camera)
    pts = transform_points(T_base_model, result.model.points.astype(np.float64))
    return _floats(mesh_distance_stats(pts, vertices_base, faces), ("mean", "median", "p95", "max", "rmse"))

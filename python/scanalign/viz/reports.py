"""The files of a run that people look at: each result's data files (its own ``save``) plus
its figures, drawn here so that the layers below never import matplotlib."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Dict, Optional, Union

import numpy as np

from scanalign import io
from scanalign.common.arrays import as_points, foreign_kind
from scanalign.common.rigid import transform_points
from scanalign.data.parts import sample_mesh
from scanalign.io.interop import Cloud
from scanalign.kinematics import Robot
from scanalign.pipelines.batch import BatchResult
from scanalign.pipelines.pick import PickResult
from scanalign.pipelines.reconstruct import ReconstructionResult
from scanalign.pose.model_views import read_model
from scanalign.viz import plots


def save_report(result: Any, out_dir: Union[str, Path], plots_too: bool = True) -> Dict[str, Path]:
    """``result.save(out_dir)`` plus, with ``plots_too``, its figures: trajectory.png,
    frames.png and joints.png of a :class:`ReconstructionResult`; pick.png of a
    :class:`PickResult`; results.png of a :class:`BatchResult`. Returns every path written."""
    out = Path(out_dir)
    paths = result.save(out) if not isinstance(result, BatchResult) else dict(result.paths)
    if not plots_too:
        return paths
    if isinstance(result, ReconstructionResult):
        paths.update(reconstruction_figures(result, out))
    elif isinstance(result, PickResult):
        paths["png"] = plots.plot_pick(result, out / "pick.png")
    elif isinstance(result, BatchResult):
        paths["plot"] = plots.plot_batch(result.records, out / "results.png")
    return paths


def reconstruction_figures(result: ReconstructionResult, out: Path) -> Dict[str, Path]:
    """trajectory.png (aligned to the reference if there is one), frames.png and, with joints, joints.png in ``out``."""
    paths: Dict[str, Path] = {}
    if result.reference is not None and len(result.reference) >= 3:
        try:  # aligned to the reference, unless it cannot be (it never moves: see metrics)
            paths["trajectory_png"] = plots.plot_trajectory_topdown(
                result.estimate_at_reference(), result.reference, out / "trajectory.png",
                title="estimated (aligned) vs reference camera path")
        except ValueError:
            paths["trajectory_png"] = plots.plot_trajectory_topdown(result.estimate, None, out / "trajectory.png")
    elif len(result.estimate) >= 2:
        paths["trajectory_png"] = plots.plot_trajectory_topdown(result.estimate, None, out / "trajectory.png")
    rows = [dict(time=r.total_seconds, iterations=r.iterations, fitness=r.fitness,
                 model_points=r.model_points, skipped=not r.merged) for r in result.records]
    paths["frames_png"] = plots.plot_frame_stats(rows, out / "frames.png", title="per-frame time and model size")
    if result.joints is not None and len(result.records) >= 2:
        try:
            limits = Robot.by_name(result.robot).limits if result.robot is not None else None
        except ValueError:  # a custom robot: no limits to draw
            limits = None
        paths["joints_png"] = plots.plot_joint_trajectory(
            [r.timestamp for r in result.records], result.joints, out / "joints.png", limits=limits,
            title=f"{result.robot or 'robot'} joint trajectory (inverse kinematics, closest to previous)")
    return paths


def write_pose_outputs(model: object, scene: np.ndarray, result: Any, prefix: Union[str, Path], *,
                       object_indices: Optional[np.ndarray] = None, samples: int = 20000) -> Dict[str, Path]:
    """Writes ``<prefix>_model.ply`` (the ``model`` -- a mesh, sampled, a model cloud, or a model file -- placed in the scene
    frame by ``result.T_scene_model``), ``<prefix>_scene.ply`` (the (M, 3) ``scene``, its ``object_indices`` (default
    all) orange, the rest grey, the model blue) and ``<prefix>_overlay.png`` (three projections); metres. Returns the
    paths written."""
    prefix = Path(prefix)
    prefix.parent.mkdir(parents=True, exist_ok=True)
    scene = as_points(scene, "scene", np.dtype(np.float64))
    if isinstance(model, (str, Path)):
        model = read_model(model)
    if isinstance(model, Cloud):
        model = model.points
    cloud = isinstance(model, np.ndarray) or foreign_kind(model) == "cloud"
    mp = as_points(model, "model", np.dtype(np.float64)) if cloud else sample_mesh(model, samples, seed=0)[0]
    placed = transform_points(np.asarray(result.T_scene_model, dtype=np.float64), mp)
    paths = {f"{part}_{ext}": prefix.with_name(f"{prefix.name}_{part}.{ext}")
             for part, ext in (("model", "ply"), ("scene", "ply"), ("overlay", "png"))}
    io.write_ply(paths["model_ply"], placed.astype(np.float32))
    idx = np.arange(len(scene)) if object_indices is None else np.asarray(object_indices, dtype=np.int64)
    colours = np.full((len(scene), 3), 160, np.uint8)
    colours[idx] = (240, 140, 40)
    io.write_ply(paths["scene_ply"], np.vstack([scene, placed]).astype(np.float32),
                  colors=np.vstack([colours, np.tile(np.array([[40, 90, 230]], np.uint8), (len(placed), 1))]))
    plots.pose_overlay(scene[idx], placed, result, paths["overlay_png"])
    return paths

"""The ``scanalign`` command line: one sub-command per job, listed by ``scanalign --help``
(``scanalign COMMAND --help``: its options). Units: metres, radians, seconds.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import time
import warnings
from pathlib import Path
from typing import Any, Optional, Sequence

import numpy as np

from scanalign import _core, datasets, io, synthetic
from scanalign import kinematics as kin
from scanalign import pose as _pose
from scanalign.cli.assemble_command import ASSEMBLE, add_assemble_parser, assemble_command
from scanalign.cli.settings import Alias, Command, add_settings_options, dump, resolve, write_effective
from scanalign.common import rigid as se3
from scanalign.common.settings import to_dict
from scanalign.data import parts
from scanalign.datasets import tum
from scanalign.features import NormalEstimationSettings, estimate_normals
from scanalign.io.interop import Cloud
from scanalign.pipelines import batch
from scanalign.pipelines import pick as _pick
from scanalign.pipelines.reconstruct import (DEMO_SETTINGS, ReconstructionFailed, model_mesh_distance, reconstruct,
                                             write_joints_csv)
from scanalign.pose.model_views import read_model
from scanalign.reconstruction import ReconstructionSettings
from scanalign.reconstruction.camera import INTRINSICS_PRESETS
from scanalign.registration import Box, IcpSettings, icp, pcl_icp
from scanalign.synthetic.cell import pick_cell, score_picks
from scanalign.viz import plots
from scanalign.viz.reports import save_report, write_pose_outputs
from scanalign.viz.viewer import Viewer


def _icp_record(r: Any) -> dict:
    """An ICP result as JSON: status, convergence, scores (m) and ``T_target_source``."""
    return dict(status=r.status, converged=bool(r.converged), iterations=r.iterations, fitness=r.fitness,
                inlier_rmse_m=r.inlier_rmse, T_target_source=r.T_target_source.tolist(), seconds=r.seconds)


def register_demo(out: Path, seed: int = 0, noise: float = 0.0005) -> dict:
    """Runs the two-cloud registration demo; returns the report written to ``out/report.json``."""
    if not (np.isfinite(noise) and noise >= 0):
        raise ValueError(f"--noise must be a finite depth noise >= 0 (m), got {noise}")
    out.mkdir(parents=True, exist_ok=True)
    # Model: the built-in part, in the model frame, 40 cm in front of the first camera.
    model = parts.builtin_object(n_points=40000, seed=seed)[0] + np.array([0.0, 0.0, 0.40])
    model_normals = estimate_normals(model, radius=0.005, viewpoint=(0.0, 0.0, 0.0))
    # A new frame: the camera moved by T_model_camera; the frame sees part of the object
    # (one side cut away) with depth noise, in its own camera frame.
    T_model_camera = se3.rigid((0.3, 1.0, 0.2), np.deg2rad(4.0), (0.012, -0.008, 0.006))
    frame = se3.transform_points(np.linalg.inv(T_model_camera), model[model[:, 0] > -0.02])
    frame = frame + np.random.default_rng(seed).normal(0.0, noise, frame.shape)
    print(f"model: {len(model)} points, frame: {len(frame)} points, depth noise {noise * 1000:.2f} mm")
    runs = {}
    for name, variant in (("scanalign", None), ("pcl_point_to_plane_lls", "point_to_plane_lls"), ("pcl_svd", "svd")):
        t0 = time.perf_counter()
        r = (icp(frame, model, model_normals, max_correspondence_distance=0.02) if variant is None else
             pcl_icp(frame, model, None if variant == "svd" else model_normals, variant=variant,
                     max_correspondence_distance=0.02))
        wall = time.perf_counter() - t0
        rot, trans = se3.pose_error(r.T_target_source, T_model_camera)
        runs[name] = {**_icp_record(r), "seconds": wall, "rotation_error_rad": rot, "translation_error_m": trans}
        print(f"  {name:24s} {r.status:24s} it={r.iterations:3d}  rot err {np.rad2deg(rot):.4f} deg  "
              f"trans err {trans * 1000:.3f} mm  rmse {r.inlier_rmse * 1000:.3f} mm  {wall * 1000:.1f} ms")
    speedup = runs["pcl_point_to_plane_lls"]["seconds"] / runs["scanalign"]["seconds"]
    print(f"  scanalign is {speedup:.1f}x faster than PCL IterativeClosestPointWithNormals here")
    aligned = se3.transform_points(np.asarray(runs["scanalign"]["T_target_source"]), frame)
    io.write_ply(out / "model.ply", model, normals=model_normals, colors=np.full((len(model), 3), 180, np.uint8))
    io.write_ply(out / "frame_aligned.ply", aligned, colors=np.tile(np.uint8([230, 80, 40]), (len(aligned), 1)))
    report = dict(T_model_camera_true=T_model_camera.tolist(), runs=runs, speedup_vs_pcl_lls=speedup)
    (out / "report.json").write_text(json.dumps(report, indent=2))
    print(f"wrote {out / 'model.ply'}, {out / 'frame_aligned.ply'} (open both in a viewer) and {out / 'report.json'}")
    return report


def register(args: argparse.Namespace) -> int:
    """``scanalign register``: ICP between two files; prints JSON, writes the aligned source."""
    src, _ = io.read_cloud(Path(args.source))
    tgt, tgt_normals = io.read_cloud(Path(args.target))
    if tgt_normals is None or not np.isfinite(tgt_normals).any():
        tgt_normals = estimate_normals(tgt, settings=args.settings["normals"])
    init = _pick.read_transform(args.init, "--init", rigid=False) if args.init else None
    r = icp(src, tgt, tgt_normals, init, settings=args.settings["icp"])
    print(json.dumps(_icp_record(r), indent=2))
    if args.out:
        aligned = se3.transform_points(r.T_target_source, src)
        io.write_ply(Path(args.out), aligned[np.all(np.isfinite(aligned), axis=1)])
    return 0 if r.converged else 2


def _synthetic_overrides(args: argparse.Namespace) -> dict:
    """SyntheticConfig fields from --frames, --noise, --seed, --robot and --robot-base (None: not given)."""
    names = ("robot_x", "robot_y", "robot_z", "robot_roll", "robot_pitch", "robot_yaw")
    return {"n_frames": args.frames, "noise": args.noise, "seed": args.seed, "robot": args.robot,
            **dict(zip(names, map(float, args.robot_base or ())))}


def _load_source(source: str, args: argparse.Namespace) -> tuple:
    """(frames, the synthetic scan or None, a description) of a SOURCE argument
    (:func:`scanalign.datasets.open_source`)."""
    src = datasets.open_source(source, synthetic_overrides=_synthetic_overrides(args), intrinsics=args.intrinsics,
                               depth_scale=args.depth_scale, start=args.start, stride=args.frame_stride,
                               limit=args.limit)
    if not isinstance(src, synthetic.SyntheticScan):
        what = ("TUM RGB-D folder" if isinstance(src, datasets.TumSequence) else
                "ROS bag" if isinstance(src, datasets.BagSequence) else "image folder")
        return src, None, f"{what} {source}"
    what = "built-in synthetic scan" if source == "builtin" else f"synthetic scan from {source}"
    if src.robot is None:
        return src.frames, src, what + " (camera poses as planned, no robot)"
    p = src.T_base_robot[:3, 3]
    return src.frames, src, (f"{what} (camera on a {src.robot.name} based at ({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m, "
                             "poses from its forward kinematics)")


def _add_output_options(g, out: str, plots: Optional[str], quiet: str = "no progress bar", view: bool = False) -> None:
    g.add_argument("--out", default=out, help=f"output folder (default: {out})")
    if plots:
        g.add_argument("--no-plots", action="store_true", help=f"do not write {plots}")
    g.add_argument("--quiet", action="store_true", help=quiet)
    if view:
        g.add_argument("--view", action="store_true", help="stream the run to a rerun viewer (spawned, or one already "
                                                           "running; needs pip install rerun-sdk)")
        g.add_argument("--view-save", metavar="FILE.rrd", help="save the rerun recording of the run to this file")


def _add_synthetic_options(g) -> None:
    g.add_argument("--frames", type=int, help="number of frames around the object (builtin: 36)")
    g.add_argument("--noise", help="sensor noise preset: none, sr300, d435, zivid (builtin: sr300)")
    g.add_argument("--seed", type=int, help="random seed of the sensor noise (builtin: 0)")
    g.add_argument("--robot", help="robot arm that moves the camera: ur5 (default), ur3, ur10, ur3e, ur5e, ur10e, "
                                   "kr6_r900_sixx, or 'none' (the planned camera poses, no arm). An arm's joints "
                                   "come from IK (closest to the previous frame, rad, written to joints.csv), the "
                                   "reference poses from its forward kinematics")
    g.add_argument("--robot-base", type=float, nargs=6, metavar=("X", "Y", "Z", "ROLL", "PITCH", "YAW"),
                   help="the robot's base frame in the scene: position (m), roll, pitch, yaw (rad; R = Rz(yaw) "
                        "Ry(pitch) Rx(roll)); default 0.9 m above the object, hanging: OBJECT_X OBJECT_Y 0.9 "
                        "3.141592653589793 0 0")


def _box(values: Any) -> Any:
    return tuple(float(v) for v in values)


_Q = ("Q1", "Q2", "Q3", "Q4", "Q5", "Q6")  # the metavars of six joint values and of a box
_BOX = ("XMIN", "XMAX", "YMIN", "YMAX", "ZMIN", "ZMAX")
_F = "frame_to_model."
#: The reconstruct command's settings: one ReconstructionSettings; its flags are aliases of fields.
RECONSTRUCT = Command(ReconstructionSettings, (
    Alias("--min-depth", "min_depth", "depth images"),
    Alias("--max-depth", "max_depth", "depth images"),
    Alias("--pixel-stride", "pixel_stride", "depth images"),
    Alias("--crop", _F + "crop_box", "depth images", nargs=6, metavar=_BOX,
          value=_box, help="keep only points inside this box in camera coordinates (x right, y down, z forward)"),
    Alias("--depth-filter", "filter_depth", "reconstruction"),
    Alias("--normal-radius", _F + "normal_radius", "reconstruction"),
    Alias("--voxel", _F + "model_voxel_size", "reconstruction"),
    Alias("--frame-voxel", _F + "frame_voxel_size", "reconstruction"),
    Alias("--min-fitness", _F + "min_fitness", "reconstruction"),
    Alias("--no-require-convergence", _F + "require_convergence", "reconstruction", flag=False,
          help="accept registrations that hit the iteration cap"),
    Alias("--model-frame", "model_frame", "reconstruction", choices=["auto", "camera", "base"]),
    Alias("--initial-guess", _F + "motion_model", "reconstruction",
          choices=["previous", "constant_velocity", "reference"]),
    Alias("--registration", "registration", "registration",
          choices=["scanalign", "pcl_svd", "pcl_dual_quaternion", "pcl_point_to_plane_lls"]),
    Alias("--estimator", _F + "icp.estimator", "registration",
          choices=["point_to_plane", "point_to_point", "dual_quaternion"]),
    Alias("--max-distance", _F + "icp.max_correspondence_distance", "registration"),
    Alias("--max-iterations", _F + "icp.max_iterations", "registration"),
    Alias("--box", _F + "icp.box", "registration", nargs=6, metavar=_BOX,
          value=_box, help="box correspondence rejector in camera coordinates (eye-in-hand paper §3.4)"),
    Alias("--box-preset", _F + "icp.box", "registration", choices=["free_hand", "banana"],
          value=lambda name: getattr(Box, name + "_preset")(), help="the eye-in-hand paper's box rejector values"),
    Alias("--threads", _F + "num_threads", "registration"),
    Alias("--backend", _F + "icp.backend", "registration", choices=["cpu", "cuda"]),
))


_P = "pose."
#: The pose command's settings: FindObjectsSettings (table, clusters, the pose per cluster).
POSE = Command(_core.pose.FindObjectsSettings, (
    # --method sets the pose settings' method (a PCL baseline: method pcl and the thesis's preset of that baseline)
    Alias("--method", "pose", choices=list(_pose.METHODS),
          value=lambda name: to_dict(_pose.pose_task_settings(_pose.PoseSettings, method=name)),
          help="coarse alignment: cbd (the thesis's curvature-based descriptor), flags, or a stock PCL baseline "
               "(fpfh, fpfh_sac_ia, shot, 3dsc, ppf, pfh, rsd, gasd, vfh: method pcl with the thesis's preset); default cbd"),
    Alias("--cbd-radius", _P + "cbd.cbd.radius", help="CBD neighbourhood radius (about 0.015 for scans with ~1-2 mm "
                                                      "noise)"),
    Alias("--resolution", _P + "views.resolution"),
    Alias("--inlier-threshold", _P + "inlier_threshold"),
    Alias("--icp-distance", _P + "icp_distance"),
    Alias("--up", "table.up", nargs=3, metavar=("X", "Y", "Z"),
          help="table normal direction (0 0 0: towards the camera at the origin)"),
    Alias("--table-threshold", "table.plane.threshold"),
    Alias("--cluster-tolerance", "table.cluster_tolerance"),
    Alias("--max-objects", "max_objects"),
))


#: The pick command's settings: PickSettings (reconstruction, find_parts, views, planner).
PICK = Command(_pick.PickSettings)


def _register_root() -> dict:
    """The register command's settings: ICP (with a 5 cm correspondence distance: two
    independent scans, not consecutive frames) and the target's normals."""
    return {"icp": IcpSettings(max_correspondence_distance=0.05), "normals": NormalEstimationSettings()}


REGISTER = Command(_register_root, (
    Alias("--max-distance", "icp.max_correspondence_distance"),
    Alias("--max-iterations", "icp.max_iterations"),
    Alias("--estimator", "icp.estimator", choices=["point_to_plane", "point_to_point", "dual_quaternion"]),
    Alias("--normal-radius", "normals.radius"),
    Alias("--box", "icp.box", nargs=6, metavar=_BOX, value=_box, help="box rejector in the source camera frame"),
    Alias("--backend", "icp.backend", choices=["cpu", "cuda"]),
))

#: The commands whose settings are C++ structs (``--config``, ``--set``, ``dump-config``).
COMMANDS = {"reconstruct": RECONSTRUCT, "register": REGISTER, "pose": POSE, "pick": PICK, "assemble": ASSEMBLE}


def _viewer(args: argparse.Namespace) -> Any:
    """The rerun live view of ``--view`` / ``--view-save FILE.rrd`` (a context yielding None without either)."""
    return Viewer(spawn=args.view, save=args.view_save) if args.view or args.view_save else contextlib.nullcontext()


def reconstruct_command(args: argparse.Namespace) -> int:
    """``scanalign demo`` / ``reconstruct``: reconstruct SOURCE, write the outputs, print a summary."""
    t0 = time.perf_counter()
    frames, scan, what = _load_source("builtin" if args.command == "demo" else args.source, args)
    load_seconds = time.perf_counter() - t0
    if not args.quiet:
        n = len(frames) if hasattr(frames, "__len__") else "?"
        print(f"scanalign: reconstructing {what}: {n} frames"
              + (f" (rendered in {load_seconds:.2f} s)" if scan is not None else ""))
    with _viewer(args) as view, warnings.catch_warnings():
        warnings.simplefilter("ignore", ReconstructionFailed)  # said below, after the summary
        result = reconstruct(frames, args.settings, progress=not (args.no_progress or args.quiet),
                             on_frame=None if view is None else view.on_frame)
        if view is not None:
            view.log_reconstruction(result)
    if scan is not None:
        result.metrics["model_to_mesh_m"] = model_mesh_distance(result, scan.mesh.vertices, scan.mesh.faces)
        result.metrics["render_seconds"] = load_seconds
    paths = save_report(result, args.out, plots_too=not args.no_plots)
    if not args.quiet:
        _print_summary(result.summary(), paths)
    if (why := result.failure()) is not None:
        print(f"scanalign {args.command}: {why}", file=sys.stderr)
        return 1
    return 0


def _print_summary(summary: dict, paths: dict) -> None:
    def mm(v: Optional[float]) -> str:
        return "n/a" if v is None else f"{v * 1000:.2f} mm"

    print(f"  frames: {summary['frames']} given, {summary['merged']} merged"
          + (f", skipped {summary['skipped']}" if summary["skipped"] else ""))
    if summary.get("seconds_per_frame_median") is not None:
        print(f"  time per frame: median {summary['seconds_per_frame_median'] * 1000:.0f} ms "
              f"(max {summary['seconds_per_frame_max'] * 1000:.0f} ms), "
              f"median {summary['iterations_median']:.0f} ICP iterations; total {summary['seconds_total']:.1f} s")
    print(f"  model: {summary['model_points']} points")
    if "ate_m" in summary:
        print(f"  ATE: rmse {mm(summary['ate_m']['rmse'])}, max {mm(summary['ate_m']['max'])};  RPE (1 frame): rmse "
              f"{mm(summary['rpe_translation_m']['rmse'])}, {summary['rpe_rotation_deg']['rmse']:.3f} deg")
    if "model_to_mesh_m" in summary:
        q = summary["model_to_mesh_m"]
        print(f"  model to mesh: mean {mm(q['mean'])}, 95th percentile {mm(q['p95'])}")
    print("  wrote " + ", ".join(str(p) for p in paths.values()))


def _add_reconstruct_options(p: argparse.ArgumentParser, out_default: str) -> None:
    g = p.add_argument_group("output")
    _add_output_options(g, out_default, "trajectory.png / frames.png", quiet="print nothing but errors", view=True)
    g.add_argument("--no-progress", action="store_true", help="no progress bar")
    _add_synthetic_options(p.add_argument_group("synthetic scans (builtin or a config file)"))
    g = p.add_argument_group("real sequences (TUM RGB-D folder)")
    g.add_argument("--intrinsics", help="intrinsics preset (tum_fr1, tum_fr2, tum_fr3, tum_default, sr300, d435) or "
                                        "a JSON/YAML file with width height fx fy cx cy (pixels); default: the "
                                        "folder's camera.json/yaml")
    g.add_argument("--depth-scale", type=float, help="metres per depth-PNG unit (TUM: 0.0002 = 1/5000)")
    g.add_argument("--start", type=int, default=0, help="first frame to use (default 0)")
    g.add_argument("--frame-stride", type=int, default=1, help="use every n-th frame (default 1)")
    g.add_argument("--limit", type=int, help="use at most this many frames")
    add_settings_options(p, RECONSTRUCT)


def synth(args: argparse.Namespace) -> int:
    """``scanalign synth``: render a synthetic scan into a TUM RGB-D folder, a ROS bag or a PNG folder."""
    scan = datasets.open_source(args.config, synthetic_overrides=_synthetic_overrides(args))
    if not isinstance(scan, synthetic.SyntheticScan):
        raise ValueError(f"{args.config}: expected a synthetic config file (.json/.yaml) or 'builtin'")
    extra, layout = "", {"tum": "TUM RGB-D layout, ground truth included", "bag": "ROS bag, ground truth in /tf",
                         "png": "PNG image folder, ground truth in groundtruth.txt"}
    if args.format == "bag":
        folder = datasets.sources.write_bag(args.out, scan.frames)
        extra = "" if scan.joints is None else f", {scan.robot.name} joints in /joint_states (rad)"
    else:
        write = tum.write_tum_sequence if args.format == "tum" else datasets.sources.write_image_folder
        folder = write(args.out, scan.frames, intrinsics=scan.intrinsics, depth_scale=scan.frames[0].depth_scale)
        if scan.joints is not None:
            write_joints_csv(Path(folder) / "joints.csv", [f.index for f in scan.frames],
                             [f.timestamp for f in scan.frames], scan.joints)
            extra = f", {scan.robot.name} joints in joints.csv (rad)"
    print(f"scanalign: wrote {len(scan.frames)} frames to {folder} ({layout[args.format]}{extra})")
    return 0


def ik_command(args: argparse.Namespace) -> int:
    """``scanalign ik``: every inverse-kinematics solution of one tool pose, labelled."""
    robot = kin.Robot.by_name(args.robot)
    if (args.pose is None) == (args.joints is None):
        raise ValueError("give exactly one of --pose X Y Z RX RY RZ or --joints Q1 ... Q6")
    if args.joints is not None:
        q_in = np.asarray(args.joints, dtype=np.float64)
        T, source = robot.fk(q_in), f"FK of q = {np.array2string(q_in, precision=4)} rad"
    else:
        v = np.asarray(args.pose, dtype=np.float64)
        if not np.all(np.isfinite(v)):
            raise ValueError("--pose: non-finite value")
        theta = float(np.linalg.norm(v[3:]))  # rotation vector: axis * angle
        T, source = se3.rigid(v[3:] if theta > 0 else (0.0, 0.0, 1.0), theta, v[:3]), "the given pose"
    sol = robot.ik(T, respect_limits=not args.ignore_limits)
    p = T[:3, 3]
    print(f"{robot.name} ({robot.geometry}): tool at ({p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f}) m in the robot base "
          f"frame ({source})")
    print("  k  shoulder elbow wrist  status           q1..q6 [rad]                                   |FK(q)-T|")
    labels = []
    for k in range(8):
        s_, e_, w_ = (int(x) for x in sol.config[k])
        labels.append(f"shoulder {s_:+d} elbow {e_:+d} wrist {w_:+d}")
        line = f"  {k}  {s_:+d}       {e_:+d}    {w_:+d}     {sol.status[k]:<16}"
        if np.all(np.isfinite(sol.q[k])):
            err = float(np.abs(robot.fk(sol.q[k]) - T).max())
            line += " " + " ".join(f"{x:+7.4f}" for x in sol.q[k]) + f"   {err:.1e}"
        if sol.singular[k]:
            line += "  singular: " + ",".join(sol.singular[k])
        if sol.unreachable_step[k]:
            line += f"  ({sol.unreachable_step[k]} point pair imaginary)"
        print(line)
    print(f"  {len(sol)} solution(s) ok, {len(sol.distinct())} distinct")
    if args.closest is not None:
        best = robot.ik_closest(T, np.asarray(args.closest, dtype=np.float64), respect_limits=not args.ignore_limits)
        print(f"  closest to {np.array2string(np.asarray(args.closest), precision=4)}: {best.status}"
              + (" q = " + " ".join(f"{x:+.4f}" for x in best.q) if best.ok else ""))
    if args.plot:
        path = plots.plot_arm_configurations(robot, sol.q, args.plot, labels=labels, T_base_tool=T,
                                             title=f"{robot.name}: inverse kinematics solutions")
        print(f"  wrote {path}")
    return 0 if len(sol) else 1


def _existing(path: str, what: str) -> Path:
    if not Path(path).exists():
        raise FileNotFoundError(f"{path}: no such {what} file")
    return Path(path)


def pose_command(args: argparse.Namespace) -> int:
    """``scanalign pose``: find a CAD part in a scan; exit status 1 when no object is found."""
    if not (np.isfinite(args.model_scale) and args.model_scale > 0):
        raise ValueError(f"--model-scale must be a finite factor > 0, got {args.model_scale}")
    model = read_model(_existing(args.model, "model"))  # a mesh, or a model cloud (PCD, face-less PLY)
    if args.model_scale != 1.0:
        model = (model._replace(points=model.points * args.model_scale) if isinstance(model, Cloud)
                 else io.Mesh(np.asarray(model.vertices) * args.model_scale, model.faces))
    scene, _ = io.read_cloud(_existing(args.scene, "scene"))
    scene = scene[np.all(np.isfinite(scene), axis=1)]
    if args.no_segment:
        results = [_pose.estimate_pose(model, scene, args.settings.pose, views=args.views, progress=not args.quiet)]
        objects = [np.arange(len(scene))]
    else:
        found = _pose.find_objects(model, scene, args.settings, views=args.views, progress=not args.quiet)
        results, objects = found.poses, found.objects
        if not results:
            print("scanalign pose: no object cluster above the table", file=sys.stderr)
    (out := Path(args.out)).mkdir(parents=True, exist_ok=True)
    report = []
    for k, (r, idx) in enumerate(zip(results, objects)):
        report.append({**r.as_dict(), "object": k, "object_points": int(len(idx))})
        print(f"object {k} ({len(idx)} points): {'found' if r.found else 'not found'} with {r.method}, view "
              f"{r.view}, fitness {r.fitness:.3f}, coverage {r.coverage:.3f}, inlier RMSE "
              f"{1000 * r.inlier_rmse:.3f} mm, {r.seconds:.2f} s" + ("" if r.found else f" ({r.message})"))
        if r.found:
            print("  T_scene_model =\n" + np.array2string(np.asarray(r.T_scene_model), precision=6,
                                                           suppress_small=True, prefix="  "))
            paths = write_pose_outputs(model, scene, r, out / f"object{k}", object_indices=idx)
            report[-1].update({key: str(v) for key, v in paths.items()})
    (out / "poses.json").write_text(json.dumps(report, indent=2))
    print(f"wrote {out / 'poses.json'}")
    return 0 if any(r.found for r in results) else 1


def pick_command(args: argparse.Namespace) -> int:
    """``scanalign pick``: scan -> part poses -> grasps -> joint targets; exit status 1 when nothing can be picked."""
    truth = None
    if args.q_current is not None and not np.all(np.isfinite(args.q_current)):
        raise ValueError(f"--q-current {' '.join(f'{q:g}' for q in args.q_current)}: joint values must be finite (rad)")
    if args.demo:
        cell = pick_cell(args.robot or "ur5", noise=args.noise or "sr300", seed=args.seed or 0)
        scene, parts, robot, T_base_robot, T_fc, truth = cell.scan, cell.parts, cell.robot, None, None, cell.truth
        print(f"scanalign pick: built-in cell: {cell.robot.name}, {len(cell.parts)} parts on the table, "
              f"{len(cell.scan)} frames with {args.noise or 'sr300'} noise")
    else:
        scene, parts, robot = args.scene, args.parts, args.robot
        T_base_robot = _pick.read_transform(args.robot_base, "--robot-base")
        T_fc = _pick.read_transform(args.hand_eye, "--hand-eye")
    with _viewer(args) as view:  # the demo (scanalign demo --pick) has no settings: the defaults
        result = _pick.pick(scene, parts, robot, T_base_robot=T_base_robot, T_flange_camera=T_fc, joints=args.joints,
                            q_current=args.q_current, settings=getattr(args, "settings", None),
                            progress=not args.quiet, viewer=view)
    _pick.print_picks(result)
    if truth is not None:
        for name, e in score_picks(result, truth).items():
            print(f"  {name}: TCP at the chosen grasp {1000 * e['tcp_m']:.3f} mm / {e['tcp_deg']:.3f} deg "
                  f"from the true grasp; part pose {1000 * e['pose_m']:.3f} mm / {e['pose_deg']:.3f} deg")
    paths = save_report(result, args.out, plots_too=not args.no_plots)
    print("wrote " + ", ".join(str(p) for p in paths.values()))
    return 0 if any(p.status == "picked" for p in result.picks) else 1


def demo_command(args: argparse.Namespace) -> int:
    """``scanalign demo``: the built-in reconstruction, or with ``--pick`` the pick demo."""
    if not args.pick:
        return reconstruct_command(args)
    # pick --demo with demo's --robot, --noise, --seed and output flags; no settings: the defaults
    vars(args).update(demo=True, noise=args.noise or "sr300", seed=args.seed or 0, q_current=None, joints=None,
                      settings=None, out=args.out if args.out != "scanalign-demo" else "scanalign-pick")
    return pick_command(args)


def _add_pick_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--demo", action="store_true", help="the built-in cell (a UR5 or the KR6, three parts)")
    p.add_argument("--scene", help="TUM RGB-D folder (with --joints), or a PLY / PCD cloud in the base frame")
    p.add_argument("--parts", nargs="+", help="part files (JSON / YAML: mesh, grasps, symmetry) or built-in "
                                              "part names (block, bracket, standoff)")
    p.add_argument("--joints", help="joint log of the scan (index,timestamp,q1..q6; as 'scanalign synth' writes)")
    p.add_argument("--hand-eye", help="text file: T_flange_camera, 4x4 (camera -> flange, m)")
    p.add_argument("--robot-base", help="text file: T_base_robot, 4x4 (robot base -> cell base, m)")
    p.add_argument("--robot", help="the arm: ur5, kr6_r900_sixx, ... (demo: ur5)")
    p.add_argument("--noise", choices=["sr300", "zivid", "d435", "none"], help="demo: sensor noise preset (sr300)")
    p.add_argument("--seed", type=int, help="demo: noise seed (0)")
    p.add_argument("--q-current", type=float, nargs=6, metavar=_Q,
                   help="the robot's joints now, rad (default: the scan's last)")
    _add_output_options(p, "scanalign-pick", "pick.png", quiet="no progress bars", view=True)
    add_settings_options(p, PICK)


def batch_command(args: argparse.Namespace) -> int:
    """``scanalign batch``: every job of a manifest on a process pool or Ray; exit status 1
    when a job failed or crashed."""
    jobs = batch.read_manifest(args.manifest)
    if not args.quiet:
        print(f"scanalign batch: {len(jobs)} jobs from {args.manifest} on {args.executor}")
    result = batch.run_batch(jobs, args.out, executor=args.executor, workers=args.workers, address=args.address,
                             threads_per_job=args.threads_per_job, retries=args.retries, progress=not args.quiet)
    if not args.no_plots:
        save_report(result, args.out)
    s = batch.summarize(result)
    print(f"  {s['executor']}: {s['jobs']} jobs ({s['skipped_as_done']} done before), status {s['status']}, "
          f"{s['wall_seconds']:.1f} s" + (f", {s['jobs_per_minute']:.1f} jobs/min" if s["jobs_per_minute"] else ""))
    for kind, k in s["kinds"].items():
        extra = ", ".join(f"{key[:-7]} {v * (1000 if key.endswith('_m_median') else 1):.3g}"
                          + (" mm" if key.endswith("_m_median") else " deg" if "deg" in key else "")
                          for key, v in k.items() if key.endswith("_median") and key != "seconds_median")
        print(f"  {kind}: {k['ok']}/{k['jobs']} ok, median {k['seconds_median']:.2f} s per job"
              + (f"; medians: {extra}" if extra else ""))
    for job_id, error in s["failures"].items():
        print(f"  {job_id}: {error}", file=sys.stderr)
    print("wrote " + ", ".join(str(p) for p in result.paths.values()))
    if not result.ok:
        print(f"scanalign batch: {s['verdict']}", file=sys.stderr)
    return 0 if result.ok else 1


def _writable(path: str, flag: str, folder: bool = True) -> None:
    """Refuses an output that cannot be written before the run, not after it."""
    target = Path(path) if folder else Path(path).parent
    existing = next(p for p in (target, *target.parents) if p.exists())
    if not existing.is_dir() or not os.access(existing, os.W_OK):
        raise ValueError(f"{flag} {path}: {existing} is {'not a folder' if not existing.is_dir() else 'read-only'}")


def _given(args: argparse.Namespace, *flags: str) -> list:
    """Those of ``flags`` given on the command line (their value not None, [] or the default)."""
    defaults = {"--start": 0, "--frame-stride": 1}
    return [f for f in flags if getattr(args, f[2:].replace("-", "_"), None) not in (None, [], defaults.get(f))]


def _preflight(args: argparse.Namespace) -> None:
    """The checks that need no work, so that a mistake stops a command in its first second: outputs
    that cannot be written, inputs missing or unknown, options that do not apply to the source."""
    for flag, path, folder in (("OUT" if args.command == "synth" else "--out", getattr(args, "out", None),
                                args.command != "register"), ("--view-save", getattr(args, "view_save", None), False)):
        if path:
            _writable(path, flag, folder)
    demo = getattr(args, "demo", True)  # demo --pick too
    if (args.command == "pick" or args.command == "demo" and args.pick) and demo:
        if extra := _given(args, "--scene", "--parts", "--joints", "--hand-eye", "--robot-base", "--frames", "--limit"):
            raise ValueError(f"{extra[0]} does not apply to the built-in pick cell (--demo)")
    elif args.command == "pick":
        if missing := [f for f in ("--scene", "--parts", "--robot") if not _given(args, f)]:
            raise ValueError(f"missing {', '.join(missing)}: pick needs --scene, --parts and --robot (or --demo)")
        if extra := _given(args, "--noise", "--seed"):
            raise ValueError(f"{extra[0]} applies to --demo only")
        if args.joints and not Path(args.joints).is_file():
            raise FileNotFoundError(f"--joints {args.joints}: no such file")
    elif args.command in ("demo", "reconstruct"):
        source = "builtin" if args.command == "demo" else args.source
        if args.intrinsics and args.intrinsics not in INTRINSICS_PRESETS and not Path(args.intrinsics).is_file():
            raise ValueError(f"--intrinsics {args.intrinsics!r}: neither a preset ({', '.join(INTRINSICS_PRESETS)}) "
                             "nor a camera file")
        if source == "builtin" or Path(source).is_file() and Path(source).suffix.lower() in datasets.SYNTHETIC_SUFFIXES:
            if extra := _given(args, "--intrinsics", "--depth-scale", "--start", "--frame-stride", "--limit"):
                raise ValueError(f"{extra[0]} applies to recordings (TUM RGB-D folder, bag, image folder), not to the "
                                 f"synthetic scan {source!r}: its camera and frames are set in a synthetic config file")
        elif extra := _given(args, "--frames", "--noise", "--seed", "--robot", "--robot-base"):
            raise ValueError(f"{extra[0]} applies to synthetic scans ('builtin' or a config file), not to {source!r}")


def _record_config(args: argparse.Namespace, rc: int) -> int:
    """Writes the settings a run used beside its outputs (``config.yaml`` in ``--out``; ``register``:
    ``NAME.config.yaml`` beside ``--out NAME.ply``, none without ``--out``); returns ``rc``."""
    if args.command not in COMMANDS or not args.out:
        return rc
    path = Path(args.out).with_suffix(".config.yaml") if args.command == "register" else Path(args.out) / "config.yaml"
    inputs = [a for a in (getattr(args, "source", None), getattr(args, "target", None)) if a]
    write_effective(args.command, args.settings, args, inputs, path)
    if args.command != "register" and not args.quiet:  # register's stdout is JSON
        print(f"  wrote {path} (the settings of this run: --config {path} repeats it)")
    return rc


def _dump_config(args: argparse.Namespace) -> int:
    print(dump(args.config_command, COMMANDS[args.config_command].root()), end="")
    return 0


def _register_demo(args: argparse.Namespace) -> int:
    register_demo(Path(args.out), seed=args.seed, noise=args.noise)
    return 0


#: What each command runs: ``(args) -> exit status``.
HANDLERS = {"demo": demo_command, "pick": pick_command, "reconstruct": reconstruct_command, "synth": synth,
            "register": register, "register-demo": _register_demo, "ik": ik_command, "pose": pose_command,
            "batch": batch_command, "dump-config": _dump_config, "assemble": assemble_command}


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="scanalign", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    pcl = "with the PCL baselines" if _core.built_with_pcl else "without PCL (SCANALIGN_WITH_PCL=OFF)"
    pcl += ", with the CUDA backend" if _core.built_with_cuda else ", without the CUDA backend (SCANALIGN_WITH_CUDA)"
    parser.add_argument("--version", action="version", version=f"scanalign {_core.__version__} ({pcl})",
                        help="print the version and whether the PCL baselines and the CUDA backend are built, then "
                             "exit")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    p = sub.add_parser("demo", help="reconstruct a built-in synthetic eye-in-hand scan (no download needed)",
                       description="Renders a built-in synthetic scan (a camera on a UR5's hand circling a part, "
                                   "SR300-like noise, reference poses from forward kinematics), reconstructs it and "
                                   "writes model.ply, trajectory.txt, reference.txt, frames.csv, joints.csv, "
                                   "report.json, trajectory.png and frames.png. The library's default settings, frames "
                                   "cropped to the part's workspace (fast: no table in the model). Exit status 1 when "
                                   "fewer than min_merged_fraction of the frames merged.")
    _add_reconstruct_options(p, "scanalign-demo")
    p.add_argument("--pick", action="store_true", help="instead: the pick demo (as 'scanalign pick --demo')")
    p = sub.add_parser("pick", help="scan, find the known parts, plan grasps and joint targets to pick them",
                       description="Reconstructs the scan in the robot's base frame (frames placed by forward "
                                   "kinematics and the hand-eye transform, refined by ICP), finds each known part "
                                   "and plans its grasp: every grasp, symmetric copy and IK branch, rejected with a "
                                   "reason or ranked by joint motion. Writes picks.json, joints.csv, scene.ply and "
                                   "pick.png. Exit status 1 when nothing can be picked.")
    _add_pick_options(p)
    add_assemble_parser(sub)
    p = sub.add_parser("reconstruct", help="reconstruct a TUM RGB-D folder, a ROS bag, a PNG folder or a synthetic scan",
                       description="Frame-to-model reconstruction (Algorithm 1 of the eye-in-hand paper) of SOURCE: "
                                   "a TUM RGB-D folder (depth/, rgb/, depth.txt, rgb.txt, optional "
                                   "groundtruth.txt), a ROS 1 .bag or ROS 2 bag (depth, colour, camera_info, "
                                   "/joint_states, /tf; RealSense recordings too), a folder of PNG depth and colour "
                                   "images with a camera YAML, a synthetic-scan config (.json/.yaml), or 'builtin'. "
                                   "Writes the outputs of 'scanalign demo'. Exit status 1 when fewer than "
                                   "min_merged_fraction of the frames merged.")
    p.add_argument("source", help="TUM RGB-D folder, ROS bag, PNG folder, synthetic config file, or 'builtin'")
    _add_reconstruct_options(p, "scanalign-out")
    p = sub.add_parser("synth", help="render a synthetic scan into a TUM RGB-D folder, a ROS bag or a PNG folder")
    p.add_argument("config", help="synthetic config file (.json/.yaml) or 'builtin'")
    p.add_argument("out", help="output folder (--format bag: a ROS 1 file when it ends in .bag, else a ROS 2 bag)")
    p.add_argument("--format", choices=["tum", "bag", "png"], default="tum",
                   help="tum: a TUM RGB-D folder (default); bag: a ROS bag (needs rosbags); png: a folder of "
                        "depth/ and rgb/ PNGs with camera.json")
    _add_synthetic_options(p)
    p = sub.add_parser("register", help="ICP between two clouds (PCD or PLY, metres)")
    p.add_argument("source", help="source cloud (its camera frame)")
    p.add_argument("target", help="target cloud (the model frame); normals are estimated if absent")
    p.add_argument("--init", help="text file with the initial 4x4 T_target_source (default identity)")
    p.add_argument("--out", help="write the aligned source cloud to this PLY file")
    add_settings_options(p, REGISTER)
    p = sub.add_parser("register-demo", help="register one simulated frame with scanalign and stock PCL")
    p.add_argument("--out", default="scanalign-register-demo", help="output folder")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--noise", type=float, default=0.0005, help="depth noise sigma in metres (default 0.0005)")
    p = sub.add_parser("ik", help="all analytic inverse-kinematics solutions of a tool pose (CGA, thesis Paper 1)",
                       description="Prints every inverse-kinematics solution (up to 8) of one tool pose with its "
                                   "configuration labels (shoulder front/back, elbow up/down, wrist flip), status "
                                   "and forward-kinematics check. Exit status 1 when no solution is ok.")
    p.add_argument("--robot", default="ur5", help="ur5 (default), ur3, ur10, ur3e, ur5e, ur10e, ur5_thesis, "
                                                  "kr6_r900_sixx")
    p.add_argument("--pose", type=float, nargs=6, metavar=("X", "Y", "Z", "RX", "RY", "RZ"),
                   help="tool pose in the robot base frame: position (m) and rotation vector (axis times angle, "
                        "rad), as a UR controller shows it")
    p.add_argument("--joints", type=float, nargs=6, metavar=_Q, help="use the pose of these joint values (radians, "
                                                                     "forward kinematics)")
    p.add_argument("--closest", type=float, nargs=6, metavar=_Q, help="also print the solution nearest these joints "
                                                                      "(radians)")
    p.add_argument("--ignore-limits", action="store_true", help="ignore the joint limits")
    p.add_argument("--plot", help="write a PNG with every configuration drawn as a stick figure")
    p = sub.add_parser("pose", help="find a CAD part in a scan (CBD or a PCL baseline, then ICP; thesis ch. 6)",
                       description="Segments the table (CGA RANSAC), clusters the objects, matches the model's "
                                   "42 tessellated-sphere views to each object (curvature-based descriptor or a "
                                   "stock PCL baseline), refines with ICP and reports T_scene_model (scene <- "
                                   "model), fitness, RMSE and time. Writes poses.json, the aligned model as PLY "
                                   "and a PNG overlay per object. Exit status 1 when nothing is found.")
    p.add_argument("--model", required=True, help="the part: a CAD mesh (STL, PLY, OFF, OBJ) or a scanned model cloud "
                                                  "(PCD, PLY without faces; whole or partial); metres, or see "
                                                  "--model-scale")
    p.add_argument("--scene", required=True, help="scan: PCD or PLY, metres, camera frame")
    p.add_argument("--model-scale", type=float, default=1.0, help="multiply the model's coordinates (0.001: mm)")
    p.add_argument("--views", type=int, nargs="+", help="only these of the 42 views (default all)")
    p.add_argument("--no-segment", action="store_true", help="the scene is one object: skip table and clusters")
    _add_output_options(p, "scanalign-pose", None)
    add_settings_options(p, POSE)
    p = sub.add_parser("batch", help="run a manifest of reconstruction, pose and pick jobs (process pool or Ray)",
                       description="Runs every job of MANIFEST (YAML or CSV, see docs/batch.md) on a local process "
                                   "pool or a Ray cluster, the part library built once and shared; writes "
                                   "results.csv, results.parquet, summary.json and results.png into --out. A re-run "
                                   "with the same --out skips the jobs already done. Exit status 1 when a job failed "
                                   "or crashed, 2 on an error (a malformed manifest, workers that cannot start).")
    p.add_argument("manifest", help="manifest file (.yaml/.yml or .csv)")
    p.add_argument("--executor", choices=["local", "ray"], default="local", help="where the jobs run (local)")
    p.add_argument("--address", help="Ray cluster address ('auto', 'ray://head:10001'); default: a local Ray instance")
    p.add_argument("--workers", type=int, help="parallel jobs (default: cores / --threads-per-job)")
    p.add_argument("--threads-per-job", type=int, default=1, help="OpenMP threads (and Ray CPUs) per job (1)")
    p.add_argument("--retries", type=int, default=1, help="times a failed or crashed job is tried again (1)")
    _add_output_options(p, "scanalign-batch", "results.png")
    p = sub.add_parser("dump-config", help="print every setting of a command with its default and unit (YAML)",
                       description="Prints every field of the C++ settings structs COMMAND uses as nested YAML, "
                                   "with its default, unit and meaning. Pass an edited copy back with 'scanalign "
                                   "COMMAND ... --config FILE'; flags and --set PATH=VALUE override the file. Every "
                                   "run of these commands writes the settings it used beside its outputs "
                                   "(config.yaml in --out; register: NAME.config.yaml beside --out).")
    p.add_argument("config_command", metavar="COMMAND", choices=tuple(COMMANDS), help="one of " + ", ".join(COMMANDS))
    args = parser.parse_args(argv)
    try:
        if args.command in COMMANDS or args.command == "demo":
            args.settings = resolve(COMMANDS.get(args.command, RECONSTRUCT), args,
                                    DEMO_SETTINGS if args.command == "demo" else None)
        _preflight(args)
        return _record_config(args, HANDLERS[args.command](args))
    except (ValueError, TypeError, OSError, RuntimeError, ImportError) as e:  # OSError: unreadable input, unwritable output
        print(f"scanalign {args.command}: error: {e}", file=sys.stderr)
        return 2

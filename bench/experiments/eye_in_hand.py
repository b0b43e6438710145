"""The eye-in-hand paper's experiments (Comput. Electron. Agric. 180 (2021) 105929, §4): Figs. 4-9 and
Table 1, on the synthetic eye-in-hand cell.

A camera circles the object on the table on one loop (Fig. 4), 40 cm above it and looking at it, and
every frame is registered frame-to-model by each ICP variant of the paper and merged (no rejection):

- (a) scanalign's k-d tree with Low's point-to-plane LLS (the paper's method);
- (b) scanalign's k-d tree with Walker's dual-quaternion point-to-point estimator;
- (c) PCL 1.13 ICP with SVD, (d) PCL 1.13 ICP with its dual-quaternion estimator;
- (e), (f): the paper's GPU variants: no CUDA backend yet (issue 29), so their lines are empty;
- extra lines: PCL's own LLS (IterativeClosestPointWithNormals), scanalign's library defaults
  (ReconstructionSettings()), Open3D's and small_gicp's point-to-plane ICP in the same frame loop.

The paper's settings (§3): 1 mm voxel grids, PCA normals of radius 5 mm, the previous pose as the
initial guess, PCL's convergence rules (transformation and fitness epsilon 1e-8, at most 50
iterations), no depth filter, and the correspondence box of §3.4 sized to the object (the paper's
banana box is +-5 cm around an object of about 8 cm). Why the box matters: see ``box_cause``.
"""

from __future__ import annotations

import hashlib
import math
import os
import pickle
import time
from pathlib import Path
from typing import Dict, List, Optional, Sequence

import numpy as np

from scanalign import synthetic
from scanalign.evaluation import absolute_trajectory_error, relative_pose_error
from scanalign.evaluation.mesh_distance import mesh_distance_stats
from scanalign.reconstruction import FrameToModelSettings, Reconstructor, depth_to_cloud

from . import Check, Log, Section

COMMAND = "python bench/reproduce.py --only eye_in_hand"
# Variant -> how it registers. "registration"/"estimator": the reconstructor's; "peer": another
# library's ICP inside the same frame loop; "defaults": scanalign's library defaults.
PAPER_VARIANTS = {
    "(a) k-d tree, LLS": dict(registration="scanalign", estimator="point_to_plane"),
    "(b) k-d tree, dual quaternion": dict(registration="scanalign", estimator="dual_quaternion"),
    "(c) PCL, SVD": dict(registration="pcl_svd"),
    "(d) PCL, dual quaternion": dict(registration="pcl_dual_quaternion"),
}
EXTRA_VARIANTS = {
    "PCL LLS (ICPWithNormals)": dict(registration="pcl_point_to_plane_lls"),
    "scanalign defaults": dict(defaults=True),
    "Open3D point-to-plane": dict(peer="open3d"),
    "small_gicp PLANE_ICP": dict(peer="small_gicp"),
}
GPU_NOTE = ("(e) GPU dual quaternion and (f) GPU LLS: no line; scanalign has no CUDA backend yet (issue 29), "
            "so the paper's GPU curves cannot be reproduced here.")
# Table 1 of the paper (ATE, RPE in cm, real SR300 scans of fruit on a Franka Panda).
PAPER_TABLE1 = {"(a) apple": (4.27, 2.36), "(b) banana": (3.29, 2.75), "(c) fruits": (3.80, 2.32)}
# Our three objects of different shape and size: name -> (mesh, largest extent in m).
OBJECTS = {"machined part": ("builtin", 0.08), "bunny": ("bunny00", 0.07), "elephant": ("elephant", 0.16)}


def object_box(size: float) -> tuple:
    """The §3.4 correspondence box in the camera frame, sized to the object: +-5 cm for the 8 cm
    part, as the paper's banana box; near and far planes as the paper's (0.1 mm, 10 m)."""
    h = 0.625 * size
    return (-h, h, -h, h, 0.0001, 10.0)


class Setup:
    """Sizes of one run: full (the paper's grid) or quick (CI: fewer points on each curve, PCL only where it
    is cheap; PCL's ICP is 2-10x slower than the engine, see Figs. 5-6)."""

    def __init__(self, quick: bool):
        self.quick = quick
        self.scale = 0.5  # image resolution relative to the SR300's 640x480 (PCL's baselines stay within minutes)
        self.images = (8, 36) if quick else (4, 8, 17, 34, 69)
        self.caps = (8, 128) if quick else (1, 2, 4, 8, 16, 32, 64, 128)
        # PCL's point-to-point runs equal (b)'s (same estimators, checked below) at 2-10x the time:
        # they run where that stays within minutes.
        self.pcl_images = self.images[:1] if quick else (4, 8, 17)
        self.pcl_caps = () if quick else (1, 2, 4, 8, 16, 32)
        self.cap_images = 18  # Figs. 6 and 9
        self.table_images = 18 if quick else 36
        self.cap = 50  # §3.3
        # Figs. 5 and 7: the paper does not state their cap; §3.3's 50 leaves point-to-point short of
        # convergence (Fig. 9), so the full run gives every variant 128, the largest of Fig. 6.
        self.images_cap = 50 if quick else 128
        # Frames cropped to +-15 cm around the optical axis (the object is centred, §4.2.1): the
        # table beyond is never inside the box and would only slow PCL's baselines down.
        self.crop = (-0.15, 0.15, -0.15, 0.15, 0.1, 1.0)


_SCANS: Dict[tuple, object] = {}


def make_scan(mesh: str, size: float, n: int, setup: Setup):
    key = (mesh, size, n, setup.scale)
    if key not in _SCANS:
        _SCANS[key] = synthetic.SyntheticConfig(mesh=mesh, object_size=size, n_frames=n, trajectory="loop",
                                                noise="sr300", seed=0, resolution_scale=setup.scale).build()
    return _SCANS[key]


def paper_reconstructor(scan, variant: dict, cap: int, box: Optional[tuple], setup: Setup) -> Reconstructor:
    """The paper's pipeline (FrameToModelSettings' defaults are §3's values), every registration merged."""
    T0 = scan.frames[0].T_base_camera
    if variant.get("defaults"):
        return Reconstructor(T_model_camera0=T0, crop_box=setup.crop, min_merged_fraction=0.0)
    icp = dict(max_iterations=cap, box=box)
    if variant.get("registration", "scanalign") == "scanalign" and "estimator" in variant:
        icp["estimator"] = variant["estimator"]
    return Reconstructor(FrameToModelSettings(), T_model_camera0=T0, registration=variant.get("registration",
                         "scanalign"), icp=icp, depth_filter=None, crop_box=setup.crop, min_fitness=0.0,
                         require_convergence=False, max_translation_change=math.inf, max_rotation_change=math.inf,
                         min_merged_fraction=0.0)


def _peer_icp(peer: str, src: np.ndarray, model: np.ndarray, normals: np.ndarray, init: np.ndarray, cap: int,
              distance: float):
    """One registration by another library: (T_model_camera, iterations or None, seconds). The time is the
    tree build and ICP, as the engine's; small_gicp's normal estimation (its Python API takes no given
    normals) is left out."""
    if peer == "open3d":
        import open3d as o3d
        reg = o3d.pipelines.registration
        s, t = o3d.geometry.PointCloud(), o3d.geometry.PointCloud()
        s.points = o3d.utility.Vector3dVector(src.astype(np.float64))
        t.points = o3d.utility.Vector3dVector(model.astype(np.float64))
        t.normals = o3d.utility.Vector3dVector(normals.astype(np.float64))
        t0 = time.perf_counter()
        r = reg.registration_icp(s, t, distance, init, reg.TransformationEstimationPointToPlane(),
                                 reg.ICPConvergenceCriteria(max_iteration=cap))
        return np.asarray(r.transformation), None, time.perf_counter() - t0
    import small_gicp as sg
    target = sg.PointCloud(model.astype(np.float64))
    sg.estimate_normals(target, sg.KdTree(target, 2), num_neighbors=20, num_threads=2)
    t0 = time.perf_counter()
    tree = sg.KdTree(target, 2)
    r = sg.align(target, sg.PointCloud(src.astype(np.float64)), tree, init_T_target_source=init,
                 registration_type="PLANE_ICP", max_correspondence_distance=distance, max_iterations=cap,
                 num_threads=2)
    return np.asarray(r.T_target_source), int(r.iterations), time.perf_counter() - t0


def _in_box(points: np.ndarray, box: Optional[tuple]) -> np.ndarray:
    if box is None:
        return points
    lo, hi = np.array(box[0::2]), np.array(box[1::2])
    return points[np.all((points >= lo) & (points <= hi), axis=1)]


def run_loop(scan, variant: dict, cap: int, box: Optional[tuple], setup: Setup) -> dict:
    """One loop: ATE and RPE (m) against the exact camera poses, registration time (s, tree build and ICP,
    summed over the frames; normals and merging excluded, as the paper's), mean iterations, the model.
    With SCANALIGN_REPRO_CACHE=folder, results are kept there and reused (to redo the report's text
    without rerunning the loops)."""
    folder = os.environ.get("SCANALIGN_REPRO_CACHE")
    if not folder:
        return _run_loop(scan, variant, cap, box, setup)
    key = repr((len(scan.frames), scan.object_mesh.vertices.shape, float(scan.object_mesh.vertices.max()),
                sorted(variant.items()), cap, box, setup.scale, setup.crop))
    path = Path(folder) / (hashlib.sha1(key.encode()).hexdigest() + ".pkl")
    if path.exists():
        return pickle.loads(path.read_bytes())
    out = _run_loop(scan, variant, cap, box, setup)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps(out))
    return out


def _run_loop(scan, variant: dict, cap: int, box: Optional[tuple], setup: Setup) -> dict:
    rec = paper_reconstructor(scan, variant, cap, box, setup)
    peer = variant.get("peer")
    register_s, iterations, poses = 0.0, [], []
    for i, frame in enumerate(scan.frames):
        if peer is None:
            r = rec.integrate(frame)
            if i:
                register_s += r.register_seconds
                iterations.append(r.icp.iterations)
            poses.append(np.asarray(r.T_model_camera))
            continue
        # A peer: the same prepared frame (crop, 1 mm grid, 5 mm normals) and the same model;
        # no box rejector in the peers, so the source is cut to the box (the box is fixed in
        # the source's camera frame, so this keeps the same points).
        points, _ = depth_to_cloud(frame.depth, frame.intrinsics, depth_scale=frame.depth_scale,
                                   min_depth=rec.job.min_depth, max_depth=rec.job.max_depth)
        prepared = rec._core.prepare(points, None)
        if not i:
            T = scan.frames[0].T_base_camera
        else:
            model, normals = rec._core.model_points(), rec._core.model_normals()
            ok = np.all(np.isfinite(normals), axis=1)
            T, its, seconds = _peer_icp(peer, _in_box(np.asarray(prepared.points), box), model[ok], normals[ok],
                                        poses[-1], cap, rec.settings.icp.max_correspondence_distance)
            register_s += seconds
            iterations.append(its if its is not None else math.nan)
        rec._core.merge(prepared, T)
        poses.append(T)
    est = np.stack(poses)
    try:  # Sturm et al.'s ATE, aligned; a trajectory that never moved cannot be aligned: both start at the truth
        ate = absolute_trajectory_error(est, scan.reference.poses).translation.rmse
    except ValueError:
        ate = absolute_trajectory_error(est, scan.reference.poses, align=False).translation.rmse
    rpe = relative_pose_error(est, scan.reference.poses).translation.rmse
    pts = rec._core.model_points()
    return dict(ate=float(ate), rpe=float(rpe), register_s=register_s,
                iterations=float(np.nanmean(iterations)) if np.isfinite(iterations).any() else math.nan, poses=est,
                model=pts)


def _variants(setup: Setup, with_peers: bool = True) -> Dict[str, dict]:
    out = dict(PAPER_VARIANTS)
    extra = dict(EXTRA_VARIANTS)
    if setup.quick:  # CI: the paper's variants only, PCL's dual quaternion standing for both PCL point-to-point
        out.pop("(c) PCL, SVD")
        extra = {}
    for name, v in extra.items():
        if "peer" in v and with_peers:
            try:
                __import__(v["peer"])
            except ImportError:
                continue
        elif "peer" in v:
            continue
        out[name] = v
    return out


def _table(xname: str, xs: Sequence, results: Dict[str, Dict], fmt, paper_col: Optional[Dict] = None) -> str:
    names = list(results)
    head = f"| {xname} | " + " | ".join(names) + (" | paper |" if paper_col else " |")
    lines = [head, "|---" * (len(names) + 1 + bool(paper_col)) + "|"]
    for x in xs:
        row = " | ".join(fmt(results[n].get(x)) for n in names)
        lines.append(f"| {x} | {row}" + (f" | {paper_col.get(x, '')} |" if paper_col else " |"))
    return "\n".join(lines)


def _mm(r: Optional[dict], key: str = "ate") -> str:
    return "-" if r is None or not np.isfinite(r[key]) else f"{r[key] * 1000:.1f}"


def _plot(xs, results: Dict[str, Dict], key: str, scale: float, path: Path, **kw) -> Path:
    from scanalign.viz.plots import plot_series
    series = {n: [results[n][x][key] * scale if x in results[n] else math.nan for x in xs] for n in results}
    return plot_series(list(xs), series, path, **kw)


def box_cause(setup: Setup, log: Log) -> str:
    """Measures why point-to-point ICP tracks poorly here: on the first pair of a loop, the share of
    correspondences on the object, the first step, and the error left after k iterations under PCL's
    rules. On the table, the nearest model point lies straight below a source point, so table pairs
    pull only along the table's normal; on a smooth object the nearest point slides with the surface.
    What is left to drive the motion is a small residual, so point-to-point closes the error by a
    small fraction per iteration, and PCL's rule (a step under 0.1 mm and 0.008 deg: converged) can
    stop it long before it gets there."""
    from scanalign import registration
    size = OBJECTS["machined part"][1]
    rows = ["| images per loop | box | estimator | pairs | on the object | step 1 (mm) | error after 10 / 50 / 128 "
            "iterations (mm) | stopped after | status |", "|---|---|---|---|---|---|---|---|---|"]
    for n, box, est in ((setup.cap_images, None, "point_to_point"), (setup.cap_images, object_box(size), "point_to_point"),
                        (setup.cap_images, object_box(size), "point_to_plane"), (setup.images[-1], object_box(size), "point_to_point"),
                        (setup.images[-1], object_box(size), "point_to_plane")):
        scan = make_scan("builtin", size, n, setup)
        rec = paper_reconstructor(scan, PAPER_VARIANTS["(a) k-d tree, LLS"], 50, None, setup)
        rec.integrate(scan.frames[0])
        model = rec.model
        ok = np.all(np.isfinite(model.normals), axis=1)
        f1 = scan.frames[1]
        points, _ = depth_to_cloud(f1.depth, f1.intrinsics, depth_scale=f1.depth_scale, min_depth=0.1, max_depth=2.0)
        src = _in_box(np.asarray(rec._core.prepare(points, None).points), box)
        T0, T1 = scan.frames[0].T_base_camera, f1.T_base_camera
        table_z = float(scan.object_mesh.vertices[:, 2].min())
        on_object = float(np.mean((src @ T1[:3, :3].T + T1[:3, 3])[:, 2] > table_z + 0.003))

        def icp(k: int):
            return registration.icp(src, model.points[ok], model.normals[ok], init=T0, estimator=est, max_iterations=k,
                                    max_correspondence_distance=0.02)

        err = lambda r: np.linalg.norm(np.asarray(r.T_target_source)[:3, 3] - T1[:3, 3]) * 1000  # noqa: E731
        step = np.linalg.norm(np.asarray(icp(1).T_target_source)[:3, 3] - T0[:3, 3]) * 1000
        runs = [icp(k) for k in (10, 50, 128)]
        label = "none" if box is None else f"+-{box[1] * 100:.0f} cm"
        rows.append(f"| {n} ({np.linalg.norm(T1[:3, 3] - T0[:3, 3]) * 1000:.0f} mm apart) | {label} | {est} | {len(src)} | "
                    f"{on_object:.0%} | {step:.2f} | " + " / ".join(f"{err(r):.1f}" for r in runs)
                    + f" | {runs[-1].iterations} | {runs[-1].status} |")
    log("eye_in_hand: measured why point-to-point tracks poorly")
    return ("Why point-to-point tracks poorly (first pair of each loop; ICP from the previous pose, 2 cm distance, "
            "PCL's rules; error = distance of the camera from its true position):\n\n" + "\n".join(rows))


def _fig8(scan, setup: Setup, size: float, figs: Path, log: Log):
    """Fig. 8: SVD vs LLS, without and with the box, on a limited number of iterations (10)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    cases = {}
    for est, label in (("point_to_point", "SVD"), ("point_to_plane", "LLS")):
        for box, blabel in ((None, "without"), (object_box(size), "with")):
            r = run_loop(scan, dict(registration="scanalign", estimator=est), 10, box, setup)
            pts = r["model"]
            c = scan.object_mesh.vertices.mean(axis=0)
            near = pts[np.all(np.abs(pts[:, :2] - c[:2]) < 0.75 * size, axis=1)]
            d = mesh_distance_stats(near, scan.mesh.vertices, scan.mesh.faces)
            cases[(label, blabel)] = dict(r, near=near, surface_rms=float(d.rmse))
            log(f"eye_in_hand fig8 {label} {blabel} box: ATE {r['ate'] * 1000:.1f} mm, surface RMS "
                f"{d.rmse * 1000:.2f} mm")
    fig, axes = plt.subplots(2, 2, figsize=(9, 9))
    for ax, (key, r) in zip(axes.ravel(), cases.items()):
        p = r["near"]
        ax.scatter(p[:, 0], p[:, 2], s=0.2, c=p[:, 1], cmap="viridis")
        ax.set_title(f"({'abcd'[list(cases).index(key)]}) {key[0]} - {key[1]} box\nATE {r['ate'] * 1000:.1f} mm, "
                     f"distance to the true surface {r['surface_rms'] * 1000:.2f} mm RMS", fontsize=9)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("z (m)")
        ax.set_aspect("equal")
    fig.suptitle("Fig. 8: accumulated models after 10 iterations per frame (side view)")
    fig.tight_layout()
    path = figs / "fig8_models.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return cases, path


def run(out: Path, quick: bool, log: Log) -> List[Section]:
    setup = Setup(quick)
    figs = out / "eye_in_hand"
    figs.mkdir(parents=True, exist_ok=True)
    variants = _variants(setup)
    size = OBJECTS["machined part"][1]
    box = object_box(size)
    setting = (f"Set-up: the built-in 80 mm part, a loop at 40 cm, SR300-like noise, "
               f"{int(640 * setup.scale)}x{int(480 * setup.scale)} depth (the paper: 640x480), frames cropped to +-15 cm "
               f"around the optical axis, the paper's settings (5 mm normals, 1 mm grids, the previous pose as the "
               f"guess, PCL's convergence rules, no depth filter), every registration merged, the box "
               f"{box[:4]} m (§3.4, as the paper's banana box).")
    sections: List[Section] = []
    t0 = time.perf_counter()
    cause = box_cause(setup, log)

    by_images: Dict[str, Dict[int, dict]] = {v: {} for v in variants}
    for n in setup.images:
        scan = make_scan("builtin", size, n, setup)
        for name, v in variants.items():
            if "registration" in v and v["registration"] != "scanalign" and n not in setup.pcl_images:
                continue
            by_images[name][n] = r = run_loop(scan, v, setup.images_cap, box, setup)
            log(f"eye_in_hand images {n:3d} {name:32s} ATE {r['ate'] * 1000:7.1f} mm  register "
                f"{r['register_s']:6.2f} s  iterations {r['iterations']:5.1f}")
    by_caps: Dict[str, Dict[int, dict]] = {v: {} for v in variants}
    scan18 = make_scan("builtin", size, setup.cap_images, setup)
    for cap in setup.caps:
        for name, v in variants.items():
            if name == "scanalign defaults" or (v.get("registration", "scanalign") != "scanalign"
                                                and cap not in setup.pcl_caps):
                continue
            by_caps[name][cap] = r = run_loop(scan18, v, cap, box, setup)
            log(f"eye_in_hand cap {cap:4d} {name:32s} ATE {r['ate'] * 1000:7.1f} mm  register "
                f"{r['register_s']:6.2f} s")
    by_caps = {k: v for k, v in by_caps.items() if v}
    seconds = lambda r: "-" if r is None else f"{r['register_s']:.2f}"  # noqa: E731
    lls, dq = by_images["(a) k-d tree, LLS"], by_images["(b) k-d tree, dual quaternion"]
    few, many = max(n for n in setup.images if n < 10), setup.images[-1]

    # Figs. 5 and 6: time.
    lls_top = by_caps["(a) k-d tree, LLS"][setup.caps[-1]]
    dq_top = by_caps["(b) k-d tree, dual quaternion"][setup.caps[-1]]
    f5 = _plot(setup.images, by_images, "register_s", 1.0, figs / "fig5_time_vs_images.png",
               xlabel="images per loop", ylabel="total registration time (s)", title="Fig. 5", logy=True)
    f6 = _plot(setup.caps, by_caps, "register_s", 1.0, figs / "fig6_time_vs_iterations.png",
               xlabel="ICP iteration cap", ylabel="total registration time (s)",
               title=f"Fig. 6 ({setup.cap_images} images)", logx=True, logy=True)
    ratio = {n: by_images["(d) PCL, dual quaternion"][n]["register_s"] / dq[n]["register_s"] for n in setup.pcl_images}
    sections.append(Section(
        "Eye-in-hand paper, Figs. 5 and 6: registration time", "\n\n".join([
            setting, f"Total registration time (s; k-d tree builds and ICP, summed over the frames):",
            _table("images", setup.images, by_images, seconds),
            f"Against the iteration cap ({setup.cap_images} images):", _table("cap", setup.caps, by_caps, seconds),
            "PCL dual quaternion / scanalign dual quaternion time: "
            + ", ".join(f"{n} images {v:.1f}x" for n, v in ratio.items()) + ".",
            "Paper (Figs. 5-6, Ryzen 1700X + GTX 1080Ti, 640x480): the GPU variants 14x faster than a similar CPU "
            "implementation and 4.5x faster than PCL; up to 48x (LLS) and 30x (dual quaternion) CPU to GPU, 8x "
            "over PCL's dual quaternion; about 1.5 s per image. Our CPU engine against PCL on the same machine is "
            "the comparison available here. " + GPU_NOTE]),
        [f5, f6], [Check("LLS needs fewer iterations than the dual quaternion (Fig. 6: LLS converges after a few)",
                         lls_top["iterations"] < dq_top["iterations"],
                         f"mean iterations on {setup.cap_images} images, cap {setup.caps[-1]}: LLS "
                         f"{lls_top['iterations']:.1f}, dual quaternion {dq_top['iterations']:.1f}")]))

    # Fig. 7: ATE vs images.
    f7 = _plot(setup.images, by_images, "ate", 1000.0, figs / "fig7_ate_vs_images.png", xlabel="images per loop",
               ylabel="ATE RMSE (mm)", title="Fig. 7", logy=True)
    same = [(n, abs(by_images[v][n]["ate"] - dq[n]["ate"])) for v in ("(c) PCL, SVD", "(d) PCL, dual quaternion")
            if v in by_images for n in by_images[v]]
    # Same estimator, same data: equal to rounding while tracking; where a run diverges (below 10
    # images) rounding differences grow with it, hence the 3 % of its error.
    worst = max(d for _, d in same)
    agree = all(d < max(0.001, 0.03 * dq[n]["ate"]) for n, d in same)
    sections.append(Section(
        "Eye-in-hand paper, Fig. 7: ATE vs images per loop", "\n\n".join([
            setting + f" Iteration cap {setup.images_cap} (not stated in the paper; see Fig. 9).",
            "ATE RMSE (mm) against the exact camera poses:", _table("images", setup.images, by_images, _mm),
            "Paper: no noticeable difference between the methods once 10 or more images are used (about 4 cm for "
            "the fruits, Table 1: real sensor and arm errors), except the LLS estimators, with large errors below "
            "10 images (the small-angle approximation of Low (2004) breaks).",
            "Reproduced: LLS fails below 10 images and tracks above (" + ", ".join(
                f"{lls[n]['ate'] * 1000:.1f} mm at {n}" for n in setup.images if n >= 10) + "). The point-to-point "
            f"variants (b)-(d) agree with each other (largest difference {worst * 1000:.2f} mm where PCL ran, the "
            "same estimator), but not with LLS: the dual quaternion gives " + ", ".join(
                f"{dq[n]['ate'] * 1000:.1f} mm at {n}" for n in setup.images if n >= 10) + " images. Where it tracks, "
            "that is about the paper's common 4 cm; there a real sensor and arm put every method near 4 cm, "
            "which hides the difference that our exact reference shows. The table below measures why: without "
            "the box, few pairs lie on the object and the first step is a fraction of a millimetre; with it, "
            "point-to-point closes the error by a small fraction per iteration (no second-order information on a "
            "smooth surface, where the nearest point slides along), and at small motions PCL's step rule (0.1 mm) "
            "stops it after a few iterations, short of the true pose.",
            cause, "What differs: our scene is synthetic with exact reference poses, so the common error is the "
            "registration's alone. " + GPU_NOTE]),
        [f7], [Check("LLS fails below 10 images per loop", lls[few]["ate"] > 3 * lls[many]["ate"],
                     f"LLS ATE {lls[few]['ate'] * 1000:.1f} mm at {few} images, {lls[many]['ate'] * 1000:.1f} mm at "
                     f"{many}"),
               Check("scanalign's dual quaternion tracks as PCL's point-to-point estimators (within 1 mm or 3 %)",
                     agree, ", ".join(f"{n} images: {d * 1000:.2f} mm" for n, d in same))]))

    # Fig. 9: ATE vs iteration cap.
    f9 = _plot(setup.caps, by_caps, "ate", 1000.0, figs / "fig9_ate_vs_iterations.png", xlabel="ICP iteration cap",
               ylabel="ATE RMSE (mm)", title=f"Fig. 9 ({setup.cap_images} images)", logx=True, logy=True)
    c_lo, c_hi = min(c for c in setup.caps if c >= 8), setup.caps[-1]  # the paper: 10 LLS iterations
    lls_c, dq_c = by_caps["(a) k-d tree, LLS"], by_caps["(b) k-d tree, dual quaternion"]
    sections.append(Section(
        f"Eye-in-hand paper, Fig. 9: ATE vs iteration cap ({setup.cap_images} images)", "\n\n".join([
            setting, "ATE RMSE (mm):", _table("cap", setup.caps, by_caps, _mm),
            "Paper: 10 iterations of point-to-plane LLS are comparable to 100 of the point-to-point dual "
            "quaternion; the curves converge to a common point (about 4 cm with the real sensor)."]),
        [f9], [Check(f"LLS at {c_lo} iterations is as good as the dual quaternion at {c_hi} (within 1.5x)",
                     lls_c[c_lo]["ate"] < 1.5 * dq_c[c_hi]["ate"],
                     f"LLS {lls_c[c_lo]['ate'] * 1000:.1f} mm at {c_lo}, dual quaternion "
                     f"{dq_c[c_lo]['ate'] * 1000:.1f} mm at {c_lo} and {dq_c[c_hi]['ate'] * 1000:.1f} mm at {c_hi}"),
               Check(f"the dual quaternion needs more than {c_lo} iterations",
                     dq_c[c_lo]["ate"] > 1.5 * dq_c[c_hi]["ate"],
                     f"{dq_c[c_lo]['ate'] * 1000:.1f} mm at {c_lo}, {dq_c[c_hi]['ate'] * 1000:.1f} mm at {c_hi}")]))

    # Fig. 8: the qualitative grid.
    cases, f8 = _fig8(scan18, setup, size, figs, log)
    g = {k: v["ate"] for k, v in cases.items()}
    s = {k: v["surface_rms"] for k, v in cases.items()}
    sections.append(Section(
        "Eye-in-hand paper, Fig. 8: SVD vs LLS, without and with the box (10 iterations)", "\n\n".join([
            setting.replace("the box", "(box as marked)"),
            "| | ATE (mm) | distance of the model to the true surface, RMS (mm) |\n|---|---|---|\n" + "\n".join(
                f"| {k[0]} - {k[1]} box | {g[k] * 1000:.1f} | {s[k] * 1000:.2f} |" for k in cases),
            "Paper (pork chop and pear, qualitative): LLS is more precise than SVD on a limited number of "
            "iterations (a, b vs c, d); the box gives more precise registrations (b, d vs a, c); (b) is slightly "
            "less precise than (d). SVD here is scanalign's point-to-point (Kabsch-SVD), the same estimator as "
            "PCL's TransformationEstimationSVD."]),
        [f8], [Check("the box makes both more precise", g[("SVD", "with")] < g[("SVD", "without")]
                     and g[("LLS", "with")] < g[("LLS", "without")],
                     ", ".join(f"{k[0]} {k[1]}: {v * 1000:.1f} mm" for k, v in g.items())),
               Check("LLS is more precise than SVD on 10 iterations (with the box)",
                     g[("LLS", "with")] < g[("SVD", "with")],
                     f"{g[('LLS', 'with')] * 1000:.1f} mm against {g[('SVD', 'with')] * 1000:.1f} mm")]))

    # Table 1 and Fig. 4: three objects, LLS.
    from scanalign.viz.plots import plot_trajectory_topdown
    from scanalign.evaluation import Trajectory
    rows, f4 = [], []
    objects = dict(list(OBJECTS.items())[:2]) if quick else OBJECTS
    for (name, (mesh, osize)), paper in zip(objects.items(), PAPER_TABLE1.items()):
        scan = make_scan(mesh, osize, setup.table_images, setup)
        r = run_loop(scan, PAPER_VARIANTS["(a) k-d tree, LLS"], setup.cap, object_box(osize), setup)
        rows.append(f"| {name}, {osize * 1000:.0f} mm | {r['ate'] * 100:.2f} | {r['rpe'] * 100:.2f} | {paper[0]} | "
                    f"{paper[1][0]:.2f} | {paper[1][1]:.2f} |")
        f4.append(plot_trajectory_topdown(Trajectory(np.arange(len(r["poses"]), dtype=float), r["poses"]),
                                          scan.reference, figs / f"fig4_trajectory_{mesh}.png",
                                          title=f"Fig. 4: {name} ({setup.table_images} images, LLS)"))
        log(f"eye_in_hand table1 {name}: ATE {r['ate'] * 1000:.1f} mm RPE {r['rpe'] * 1000:.1f} mm")
    ates = [float(x.split("|")[2]) for x in rows]
    sections.append(Section(
        "Eye-in-hand paper, Table 1 and Fig. 4: ATE and RPE of three objects (LLS)", "\n\n".join([
            f"{setup.table_images} images per loop, LLS with the box sized to each object; otherwise as above. "
            "RPE: frame to frame (Sturm et al. 2012), translation RMSE.",
            "| our object | ATE (cm) | RPE (cm) | paper's object | paper ATE (cm) | paper RPE (cm) |\n"
            "|---|---|---|---|---|---|\n" + "\n".join(rows),
            "What differs: the paper's objects are real fruit scanned by an SR300 on a Franka Panda; its errors "
            "(3-4 cm) are dominated by the sensor and the arm's pose (§4.7). Our reference poses are exact and "
            "the noise is an SR300-like model, so our errors are the registration's alone and far smaller; the "
            "table shows the same ordering claim cannot be tested. Fig. 4: the estimated trajectories against "
            "the reference, top down."]),
        f4, [Check("every object tracked (ATE under the paper's 3.3 cm)", max(ates) < 3.29,
                   ", ".join(f"{a:.2f} cm" for a in ates))]))
    sections[0].seconds = time.perf_counter() - t0
    return sections

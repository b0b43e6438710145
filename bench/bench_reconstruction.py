"""Figures 5, 6, 7 and 9 of the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929)
on the synthetic eye-in-hand dataset.

A camera circles the object on the table (one full loop, eye-in-hand paper Fig. 4) and the frames are
reconstructed frame-to-model by each registration method, in this one run:

- Fig. 5: total registration time vs number of images per loop (4, 8, 17, 34, 69);
- Fig. 6: total registration time vs ICP iteration cap (1 ... 128) on 18 images;
- Fig. 7: ATE vs number of images;
- Fig. 9: ATE vs iteration cap.

Methods: scanalign's engine with Low's point-to-plane LLS (the eye-in-hand paper's method) and with the
closed-form point-to-point estimator, and stock PCL 1.13 ICP with SVD, dual quaternion
and point-to-plane LLS (IterativeClosestPointWithNormals). Every method gets the same
prepared frames (1 mm voxels, 5 mm normals), the same model updates (1 mm grid) and the
same criteria, with the demo's settings (a 20 x 20 cm workspace crop, 10 mm normals, the
bilateral depth filter); as in the eye-in-hand paper, every registration is merged (no rejection), so
the curves show each estimator's own behaviour. Times are the registration only (tree
build + ICP), summed over the frames; normals and merging are the same for everyone and
excluded, as in the eye-in-hand paper. Ratios are PCL / scanalign from this same run.

    python bench/bench_reconstruction.py [--scale 0.5] [--quick] [--out bench-out] [--json r.json]

``--scale`` is the image resolution relative to the SR300's 640x480 (0.5 keeps the PCL
baselines to minutes); ``--quick`` runs a reduced grid (smoke test).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from scanalign import synthetic
from scanalign.evaluation import absolute_trajectory_error
from scanalign.reconstruction import BilateralFilterSettings, Reconstructor

METHODS = {
    "scanalign LLS": dict(registration="scanalign", estimator="point_to_plane"),
    "scanalign point-to-point": dict(registration="scanalign", estimator="point_to_point"),
    "PCL SVD": dict(registration="pcl_svd"),
    "PCL dual quaternion": dict(registration="pcl_dual_quaternion"),
    "PCL LLS": dict(registration="pcl_point_to_plane_lls"),
}
IMAGES = (4, 8, 17, 34, 69)
ITERATION_CAPS = (1, 2, 4, 8, 16, 32, 64, 128)


def make_scan(n_frames: int, args: argparse.Namespace):
    config = synthetic.SyntheticConfig(mesh=args.mesh, n_frames=n_frames, trajectory="loop", noise=args.noise,
                                       seed=args.seed, resolution_scale=args.scale)
    return config.build()


def run(scan, method: dict, max_iterations: int, max_distance: float) -> dict:
    icp = dict(max_iterations=max_iterations, max_correspondence_distance=max_distance)
    if "estimator" in method:
        icp["estimator"] = method["estimator"]
    # The demo's settings (workspace crop, 10 mm normals, bilateral depth filter: the
    # simulated SR300 noise needs them, see the README), with every check off.
    rec = Reconstructor(T_model_camera0=scan.frames[0].T_base_camera, registration=method["registration"],
                        icp=icp, crop_box=(-0.1, 0.1, -0.1, 0.1, 0.1, 1.0), normal_radius=0.01,
                        depth_filter=BilateralFilterSettings(), min_fitness=0.0, require_convergence=False,
                        max_translation_change=float("inf"), max_rotation_change=float("inf"))
    t0 = time.perf_counter()
    for f in scan.frames:
        rec.integrate(f)
    wall = time.perf_counter() - t0
    records = rec.records
    reg = sum(r.register_seconds for r in records)
    merged = [r for r in records if r.merged]
    est = rec.trajectory
    ref = scan.reference[np.array([r.index for r in merged])]
    ate = absolute_trajectory_error(est, ref).translation.rmse if len(merged) >= 3 else float("nan")
    return dict(register_seconds=reg, wall_seconds=wall, ate_m=float(ate), merged=len(merged), frames=len(records),
                iterations=float(np.mean([r.iterations for r in records[1:]])) if len(records) > 1 else 0.0)


def table(title: str, xname: str, xs, results: dict, key: str, fmt) -> str:
    names = list(results)
    lines = [f"### {title}", "", f"| {xname} | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    for x in xs:
        lines.append(f"| {x} | " + " | ".join(fmt(results[n][x][key]) for n in names) + " |")
    return "\n".join(lines)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scale", type=float, default=0.5, help="image resolution relative to 640x480 (0.5)")
    ap.add_argument("--mesh", default="builtin", help="scene object: builtin, a CGAL mesh name, or a file")
    ap.add_argument("--noise", default="sr300", help="sensor noise preset (sr300)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-distance", type=float, default=0.05, help="max correspondence distance, m (0.05)")
    ap.add_argument("--methods", nargs="+", choices=list(METHODS), default=list(METHODS))
    ap.add_argument("--quick", action="store_true", help="reduced grid: images 8, 17; caps 1, 8, 32")
    ap.add_argument("--out", default="bench-out", help="folder for the PNG figures (bench-out)")
    ap.add_argument("--json", help="write all results to this JSON file")
    args = ap.parse_args()
    images = (8, 17) if args.quick else IMAGES
    caps = (1, 8, 32) if args.quick else ITERATION_CAPS
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    by_images = {m: {} for m in args.methods}
    for n in images:
        scan = make_scan(n, args)
        for m in args.methods:
            by_images[m][n] = r = run(scan, METHODS[m], 50, args.max_distance)
            print(f"images {n:3d}  {m:26s} reg {r['register_seconds']:8.2f} s  ATE {r['ate_m'] * 1000:8.2f} mm  "
                  f"mean it {r['iterations']:5.1f}", file=sys.stderr)
    by_caps = {m: {} for m in args.methods}
    scan18 = make_scan(18, args)
    for cap in caps:
        for m in args.methods:
            by_caps[m][cap] = r = run(scan18, METHODS[m], cap, args.max_distance)
            print(f"cap {cap:4d}  {m:26s} reg {r['register_seconds']:8.2f} s  ATE {r['ate_m'] * 1000:8.2f} mm",
                  file=sys.stderr)

    secs = lambda v: f"{v:.2f} s"  # noqa: E731
    mm = lambda v: "failed" if not np.isfinite(v) else f"{v * 1000:.2f} mm"  # noqa: E731
    print(f"Synthetic loop scan: {args.mesh}, noise {args.noise}, resolution x{args.scale}, "
          f"max distance {args.max_distance} m\n")
    print(table("Fig. 5: total registration time vs images per loop", "images", images, by_images,
                "register_seconds", secs) + "\n")
    print(table("Fig. 7: ATE vs images per loop", "images", images, by_images, "ate_m", mm) + "\n")
    print(table("Fig. 6: total registration time vs iteration cap (18 images)", "cap", caps, by_caps,
                "register_seconds", secs) + "\n")
    print(table("Fig. 9: ATE vs iteration cap (18 images)", "cap", caps, by_caps, "ate_m", mm) + "\n")
    # Like for like: PCL's LLS against scanalign's LLS, PCL's SVD / dual quaternion (both
    # point-to-point) against scanalign's point-to-point.
    for pcl, ours in (("PCL LLS", "scanalign LLS"), ("PCL SVD", "scanalign point-to-point"),
                      ("PCL dual quaternion", "scanalign point-to-point")):
        if pcl in args.methods and ours in args.methods:
            ratio = [by_images[pcl][n]["register_seconds"] / by_images[ours][n]["register_seconds"] for n in images]
            print(f"{pcl} / {ours} time: " + ", ".join(f"{n} img {r:.1f}x" for n, r in zip(images, ratio)))

    from scanalign.viz.plots import plot_series

    def series(data: dict, xs, key: str, scale: float = 1.0) -> dict:
        return {m: [data[m][x][key] * scale for x in xs] for m in data}

    plot_series(list(images), series(by_images, images, "register_seconds"), out / "fig5_time_vs_images.png",
                xlabel="images per loop", ylabel="total registration time (s)", title="Fig. 5", logy=True)
    plot_series(list(caps), series(by_caps, caps, "register_seconds"), out / "fig6_time_vs_iterations.png",
                xlabel="ICP iteration cap", ylabel="total registration time (s)", title="Fig. 6 (18 images)",
                logx=True, logy=True)
    plot_series(list(images), series(by_images, images, "ate_m", 1000.0), out / "fig7_ate_vs_images.png",
                xlabel="images per loop", ylabel="ATE RMSE (mm)", title="Fig. 7", logy=True)
    plot_series(list(caps), series(by_caps, caps, "ate_m", 1000.0), out / "fig9_ate_vs_iterations.png",
                xlabel="ICP iteration cap", ylabel="ATE RMSE (mm)", title="Fig. 9 (18 images)", logx=True, logy=True)
    print(f"\nfigures in {out}/")
    if args.json:
        Path(args.json).write_text(json.dumps(dict(args=vars(args), images=by_images, caps=by_caps), indent=2,
                                              default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())

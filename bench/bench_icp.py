"""ICP speed and accuracy: scanalign's engine against stock PCL 1.13, in one run.

For each real surface (CGAL demo meshes, scaled to 15 cm, 50 cm from the camera) a
target of --target-points points with normals and a noisy source of --source-points
points displaced by a known motion are registered by every method with the same
criteria (the eye-in-hand paper, (Comput. Electron. Agric. 180 (2021) 105929), §3.3: 50 iterations, epsilons 1e-8, 2 cm max
distance). Times are
medians over --repeats runs and include each method's k-d tree build. Ratios are PCL
time / scanalign time from this same run (this machine is noisy; do not compare
numbers across runs).

    python bench/bench_icp.py [--repeats 5] [--json results.json]

Open3D and small_gicp are added as peers when they are installed.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "tests"))
from helpers import apply, pose_error, rigid  # noqa: E402

from scanalign import registration  # noqa: E402
from scanalign.data import downloads as datasets
from scanalign.data import parts

# Motions of the camera between the two clouds (T_target_source). "frame-to-frame" is an
# eye-in-hand step at the eye-in-hand paper's capture rate (10 Hz, arm at <= 0.1 m/s): about 1 cm;
# "large" is a 5 degree, 8.8 mm step (a 4.4 cm shift at the object, 50 cm away), where
# many source points start farther than the 2 cm correspondence distance.
MOTIONS = {
    "frame-to-frame": rigid((0.3, 1.0, -0.4), np.deg2rad(1.0), (0.004, -0.003, 0.003)),
    "large": rigid((0.3, 1.0, -0.4), np.deg2rad(5.0), (0.006, -0.004, 0.005)),
}
CRITERIA = dict(max_correspondence_distance=0.02, max_iterations=50, transformation_epsilon=1e-8, fitness_epsilon=1e-8)


def surface(name: str, n: int, seed: int):
    mesh = datasets.load_cgal_mesh(name)
    v = mesh.vertices - mesh.vertices.mean(axis=0)
    v = v * (0.15 / np.ptp(v, axis=0).max()) + [0.0, 0.0, 0.5]
    return parts.sample_mesh((v, mesh.faces), n, seed=seed)


def methods(src, tgt, nrm):
    f32 = lambda a: np.ascontiguousarray(a, np.float32)  # noqa: E731
    s, t, n = f32(src), f32(tgt), f32(nrm)
    yield "scanalign point-to-plane LLS", lambda: registration.icp(s, t, n, **CRITERIA)
    yield "scanalign point-to-point", lambda: registration.icp(s, t, n, estimator="point_to_point", **CRITERIA)
    for variant, label in (
        ("point_to_plane_lls", "PCL ICPWithNormals (LLS)"),
        ("svd", "PCL ICP SVD"),
        ("dual_quaternion", "PCL ICP dual quaternion"),
    ):
        yield label, (lambda v=variant: registration.pcl_icp(s, t, n, variant=v, **CRITERIA))
    try:
        import open3d as o3d

        def o3d_run():
            ps, pt = o3d.geometry.PointCloud(), o3d.geometry.PointCloud()
            ps.points = o3d.utility.Vector3dVector(src)
            pt.points = o3d.utility.Vector3dVector(tgt)
            pt.normals = o3d.utility.Vector3dVector(nrm)
            r = o3d.pipelines.registration.registration_icp(
                ps, pt, CRITERIA["max_correspondence_distance"], np.eye(4),
                o3d.pipelines.registration.TransformationEstimationPointToPlane(),
                o3d.pipelines.registration.ICPConvergenceCriteria(1e-8, 1e-8, 50))
            return r.transformation

        yield "Open3D point-to-plane", o3d_run
    except ImportError:
        pass
    try:
        import small_gicp

        yield "small_gicp PLANE_ICP", lambda: small_gicp.align(
            tgt, src, registration_type="PLANE_ICP", max_correspondence_distance=0.02, downsampling_resolution=1e-6
        ).T_target_source
    except ImportError:
        pass


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--target-points", type=int, default=60000)
    ap.add_argument("--source-points", type=int, default=30000)
    ap.add_argument("--noise", type=float, default=0.0005, help="source noise sigma, m")
    ap.add_argument("--surfaces", nargs="+", default=["bunny00", "fandisk"])
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args()
    rows = []
    for name, motion in ((n, m) for n in args.surfaces for m in MOTIONS):
        T_TRUE = MOTIONS[motion]
        tgt, nrm = surface(name, args.target_points, seed=1)
        src_model, _ = surface(name, args.source_points, seed=2)
        src = apply(np.linalg.inv(T_TRUE), src_model) + np.random.default_rng(3).normal(0, args.noise, src_model.shape)
        print(f"\n{name}, {motion} motion: target {len(tgt)} points, source {len(src)} points, "
              f"noise {args.noise * 1e3:.2f} mm, {args.repeats} repeats")
        times: dict = {}
        results: dict = {}
        for label, run in methods(src, tgt, nrm):
            ts = []
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                out = run()
                ts.append(time.perf_counter() - t0)
            times[label] = statistics.median(ts)
            T = out if isinstance(out, np.ndarray) else out.T_target_source
            rot, trans = pose_error(np.asarray(T), T_TRUE)
            iters = getattr(out, "iterations", None)
            results[label] = (rot, trans, iters)
        ours = times["scanalign point-to-plane LLS"]
        print(f"{'method':34s} {'median ms':>10s} {'x slower than ours':>19s} {'rot err deg':>12s} "
              f"{'trans err mm':>13s} {'iters':>6s}")
        for label, t in times.items():
            rot, trans, iters = results[label]
            print(f"{label:34s} {t * 1e3:10.2f} {t / ours:19.2f} {np.rad2deg(rot):12.5f} {trans * 1e3:13.4f} "
                  f"{'' if iters is None else iters:>6}")
            rows.append(dict(surface=name, motion=motion, method=label, median_s=t, ratio_to_scanalign=t / ours,
                             rotation_error_rad=rot, translation_error_m=trans, iterations=iters))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())

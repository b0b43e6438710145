"""Depth rendering speed: scanalign's z-buffer renderer, and Open3D's ray caster as a peer.

Each mesh (the built-in part, about 3000 triangles, and CGAL's Stanford bunny, about
75000 triangles, scaled to 15 cm) stands alone at the origin and is seen from the
--frames poses of the default scan loop (40 cm above the table, 20 cm radius) at 640x480
with the SR300 intrinsics. Reported: the median over --repeats of the mean time per frame
of scanalign.reconstruction.rendering.render_depth (all threads, then one), of a whole synthetic scan
frame (render + sensor noise + shaded RGB, frames rendered concurrently), and, when Open3D
is installed, of RaycastingScene.cast_rays on the same mesh, poses and pixels (its BVH is
built once, outside the timing; ray generation is included, as our renderer projects the
vertices inside its timing) with the ratio Open3D / scanalign from this same run, plus
the median depth difference between the two on pixels both hit.

    python bench/bench_render.py [--repeats 7] [--frames 36] [--json results.json]

This machine is shared and noisy: compare ratios within a run, not times across runs.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time

import numpy as np

from scanalign import synthetic
from scanalign.data import downloads as datasets
from scanalign.data import parts
from scanalign.reconstruction import rendering
from scanalign.common import rigid as se3
from scanalign.reconstruction.camera import intrinsics_preset


def meshes():
    yield "builtin part", parts.builtin_mesh()
    try:
        yield "bunny00 (CGAL)", parts.normalize_mesh(datasets.load_cgal_mesh("bunny00"), 0.15)
    except datasets.DatasetUnavailableError as exc:
        print(f"skipping the bunny: {exc}", file=sys.stderr)


def per_frame(fn, poses, repeats: int) -> float:
    """Median over repeats of the mean seconds per pose."""
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        for T in poses:
            fn(T)
        times.append((time.perf_counter() - t) / len(poses))
    return statistics.median(times)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--frames", type=int, default=36)
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args()

    K = intrinsics_preset("sr300")
    traj = synthetic.loop_trajectory(args.frames, center=(0.0, 0.0, 0.0), height=0.40, radius=0.20)
    T_base_camera = traj.T_base_camera
    T_camera_base = se3.inverse(T_base_camera)
    try:
        import open3d as o3d
    except ImportError:
        o3d = None
        print("open3d not installed: no peer (pip install open3d)", file=sys.stderr)

    rows = []
    print(f"{os.cpu_count()} CPUs, {K.width}x{K.height}, {args.frames} poses, median of {args.repeats}")
    for name, mesh in meshes():
        v = np.ascontiguousarray(mesh.vertices)
        f = np.ascontiguousarray(mesh.faces, dtype=np.int32)
        row = {"mesh": name, "triangles": int(len(f))}
        ours = lambda T, n=0: rendering.render_depth(v, f, K, T, num_threads=n)  # noqa: E731
        ours(T_camera_base[0])  # warm-up
        row["scanalign_ms"] = 1e3 * per_frame(ours, T_camera_base, args.repeats)
        row["scanalign_1thread_ms"] = 1e3 * per_frame(lambda T: ours(T, 1), T_camera_base, args.repeats)

        scene = synthetic.Scene(table_size=(0.6, 0.6), table_center=(0.0, 0.0))
        scene.add_object(mesh, position=(0.0, 0.0))
        synthetic.render_scan(scene, T_base_camera[:2], K, "sr300")  # warm-up (caches)
        t = []
        for _ in range(max(1, args.repeats // 2)):
            t0 = time.perf_counter()
            synthetic.render_scan(scene, T_base_camera, K, "sr300")
            t.append((time.perf_counter() - t0) / len(T_base_camera))
        row["scan_frame_ms"] = 1e3 * statistics.median(t)

        if o3d is not None:
            rc = o3d.t.geometry.RaycastingScene()
            rc.add_triangles(o3d.core.Tensor(v.astype(np.float32)), o3d.core.Tensor(f.astype(np.uint32)))
            # Open3D puts pixel (u, v)'s ray through (u + 0.5, v + 0.5); shifting the principal
            # point by half a pixel gives the OpenCV rays scanalign renders.
            Kt = o3d.core.Tensor(K.K + np.array([[0, 0, 0.5], [0, 0, 0.5], [0, 0, 0]]))

            def peer(T):
                rays = o3d.t.geometry.RaycastingScene.create_rays_pinhole(Kt, o3d.core.Tensor(T), K.width, K.height)
                return rc.cast_rays(rays)

            peer(T_camera_base[0])  # warm-up
            row["open3d_ms"] = 1e3 * per_frame(peer, T_camera_base, args.repeats)
            row["open3d_over_scanalign"] = row["open3d_ms"] / row["scanalign_ms"]
            # Same depth? Open3D's t_hit is in units of its ray direction: depth = t (d . z_cam).
            T = T_camera_base[0]
            rays = o3d.t.geometry.RaycastingScene.create_rays_pinhole(Kt, o3d.core.Tensor(T), K.width, K.height)
            t_hit = rc.cast_rays(rays)["t_hit"].numpy()
            d = rays.numpy()[..., 3:]
            z_o3d = t_hit * (d @ np.linalg.inv(T)[:3, 2])
            z_ours = ours(T).depth
            both = np.isfinite(z_o3d) & np.isfinite(z_ours)
            row["median_depth_difference_m"] = float(np.median(np.abs(z_o3d[both] - z_ours[both]))) if both.any() else None
        rows.append(row)

    head = f"{'mesh':<16}{'triangles':>10}{'scanalign':>12}{'1 thread':>11}{'scan frame':>12}"
    print(head + (f"{'Open3D':>10}{'ratio':>8}{'|dz| median':>13}" if o3d else ""))
    for r in rows:
        line = (f"{r['mesh']:<16}{r['triangles']:>10}{r['scanalign_ms']:>10.2f}ms{r['scanalign_1thread_ms']:>9.2f}ms"
                f"{r['scan_frame_ms']:>10.2f}ms")
        if "open3d_ms" in r:
            dz = r["median_depth_difference_m"]
            line += f"{r['open3d_ms']:>8.2f}ms{r['open3d_over_scanalign']:>7.1f}x" + (
                f"{dz:>11.1e} m" if dz is not None else "")
        print(line)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())

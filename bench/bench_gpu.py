"""The CUDA ICP backend against scanalign's CPU engine, in one process on one machine (issue 29).

The eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929) reports its GPU ICP (Algorithm 1) up to 48x
faster than its CPU version for LLS and 8x faster than PCL, and GPU normals at 0.05 s per image. This benchmark
measures scanalign's CUDA backend against its own CPU engine on all cores of the same machine:

* **registration** at 10k, 100k and 1M source points (a wavy surface with spheres, an independent sample of the same
  density as the model, a known motion, 0.5 mm noise): median align time over interleaved repeats (target tree built
  once, excluded; its build and upload reported beside), iterations, error against the known motion, and the pose
  difference to the CPU engine;
* **frame loop**: the built-in demo scan at 640x480 (SR300 intrinsics), whole ``reconstruct`` loop per backend:
  frames per second, median registration and total time per frame, ATE.

small_gicp (PLANE_ICP on all cores, its own defaults and normals) runs beside them when it is importable
(``scripts/gpu_check.sh`` installs its wheel from ``.gpu-deps/``). PCL is not on the GPU machine (its headers need
Boost's): its time is estimated as scanalign's single-thread CPU time on that machine times the PCL/scanalign
single-thread ratio measured on the development machine (``docs/benchmarks.md``: 3.90 at 40k source / 120k model
points), and the table says so. Open3D's CUDA build is several hundred MB: it cannot be taken along.

    python bench/bench_gpu.py [--out DIR] [--sizes 10000 100000 1000000] [--repeats 5] [--frames 36] [--quick]

Without a CUDA device the CUDA rows are skipped (the CPU rows still run): ``--quick`` is the smoke test CI runs.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from scanalign import _core
from scanalign.registration import Icp, cuda_devices

#: PCL ICPWithNormals time / scanalign float32 time, one thread, dense frame-to-model (docs/benchmarks.md).
PCL_RATIO_1_THREAD = 3.90
CRITERIA = dict(max_correspondence_distance=0.02, max_iterations=50, transformation_epsilon=1e-8, fitness_epsilon=1e-8)


def surface(n: int, seed: int) -> tuple:
    """n points (metres) on a 0.4 m wavy height field with three spheres, exact unit normals."""
    rng = np.random.default_rng(seed)
    n_sph = n // 5
    x, y = rng.uniform(-0.2, 0.2, (2, n - n_sph))
    z = 0.6 + 0.01 * np.sin(40 * x) * np.cos(30 * y) + 0.2 * x * x
    g = np.stack([-(0.4 * np.cos(40 * x) * np.cos(30 * y) + 0.4 * x), 0.3 * np.sin(40 * x) * np.sin(30 * y),
                  np.ones_like(x)], axis=1)
    centers = np.array([[0.05, -0.04, 0.55], [-0.08, 0.06, 0.56], [0.1, 0.1, 0.57]])
    u = rng.normal(size=(n_sph, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    c = centers[rng.integers(0, 3, n_sph)]
    pts = np.vstack([np.stack([x, y, z], axis=1), c + 0.03 * u])
    nrm = np.vstack([-g / np.linalg.norm(g, axis=1, keepdims=True), u])
    return pts.astype(np.float32), nrm.astype(np.float32)


def motion() -> np.ndarray:
    a = np.deg2rad(2.0)
    axis = np.array([0.3, 1.0, -0.4]) / np.linalg.norm([0.3, 1.0, -0.4])
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    T = np.eye(4)
    T[:3, :3] = np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K
    T[:3, 3] = [0.004, -0.003, 0.003]
    return T


def pose_error(T: np.ndarray, truth: np.ndarray) -> tuple:
    D = np.linalg.inv(truth) @ T
    angle = np.degrees(np.arccos(np.clip((np.trace(D[:3, :3]) - 1) / 2, -1, 1)))
    return float(np.linalg.norm(D[:3, 3]) * 1000), float(angle)


def _small_gicp(tgt: np.ndarray, src: np.ndarray, threads: int):
    """small_gicp PLANE_ICP on all cores (its defaults, its own normals k=10, tree prebuilt as ours), or None."""
    try:
        import small_gicp as sg
    except ImportError:
        return None
    target = sg.PointCloud(tgt.astype(np.float64))
    sg.estimate_normals(target, sg.KdTree(target, threads), num_neighbors=10, num_threads=threads)
    tree, source = sg.KdTree(target, threads), sg.PointCloud(src.astype(np.float64))

    def run():
        r = sg.align(target, source, tree, registration_type="PLANE_ICP", max_correspondence_distance=0.02,
                     num_threads=threads)
        return np.asarray(r.T_target_source), int(r.iterations), "converged" if r.converged else "not converged"
    return run


def registration_rows(sizes, repeats: int, threads: int, cuda: bool) -> list:
    rows = []
    truth = motion()
    for n in sizes:
        tgt, nrm = surface(n, 1)
        src_base, _ = surface(n, 2)  # another sample of the same surface: no point pairs exactly
        rng = np.random.default_rng(3)
        src = ((src_base - truth[:3, 3]) @ truth[:3, :3] + rng.normal(0, 5e-4, src_base.shape)).astype(np.float32)
        configs = {"cpu, 1 thread": dict(backend="cpu", num_threads=1),
                   f"cpu, {threads} threads": dict(backend="cpu", num_threads=threads)}
        if cuda:
            configs["cuda"] = dict(backend="cuda")
        runs, setup = {}, {}
        for name, kw in configs.items():
            t0 = time.perf_counter()
            engine = Icp(tgt, nrm, **CRITERIA, **kw)
            setup[name] = time.perf_counter() - t0

            def run(engine=engine):
                r = engine.align(src)
                return r.T_target_source, r.iterations, r.status
            runs[name] = run
        sg_run = _small_gicp(tgt, src, threads)
        if sg_run is not None:
            runs[f"small_gicp, {threads} threads"], setup[f"small_gicp, {threads} threads"] = sg_run, None
        reps = repeats if n < 500_000 else max(2, repeats // 2)
        times, results = {k: [] for k in runs}, {}
        for _ in range(reps):  # interleaved: each repeat runs every method once
            for name, run in runs.items():
                t0 = time.perf_counter()
                results[name] = run()
                times[name].append(time.perf_counter() - t0)
        ref = results[f"cpu, {threads} threads"][0]
        for name in runs:
            T, iterations, status = results[name]
            err = pose_error(T, truth)
            rows.append(dict(points=n, backend=name, median_s=statistics.median(times[name]), repeats=reps,
                             tree_and_upload_s=setup[name], iterations=iterations, status=status,
                             error_mm=err[0], error_deg=err[1], max_pose_diff_to_cpu=float(np.abs(T - ref).max())))
            print(f"  {n:>8} {name:<22} {rows[-1]['median_s'] * 1e3:9.2f} ms  {iterations:3d} it  "
                  f"{err[0]:.3f} mm {err[1]:.4f} deg  |dT| {rows[-1]['max_pose_diff_to_cpu']:.1e}", flush=True)
    return rows


def frame_loop_rows(frames: int, repeats: int, cuda: bool) -> list:
    from scanalign import synthetic
    from scanalign.pipelines.reconstruct import DEMO_SETTINGS, reconstruct

    scan = synthetic.builtin_scan(36, intrinsics="sr300")  # the demo loop (10 degrees apart), rendered once
    rendered = scan.frames[:frames]
    size = (rendered[0].depth.shape[1], rendered[0].depth.shape[0])
    backends = ["cpu"] + (["cuda"] if cuda else [])
    wall, results = {b: [] for b in backends}, {}
    for _ in range(repeats):
        for b in backends:
            t0 = time.perf_counter()
            results[b] = reconstruct(rendered, progress=False, backend=b, **DEMO_SETTINGS)
            wall[b].append(time.perf_counter() - t0)
    rows = []
    for b in backends:
        res = results[b]
        s = res.summary()
        w = statistics.median(wall[b])
        rows.append(dict(backend=b, frames=len(rendered), width=size[0], height=size[1], hz=len(rendered) / w,
                         median_register_ms=1e3 * statistics.median(r.register_seconds for r in res.records[1:]),
                         median_total_ms=1e3 * statistics.median(r.total_seconds for r in res.records),
                         merged=s["merged"], ate_mm=1e3 * s["ate_m"]["rmse"] if s.get("ate_m") else None))
        print(f"  frame loop {b:<5} {rows[-1]['hz']:6.1f} Hz  register {rows[-1]['median_register_ms']:.2f} ms  "
              f"ATE {rows[-1]['ate_mm']} mm", flush=True)
    return rows


def markdown(report: dict) -> str:
    lines = [f"# CUDA backend benchmark ({report['machine']['gpu'] or 'no CUDA device'})", "",
             f"CPU: {report['machine']['cpu']}, {report['machine']['cores']} cores; scanalign {report['version']}; "
             f"{report['command']}", "",
             "| source points | backend | align (median) | ratio to all cores | est. ratio to PCL | iterations | "
             "error | pose diff to CPU | tree + upload |", "| ---: | --- | ---: | ---: | ---: | ---: | --- | ---: | ---: |"]
    for n in sorted({r["points"] for r in report["registration"]}):
        rows = [r for r in report["registration"] if r["points"] == n]
        allc = next(r for r in rows if r["backend"].startswith("cpu, ") and r["backend"] != "cpu, 1 thread")
        one = next(r for r in rows if r["backend"] == "cpu, 1 thread")
        pcl = one["median_s"] * PCL_RATIO_1_THREAD
        for r in rows:
            lines.append(f"| {n:,} | {r['backend']} | {r['median_s'] * 1e3:.2f} ms | "
                         f"{allc['median_s'] / r['median_s']:.2f}x | {pcl / r['median_s']:.1f}x | {r['iterations']} | "
                         f"{r['error_mm']:.3f} mm, {r['error_deg']:.4f}° | {r['max_pose_diff_to_cpu']:.1e} | "
                         + ("- |" if r["tree_and_upload_s"] is None else f"{r['tree_and_upload_s'] * 1e3:.1f} ms |"))
    lines += ["", "Ratios above 1: faster than the reference. PCL's time is estimated (not on this machine): "
              f"scanalign's 1-thread time here x {PCL_RATIO_1_THREAD} (PCL/scanalign, 1 thread, development machine).",
              "", "| frame loop | size | frames per second | registration per frame (median) | whole frame (median) | "
              "merged | ATE |", "| --- | --- | ---: | ---: | ---: | ---: | ---: |"]
    for r in report["frame_loop"]:
        ate = "-" if r["ate_mm"] is None else f"{r['ate_mm']:.2f} mm"
        lines.append(f"| {r['backend']} | {r['width']}x{r['height']} | {r['hz']:.1f} Hz | {r['median_register_ms']:.2f} ms"
                     f" | {r['median_total_ms']:.2f} ms | {r['merged']} / {r['frames']} | {ate} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="bench/results/gpu", help="output folder (bench_gpu.json, bench_gpu.md)")
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000], help="source points")
    ap.add_argument("--repeats", type=int, default=5, help="interleaved repeats (halved at 1M points)")
    ap.add_argument("--frames", type=int, default=36, help="the first this many frames of the 36-frame demo loop")
    ap.add_argument("--quick", action="store_true", help="smoke run: 3000 points, 3 frames, 1 repeat")
    a = ap.parse_args(argv)
    if a.quick:
        a.sizes, a.repeats, a.frames = [3000], 1, 3
    devices = cuda_devices()
    cores = os.cpu_count() or 1
    print(f"scanalign {_core.__version__}: CUDA built {_core.built_with_cuda}, devices {devices or 'none'}", flush=True)
    report = dict(version=_core.__version__, command="python bench/bench_gpu.py " + " ".join(sys.argv[1:] if argv is None
                                                                                              else argv),
                  machine=dict(gpu=devices[0] if devices else None, cpu=platform.processor() or platform.machine(),
                               cores=cores),
                  pcl_ratio_1_thread=PCL_RATIO_1_THREAD)
    print("registration (point-to-plane LLS, 2 cm, 50 iterations, epsilons 1e-8)", flush=True)
    report["registration"] = registration_rows(a.sizes, a.repeats, cores, bool(devices))
    print("frame loop (demo settings)", flush=True)
    report["frame_loop"] = frame_loop_rows(a.frames, max(1, a.repeats // 2), bool(devices))
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_gpu.json").write_text(json.dumps(report, indent=2))
    (out / "bench_gpu.md").write_text(markdown(report))
    print(markdown(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Heaps of the built-in parts on the table (scanalign.synthetic.heap): how many of the copies seen to 60 % or more
find_parts finds within 1 mm / 1 degree (over each part's symmetry), how many it finds twice, and how many instances it
reports where no copy is (further than 2 mm / 2 degrees from every copy), per part and sensor noise, over seeds.

    python bench/bench_heap.py [--seeds 3] [--noise zivid sr300 kinect_one] [--out bench/results/heap.md]

One camera image per heap (SR300 intrinsics, 0.5 m from the heap, 69 degrees above the table). Settings: find_parts'
defaults with max_instances 10 (the table's up given: the base frame's z). Besides found / not found, the "ambiguous"
detections are counted: they are not picked, and a pose turned 180 degrees about an axis along which the visible faces look alike is reported
so rather than as found.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from scanalign import _core, pose
from scanalign import synthetic as syn
from scanalign.data import parts
from scanalign.grasp import symmetric_pose_error
from scanalign.pose import model_views as cad
from scanalign.reconstruction import depth_to_cloud
from scanalign.reconstruction.camera import intrinsics_preset
from scanalign.synthetic.heap import drop_heap, visible_fractions

HEAPS = (("block", 6), ("bracket", 6), ("standoff", 8))


def run_heap(name: str, count: int, seed: int, noise: str, models) -> dict:
    mesh, sym = parts.builtin_mesh(name=name), parts.BUILTIN_PARTS[name]
    heap = drop_heap([mesh], count, seed=seed, radius=0.1)
    K = intrinsics_preset("sr300")
    target = np.array([0.5, 0.0, 0.0])
    T = syn.look_at(target + 0.5 * np.array([math.cos(0.3) * math.cos(1.2), math.sin(0.3) * math.cos(1.2),
                                              math.sin(1.2)]), target)
    visible = visible_fractions(heap.scene, T, K)
    r = heap.scene.render(T, K)
    z = _core.synthetic.apply_sensor_noise(syn.NOISE_PRESETS[noise], r.depth, r.cos_incidence, seed + 1)
    p, _ = depth_to_cloud(z, K, max_depth=1.5)
    cloud = p.astype(np.float64) @ T[:3, :3].T + T[:3, 3]
    t0 = time.perf_counter()
    out = pose.find_parts(models, cloud, symmetries=[sym], up=(0, 0, 1), max_instances=10)
    seconds = time.perf_counter() - t0
    hits, wrong, errors, ambiguous = [], 0, [], 0
    for d in out.detections:
        if d.status.name == "not_found":
            continue
        ambiguous += d.status.name == "ambiguous"
        e = [symmetric_pose_error(d.pose.T_scene_model, Tt, sym) for Tt in heap.T_base_part]
        k = int(np.argmin([x[1] for x in e]))
        deg, mm = math.degrees(e[k][0]), 1e3 * e[k][1]
        if deg < 1 and mm < 1:
            hits.append(k)
            errors.append((deg, mm))
        elif deg > 2 or mm > 2:
            wrong += 1
    eligible = [k for k in range(count) if visible[k] >= 0.6]
    return dict(eligible=len(eligible), found=sum(k in hits for k in eligible), duplicates=len(hits) - len(set(hits)),
                wrong=wrong, ambiguous=ambiguous, seconds=seconds, errors=errors)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--noise", nargs="+", default=["zivid", "sr300", "kinect_one"])
    ap.add_argument("--out", type=Path, default=None)
    a = ap.parse_args(argv)
    rows = ["| part | copies | noise | copies seen >= 60 % | found (1 mm / 1 deg) | found twice | "
            "instances where none is | ambiguous | median error (deg / mm) | s per heap |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    for name, count in HEAPS:
        models = [cad.render_views(parts.builtin_mesh(name=name), resolution=100)]
        for noise in a.noise:
            runs = [run_heap(name, count, seed, noise, models) for seed in range(a.seeds)]
            el, fo = sum(r["eligible"] for r in runs), sum(r["found"] for r in runs)
            err = [e for r in runs for e in r["errors"]] or [(math.nan, math.nan)]
            rows.append(f"| {name} | {count} | {noise} | {el} | {fo} ({100 * fo / max(el, 1):.0f} %) | "
                        f"{sum(r['duplicates'] for r in runs)} | {sum(r['wrong'] for r in runs)} | "
                        f"{sum(r['ambiguous'] for r in runs)} | "
                        f"{np.median([e[0] for e in err]):.2f} / {np.median([e[1] for e in err]):.2f} | "
                        f"{np.median([r['seconds'] for r in runs]):.1f} |")
            print(rows[-1], flush=True)
    text = "\n".join(rows) + "\n"
    if a.out:
        a.out.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())

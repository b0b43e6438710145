"""One point-to-plane LLS estimate: scanalign::PointToPlaneLLS against PCL's
TransformationEstimationPointToPlaneLLS on identical correspondences, in one run.

Times are measured in C++ around estimateRigidTransformation alone (the conversion of the
arrays to pcl::PointNormal clouds is excluded). Prints median times, the ratio, and the
largest difference between the two transforms.

    python bench/bench_lls.py [--pairs 300000] [--repeats 7]
"""

from __future__ import annotations

import argparse
import statistics

import numpy as np

from scanalign import _core


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pairs", type=int, default=300000)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    tgt = rng.uniform(-0.1, 0.1, (args.pairs, 3)).astype(np.float32) + np.float32([0, 0, 0.5])
    nrm = rng.normal(size=(args.pairs, 3)).astype(np.float32)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    src = (tgt + rng.normal(0, 0.002, tgt.shape)).astype(np.float32)

    def median(fn):
        runs = [fn() for _ in range(args.repeats)]
        return statistics.median(t for _, t in runs), runs[0][0]

    reg = _core.registration
    t_ours, ours = median(lambda: (lambda r: (r[0], r[4]))(reg.point_to_plane_lls(src, tgt, nrm, 1e-6)))
    t_pcl, theirs = median(lambda: reg.pcl_point_to_plane_lls(src, tgt, nrm))
    print(f"{args.pairs} correspondences, median of {args.repeats} (estimate only, in C++)")
    print(f"scanalign PointToPlaneLLS      {t_ours * 1e3:8.2f} ms")
    print(f"PCL PointToPlaneLLS            {t_pcl * 1e3:8.2f} ms   ({t_pcl / t_ours:.2f}x ours)")
    print(f"max |T_ours - T_pcl|           {np.abs(ours - theirs).max():.2e}")


if __name__ == "__main__":
    main()

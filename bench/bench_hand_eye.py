"""Hand-eye calibration: scanalign.calibration (closed form and refined) against every method
of OpenCV's ``cv2.calibrateHandEye`` (Tsai, Park, Horaud, Andreff, Daniilidis), on the same
synthetic target views (the generator and noise presets of tests/test_hand_eye.py: N robot
poses over a hemisphere 0.35-0.45 m from a target, exact robot poses, camera-pose noise
"zivid" 0.05 mm / 0.01 deg or "sr300" 0.3 mm / 0.05 deg per axis).

Per preset: median rotation (deg) and translation (mm) error of T_flange_camera over
``--seeds`` seeds, and the median wall time of one call (ours: both camera-pose checks, the
closed form over all N(N-1)/2 pairs and the refinement; the closed-form row is the same call
with ``refine=False``). Prints a markdown table. OpenCV 5.0 wheels lack calibrateHandEye:
its rows are then left out (use ``opencv-python-headless<5``).

    python bench/bench_hand_eye.py [--poses 20] [--seeds 100]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_hand_eye import NOISE_PRESETS, errors, target_views  # noqa: E402

from scanalign.calibration import calibrate_hand_eye  # noqa: E402


def solvers():
    out = {"scanalign closed form": lambda A, C: calibrate_hand_eye(A, C, refine=False).T_flange_camera,
           "scanalign refined": lambda A, C: calibrate_hand_eye(A, C).T_flange_camera}
    try:
        import cv2
    except ImportError:
        return out
    if not hasattr(cv2, "calibrateHandEye"):
        print(f"(OpenCV {cv2.__version__} has no calibrateHandEye: its rows are left out)")
        return out

    def opencv(method):
        def solve(A, C):
            R, t = cv2.calibrateHandEye(A[:, :3, :3], A[:, :3, 3], C[:, :3, :3], C[:, :3, 3], method=method)
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = R, np.ravel(t)
            return T
        return solve

    for name in ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS"):
        out[f"OpenCV {cv2.__version__} {name}"] = opencv(getattr(cv2, f"CALIB_HAND_EYE_{name}"))
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--poses", type=int, default=20)
    p.add_argument("--seeds", type=int, default=100)
    args = p.parse_args()
    methods = solvers()
    print(f"\n{args.poses} poses, {args.seeds} seeds; median errors of T_flange_camera, median time per call\n")
    print("| preset | method | rotation (deg) | translation (mm) | time (ms) |")
    print("| --- | --- | --- | --- | --- |")
    for preset in NOISE_PRESETS:
        data = [target_views(args.poses, preset, seed) for seed in range(args.seeds)]
        for name, solve in methods.items():
            errs, times = [], []
            for A, C, X, _ in data:
                t0 = time.perf_counter()
                T = solve(A, C)
                times.append(time.perf_counter() - t0)
                errs.append(errors(T, X))
            rot, trans = np.median(np.array(errs), axis=0)
            print(f"| {preset} | {name} | {rot:.4f} | {trans:.4f} | {1e3 * statistics.median(times):.3f} |")


if __name__ == "__main__":
    main()

"""06: a batch of jobs on a process pool: synthetic reconstructions and pose estimations of the
built-in parts, the part library built once and shared with the workers, one results table.
Checks every job's accuracy against the synthetic truth. With --executor ray the same jobs run on
a local Ray instance (pip install 'scanalign[ray]').

    python examples/python/06_batch_runs.py [--executor ray] [--out scanalign-06]
"""

from __future__ import annotations

import argparse

from scanalign.pipelines import batch
from scanalign.pipelines.batch import Job


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--executor", default="local", choices=["local", "ray"])
    ap.add_argument("--out", default="scanalign-06")
    args = ap.parse_args()
    jobs = [Job(f"rec-{s}", "reconstruct", seed=s, settings={"pixel_stride": 2}) for s in range(2)]
    jobs += [Job(f"pose-{robot}", "pose", robot=robot) for robot in ("ur5", "kr6_r900_sixx")]
    result = batch.run_batch(jobs, args.out, executor=args.executor, workers=2)
    for r in result.records:
        if r["kind"] == "reconstruct":
            print(f"{r['id']}: {r['status']}, ATE RMSE {1000 * r['ate_rmse_m']:.2f} mm, {r['seconds']:.1f} s")
        else:
            print(f"{r['id']}: {r['status']}, {r['found']}/{r['parts']} parts, worst pose error "
                  f"{1000 * r['pose_error_max_m']:.3f} mm / {r['pose_error_max_deg']:.3f} deg, {r['seconds']:.1f} s")
    print("wrote", ", ".join(str(p) for p in result.paths.values()))
    ok = all(r["status"] == "ok" for r in result.records)
    ok &= all(r["ate_rmse_m"] < 0.01 for r in result.records if r["kind"] == "reconstruct")
    ok &= all(r["found"] == 3 and r["pose_error_max_m"] < 0.001 for r in result.records if r["kind"] == "pose")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())

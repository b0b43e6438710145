"""Batch throughput: jobs per minute against workers (1, 2) on the local process pool and a
local Ray instance, the per-job overhead of each executor, and what a multi-node run ships.

1. Throughput: the same mixed manifest (``--jobs`` jobs, half synthetic reconstructions of 36
   frames, half pose estimations of the three built-in parts in the UR5 and KR6 cells) on each
   executor with 1 and 2 workers, one OpenMP thread per job, interleaved over ``--repeats``;
   median wall time and jobs per minute, and the accuracy of every run (median ATE RMSE, worst
   part pose error) so that speed is never bought with results. The part library is built
   once before the timings (its time is printed separately).
2. Overhead: ``--noop`` jobs whose function returns at once: (wall time x workers) / jobs is
   the executor's cost per job (submission, pickling, scheduling, the result's way back).
3. Sizes: the part library on disk and pickled (what Ray's object store ships once per node),
   one pickled Job and one record (per task), a pickled ModelView with its descriptors.

    python bench/bench_batch.py [--jobs 16] [--repeats 2] [--noop 200]
"""

from __future__ import annotations

import argparse
import json
import math
import pickle
import statistics
import sys
import tempfile
import time
from pathlib import Path

from scanalign.pipelines import batch
from scanalign.pipelines.batch import Job
from scanalign.grasp.part_library import build_part_library


def noop(job: Job, library) -> dict:
    """A job that does nothing: the executor's own cost."""
    return {"id": job.id, "kind": job.kind, "status": "ok", "error": "", "seconds": 0.0}


def mixed_jobs(n: int) -> list:
    half = n // 2
    rec = [Job(f"rec-{k}", "reconstruct", seed=k, noise=("sr300", "zivid")[k % 2],
               settings={"pixel_stride": 2}) for k in range(half)]
    pose = [Job(f"pose-{k}", "pose", seed=k, robot=("ur5", "kr6_r900_sixx")[k % 2]) for k in range(n - half)]
    return rec + pose


def run(executor: str, workers: int, jobs: list, out: Path, runner=batch.run_job) -> tuple:
    t0 = time.perf_counter()
    r = batch.run_batch(jobs, out, executor=executor, workers=workers, retries=0, progress=False,
                        runner=runner)
    return time.perf_counter() - t0, r


def finite(values):
    return [v for v in values if isinstance(v, float) and math.isfinite(v)]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--jobs", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--noop", type=int, default=200)
    ap.add_argument("--json", type=Path, help="also write the figures here")
    args = ap.parse_args()
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False,
             runtime_env={"env_vars": {"PYTHONPATH": str(Path(batch.__file__).resolve().parents[2])}})
    ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])  # the noop runner, for Ray's workers
    tmp = Path(tempfile.mkdtemp(prefix="bench-batch-"))
    t0 = time.perf_counter()
    library = build_part_library(batch.DEFAULT_PARTS)
    library_seconds = time.perf_counter() - t0
    jobs = mixed_jobs(args.jobs)
    figures: dict = {"jobs": len(jobs), "library_build_seconds": library_seconds, "throughput": {}, "overhead": {}}
    cases = [(e, w) for w in (1, 2) for e in ("local", "ray")]
    walls = {c: [] for c in cases}
    accuracy = {}
    for rep in range(args.repeats):
        for e, w in cases:  # interleaved: drift on the machine hits every case alike
            out = tmp / f"{e}-{w}-{rep}"
            out.mkdir()
            library.save(out / "parts.npz")  # built once above; every run loads it
            wall, r = run(e, w, jobs, out)
            walls[(e, w)].append(wall)
            assert all(x["status"] == "ok" for x in r.records), [x["error"] for x in r.records if x["error"]]
            accuracy[(e, w)] = (statistics.median(finite([x["ate_rmse_m"] for x in r.records])),
                                max(finite([x["pose_error_max_m"] for x in r.records])),
                                max(finite([x["pose_error_max_deg"] for x in r.records])))
    print(f"part library (3 parts, 42 views each, described once): {library_seconds:.2f} s\n")
    print(f"| executor | workers | wall (s, median of {args.repeats}) | jobs/min | speed-up | median ATE RMSE (mm) "
          f"| worst pose error (mm / deg) |")
    print("|---|---|---|---|---|---|---|")
    for e, w in cases:
        wall = statistics.median(walls[(e, w)])
        base = statistics.median(walls[(e, 1)])
        ate, pm, pd = accuracy[(e, w)]
        figures["throughput"][f"{e}-{w}"] = {"wall_s": wall, "jobs_per_min": 60 * len(jobs) / wall,
                                             "ate_rmse_median_m": ate, "pose_error_max_m": pm,
                                             "pose_error_max_deg": pd}
        print(f"| {e} | {w} | {wall:.1f} | {60 * len(jobs) / wall:.1f} | {base / wall:.2f} | {1000 * ate:.2f} "
              f"| {1000 * pm:.3f} / {pd:.3f} |")
    print(f"\nper-job overhead ({args.noop} no-op jobs, 2 workers):\n")
    print("| executor | wall (s) | overhead per job (ms, wall x workers / jobs) |")
    print("|---|---|---|")
    noops = [Job(f"n{k}", "reconstruct") for k in range(args.noop)]  # no parts: no library to load
    for e in ("local", "ray"):
        out = tmp / f"noop-{e}"
        wall, _ = run(e, 2, noops, out, runner=noop)
        figures["overhead"][e] = {"wall_s": wall, "per_job_ms": 1000 * wall * 2 / len(noops)}
        print(f"| {e} | {wall:.2f} | {1000 * wall * 2 / len(noops):.1f} |")
    record = json.loads((tmp / "local-1-0" / "records.jsonl").read_text().splitlines()[0])
    view = library["block"].views[0]
    sizes = {"library_npz_bytes": (tmp / "local-1-0" / "parts.npz").stat().st_size,
             "library_pickled_bytes": len(pickle.dumps(library, protocol=5)),
             "job_pickled_bytes": len(pickle.dumps(jobs[-1], protocol=5)),
             "record_json_bytes": len(json.dumps(record)),
             "model_view_pickled_bytes": len(pickle.dumps(view, protocol=5)),
             "model_view_points": len(view)}
    figures["sizes"] = sizes
    print("\nsizes: " + ", ".join(f"{k} {v:,}" for k, v in sizes.items()))
    ray.shutdown()
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Runs the fuzz targets of one module in this process (started by tests/test_fuzz.py).

    python tests/fuzz/run.py MODULE --examples N --log FILE [--seed S]

Every input is written to the log (one line, flushed) before the call, so a crash or a
hang (the watchdog kills the process after --call-timeout seconds and dumps the stacks)
leaves its reproducer as the log's last line. Findings that raise are shrunk by hypothesis
and printed; the exit status is the number of failing targets (capped at 100), and the
last stdout line is a JSON summary.
"""

from __future__ import annotations

import argparse
import faulthandler
import json
import os
import resource
import sys
import time
import traceback

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from hypothesis import HealthCheck, given, settings  # noqa: E402

import contract  # noqa: E402
import targets  # noqa: E402


def _runner(name, strategy, fn, args, log, tried, slowest):
    @settings(max_examples=max(5, int(args.examples * getattr(fn, 'weight', 1.0))), deadline=None, database=None, derandomize=args.seed is None,
              suppress_health_check=list(HealthCheck), print_blob=True)
    @given(case=strategy)
    def run(case):
        tried[0] += 1
        log.write(f"{name} {case!r}\n")
        faulthandler.dump_traceback_later(args.call_timeout, exit=True)
        t0 = time.perf_counter()
        try:
            fn(case)
        finally:
            faulthandler.cancel_dump_traceback_later()
            dt = time.perf_counter() - t0
            if dt > slowest[0]:
                slowest[:] = [dt, repr(case)[:400]]
    return run


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("module")
    ap.add_argument("--examples", type=int, default=100)
    ap.add_argument("--log", required=True)
    ap.add_argument("--call-timeout", type=float, default=60.0)
    ap.add_argument("--memory-gb", type=float, default=4.0)
    ap.add_argument("--seed", type=int, default=None, help="random seed (default: derandomised, as in CI)")
    args = ap.parse_args()
    limit = int(args.memory_gb * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))  # an unbounded allocation fails, not the machine
    log = open(args.log, "w", buffering=1)
    summary = {"module": args.module, "targets": {}, "failures": {}}
    for name, strategy, fn in targets.TARGETS[args.module]:
        before = dict(contract.STATS)
        tried = [0]

        slowest = [0.0, ""]
        run = _runner(name, strategy, fn, args, log, tried, slowest)
        t0 = time.perf_counter()
        try:
            if args.seed is not None:
                run = __import__("hypothesis").seed(args.seed)(run)
            run()
        except Exception as exc:  # noqa: BLE001 - every finding is reported, then the next target runs
            found = getattr(exc, "exceptions", [exc])  # hypothesis groups distinct failures
            summary["failures"][name] = [f"{type(e).__name__}: {str(e)[:300]} | {getattr(e, '__notes__', [''])[0][:1200]}"
                                         for e in found]
            traceback.print_exc()
        stats = {k: contract.STATS[k] - before[k] for k in contract.STATS}
        summary["targets"][name] = dict(examples=tried[0], seconds=round(time.perf_counter() - t0, 1), **stats,
                                        slowest_call=[round(slowest[0], 2), slowest[1]])
    log.write("done\n")
    print(json.dumps(summary))
    return min(len(summary["failures"]), 100)


if __name__ == "__main__":
    sys.exit(main())

"""Reproduces the experiments of scanalign's two source works in one report (markdown + PNG):

- the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929): Figs. 4-9 and Table 1;
- Kleppe's thesis (NTNU 2018): Paper 3's three experiments (the two-step pose and assembly:
  Tables 1-6 and the ten assemblies), Paper 4 Table 1 (flags), Paper 5 experiment 1 (the
  descriptor sweep, Fig. 9) and experiment 2 (Tables I and II, every baseline).

Each figure and table stands beside the source's own numbers and says what differs. ``--quick``
runs every experiment at a reduced size (about two minutes on two cores) and checks each
source's qualitative claims: it exits 1 when a claim no longer holds, so the reproduction
cannot rot (the test command runs it).

    python bench/reproduce.py [--quick] [--only eye_in_hand paper3 paper4 paper5] [--out bench/results/reproduction]
"""

from __future__ import annotations

import argparse
import importlib
import os
import platform
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from experiments import Section  # noqa: E402

MODULES = ("eye_in_hand", "paper3", "paper4", "paper5")


def report(sections: "list[Section]", args: argparse.Namespace, seconds: float) -> str:
    checks = [c for s in sections for c in s.checks]
    failed = [c for c in checks if not c.passed]
    lines = ["# Reproduction of the source works' experiments", "",
             f"Made by `python bench/reproduce.py{' --quick' if args.quick else ''}"
             f"{' --only ' + ' '.join(args.only) if args.only != list(MODULES) else ''}` in {seconds / 60:.1f} min "
             f"on {platform.machine()} with {os.cpu_count()} cores, "
             f"{'quick (reduced) sizes' if args.quick else 'full sizes'}"
             + (", the eye-in-hand loops reused from an earlier run's cache (SCANALIGN_REPRO_CACHE)"
                if os.environ.get("SCANALIGN_REPRO_CACHE") else "") + ".", "",
             f"Claims checked: {len(checks) - len(failed)} of {len(checks)} hold.", ""]
    lines += [f"- [{'x' if c.passed else ' '}] {c.claim}: {c.detail}" for c in checks]
    for s in sections:
        lines += ["", f"## {s.title}", "", s.markdown, ""]
        lines += [f"![{p.name}]({p.relative_to(args.out).as_posix()})" for p in s.figures]
    return "\n".join(lines) + "\n"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="reduced sizes; exit 1 if a claim fails")
    ap.add_argument("--only", nargs="+", choices=MODULES, default=list(MODULES), help="experiments to run")
    ap.add_argument("--out", type=Path, default=Path("bench/results/reproduction"), help="report folder")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    sections = []
    for name in args.only:
        module = importlib.import_module(f"experiments.{name}")
        sections += module.run(args.out, args.quick, lambda msg: print(msg, file=sys.stderr, flush=True))
    text = report(sections, args, time.perf_counter() - t0)
    (args.out / "report.md").write_text(text)
    failed = [c for s in sections for c in s.checks if not c.passed]
    print(f"report: {args.out / 'report.md'}; {len(failed)} claim(s) failed", file=sys.stderr)
    for c in failed:
        print(f"  FAILED: {c.claim}: {c.detail}", file=sys.stderr)
    return 1 if failed and args.quick else 0


if __name__ == "__main__":
    sys.exit(main())

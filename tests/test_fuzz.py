"""Property-based fuzzing of every public entry point (hypothesis), one module per test.

Each module's targets (tests/fuzz/targets.py) run in a child process under a memory limit
(an unbounded allocation fails instead of swapping) with a per-call watchdog (a hang dumps
the stacks and exits), so a crash or a hang fails that module's test and names the input
that caused it (the child logs every input before the call). The contract is in
tests/fuzz/contract.py.

Budget: ``SCANALIGN_FUZZ_EXAMPLES`` examples per target (default 400, about one minute in
all on two cores, derandomised so CI is reproducible). For a longer hunt with fresh
random inputs: ``SCANALIGN_FUZZ_EXAMPLES=2000 SCANALIGN_FUZZ_SEED=$RANDOM pytest tests/test_fuzz.py``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("hypothesis", reason="the fuzz tests need hypothesis (README test command installs it)")

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE / "fuzz"))
from targets import TARGETS  # noqa: E402

EXAMPLES = int(os.environ.get("SCANALIGN_FUZZ_EXAMPLES", "400"))
SEED = os.environ.get("SCANALIGN_FUZZ_SEED")


@pytest.mark.parametrize("module", sorted(TARGETS))
def test_fuzz_module_keeps_the_contract(module, tmp_path):
    log = tmp_path / f"{module}.log"
    cmd = [sys.executable, str(HERE / "fuzz" / "run.py"), module, "--examples", str(EXAMPLES), "--log", str(log)]
    if SEED:
        cmd += ["--seed", SEED]
    # the child imports scanalign as this process does (the installed package, or PYTHONPATH)
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60 * max(10, EXAMPLES // 10))
    lines = log.read_text().splitlines() if log.exists() else []
    if proc.returncode < 0 or not lines or lines[-1] != "done":
        pytest.fail(f"{module}: the process died (status {proc.returncode}) on\n  {lines[-1] if lines else '?'}\n"
                    f"{proc.stderr[-3000:]}")
    summary = json.loads(proc.stdout.strip().splitlines()[-1])
    assert not summary["failures"], f"{module}: contract broken:\n" + "\n".join(
        f"- {name}: {m}" for name, msgs in summary["failures"].items() for m in msgs)
    for name, stats in summary["targets"].items():
        # A target whose every call was refused tests only the argument checks.
        assert stats["returned"] > 0, f"{module}.{name} never reached the algorithm: {stats}"
    print(json.dumps(summary))

"""The numbered Python examples run to completion (each checks its own result against a known
truth and exits non-zero when it misses)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = sorted((Path(__file__).resolve().parents[1] / "examples" / "python").glob("[0-9][0-9]_*.py"))


@pytest.mark.parametrize("example", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_example_runs(example, tmp_path):
    env = {**os.environ, "MPLBACKEND": "Agg"}
    r = subprocess.run([sys.executable, str(example)], cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0, f"{example.name} failed:\n{r.stdout[-2000:]}\n{r.stderr[-2000:]}"


def test_every_numbered_example_is_collected():
    assert [p.name[:2] for p in EXAMPLES] == ["01", "02", "03", "04", "05", "06"]

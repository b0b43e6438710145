"""Batch runs from a user's script (docs/batch.md): the local pool's workers start with the 'spawn' method and import
the main script again, so a script without the ``if __name__ == "__main__":`` guard must be told so, not see its jobs
recorded as native crashes; workers that die while starting are reported as that; a batch whose every job failed
says so and exits non-zero."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

from scanalign.pipelines import batch

ENV = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
BODY = """\
result = batch.run_batch([batch.Job("a", "reconstruct", frames=2), batch.Job("b", "reconstruct", frames=2)],
                         "out", workers=2, retries=0, progress=False)
print(batch.summarize(result)["status"])
"""


def run_script(folder, guarded: bool) -> subprocess.CompletedProcess:
    body = "if __name__ == '__main__':\n" + textwrap.indent(BODY, "    ") if guarded else BODY
    (folder / "script.py").write_text("from scanalign.pipelines import batch\n" + body)
    return subprocess.run([sys.executable, "script.py"], cwd=folder, capture_output=True, text=True, env=ENV,
                          timeout=600)


def test_a_script_without_the_main_guard_is_told_to_add_it(tmp_path):
    r = run_script(tmp_path, guarded=False)
    assert r.returncode == 1, (r.stdout, r.stderr)  # the script stops: no job could run
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("RuntimeError: the local pool's workers died while starting, before running any job")
    assert str(tmp_path / "script.py") in last and "'if __name__ == \"__main__\":'" in last, last
    assert "native code" not in r.stderr and "crashed" not in r.stdout
    assert not (tmp_path / "out" / "summary.json").exists()  # no job is blamed
    # the fix the message names: the same script under the guard runs both jobs
    r = run_script(tmp_path, guarded=True)
    assert r.returncode == 0 and r.stdout.strip() == "{'ok': 2}", (r.stdout, r.stderr)


def test_workers_that_die_loading_the_part_library_are_reported_as_that(tmp_path):
    missing = tmp_path / "missing.npz"
    with pytest.raises(RuntimeError, match=r"workers died loading the part library .*missing\.npz"):
        list(batch.LocalExecutor(1).run([batch.Job("a", "reconstruct", frames=2)], missing))


def test_a_batch_whose_every_job_failed_says_so_and_exits_non_zero(tmp_path):
    (tmp_path / "m.yaml").write_text("jobs:\n  - {id: gone, kind: reconstruct, source: missing_folder, seeds: 2}\n")
    r = subprocess.run([sys.executable, "-m", "scanalign.cli", "batch", str(tmp_path / "m.yaml"), "--retries", "0",
                        "--no-plots", "--out", str(tmp_path / "out"), "--quiet"],
                       capture_output=True, text=True, env=ENV, timeout=600)
    assert r.returncode == 1, (r.stdout, r.stderr)
    assert r.stderr.strip().splitlines()[-1] == "scanalign batch: every job failed or crashed (2 of 2)", r.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["verdict"] == "every job failed or crashed (2 of 2)" and summary["status"] == {"failed": 2}
    # from Python: the result says it, and a partly failed batch is counted as that
    (tmp_path / "m.yaml").write_text("jobs:\n  - {id: gone, kind: reconstruct, source: missing_folder}\n"
                                     "  - {id: ok, kind: reconstruct, frames: 2}\n")
    result = batch.run_batch(batch.read_manifest(tmp_path / "m.yaml"), tmp_path / "out2", workers=1, retries=0,
                             progress=False)
    assert not result.ok and batch.summarize(result)["verdict"] == "1 of 2 jobs failed or crashed"
    assert [r["status"] for r in result.records] == ["failed", "ok"]

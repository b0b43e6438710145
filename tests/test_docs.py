"""The docs are tests: every ```python and ```bash block of README.md and docs/**/*.md runs as written, in
an empty folder, and prints what the text says it prints (markers: docs/testing.md, "The docs are tests")."""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from docs_blocks import ROOT, Block, all_blocks, output_problem, undefined_names

BLOCKS = all_blocks()
RUN = [b for b in BLOCKS if b.runnable]
_done: dict = {}  # Block.id -> None (ran as the page says) or why not


@pytest.fixture(scope="session")
def docs_env(tmp_path_factory) -> dict:
    """The inherited environment with PATH starting at this interpreter's folder (its `scanalign`
    console script, or a shim running `python -m scanalign.cli` where it has none, e.g. under
    PYTHONPATH in development) and PYTHONPATH made absolute."""
    env = dict(os.environ)
    bindir = Path(sys.executable).parent
    shims = tmp_path_factory.mktemp("shims")
    for name, args in (("scanalign", "-m scanalign.cli"), ("python", "")):
        if shutil.which(name, path=str(bindir)) is None:
            (shims / name).write_text(f'#!/bin/sh\nexec "{sys.executable}" {args} "$@"\n')
            (shims / name).chmod(0o755)
    env["PATH"] = os.pathsep.join([str(bindir), str(shims), env.get("PATH", "")])
    if env.get("PYTHONPATH"):
        env["PYTHONPATH"] = os.pathsep.join(str(Path(p).resolve()) for p in env["PYTHONPATH"].split(os.pathsep))
    env.setdefault("MPLBACKEND", "Agg")
    return env


def _script(block: Block) -> str:
    return block.prelude + block.code


def _check_syntax(block: Block) -> None:
    if block.lang == "python":
        compile(_script(block), block.id, "exec")
    else:
        r = subprocess.run(["bash", "-n"], input=_script(block), capture_output=True, text=True)
        assert r.returncode == 0, f"{block.id}: not valid bash:\n{r.stderr}"


def _run(block: Block, folder: Path, scripts: Path, env: dict) -> str | None:
    """Runs one block in ``folder``; None when it did what the page says, else why not."""
    if "file" in block.markers:
        (folder / block.markers["file"]).write_text(block.code, encoding="utf-8")
        return None
    script = scripts / (block.id.replace("/", "_").replace(":", "-") + (".py" if block.lang == "python" else ".sh"))
    script.write_text(_script(block), encoding="utf-8")
    command = [sys.executable, str(script)] if block.lang == "python" else ["bash", "-e", "-o", "pipefail", str(script)]
    timeout = float(block.markers.get("timeout", 120))
    with subprocess.Popen(command, cwd=folder, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          start_new_session=True) as proc:
        try:
            out, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            out, err = proc.communicate()
            return f"still running after {timeout:g} s (a `timeout: N` marker sets the limit)\n{err[-3000:]}"
    if proc.returncode != 0:
        # Script lines -> page lines, so a traceback points into the page.
        shift = block.line - block.prelude.count("\n")
        err = re.sub(rf'"{re.escape(str(script))}", line (\d+)',
                     lambda m: f'{block.id.split(":")[0]}, line {int(m.group(1)) + shift}', err)
        return f"exit status {proc.returncode}\n--- stdout\n{out[-3000:]}\n--- stderr\n{err[-5000:]}"
    if block.expected is not None:
        return output_problem(block.expected, out, block.tolerance)
    return None


def _ensure(block: Block, tmp_path_factory, env: dict) -> str | None:
    """Runs ``block`` after the blocks of its folder before it (once each)."""
    if block.id not in _done:
        first = block.chain or block
        chain = [b for b in BLOCKS if b is first or b.chain is first]
        folder = _done.setdefault(("folder", first.id), tmp_path_factory.mktemp("docs"))
        for b in chain[:chain.index(block) + 1]:
            if b.id in _done:
                continue
            if "skip" in b.markers or "sketch" in b.markers:
                _done[b.id] = None
            elif failed := next((p.id for p in chain[:chain.index(b)] if _done.get(p.id)), None):
                _done[b.id] = f"not run: {failed}, whose folder it continues, failed"
            else:
                scripts = _done.setdefault("scripts", tmp_path_factory.mktemp("scripts"))
                _done[b.id] = _run(b, folder, scripts, env)
    return _done[block.id]


@pytest.mark.parametrize("block", RUN, ids=[b.id for b in RUN])
def test_block(block: Block, docs_env: dict, tmp_path_factory) -> None:
    _check_syntax(block)
    if "skip" in block.markers:
        pytest.skip(block.markers["skip"] or "marked skip")
    if "sketch" in block.markers:
        if block.lang == "python" and (missing := undefined_names(_script(block))):
            pytest.fail(f"{block.id}: a sketch whose prelude does not define {', '.join(missing)}")
        return
    if problem := _ensure(block, tmp_path_factory, docs_env):
        pytest.fail(f"{block.id}: {problem}", pytrace=False)


def test_file_blocks_equal_the_examples() -> None:
    """A `file:` block that shows a file shipped in examples/ shows it as it is."""
    shown = [b for b in BLOCKS if (ROOT / "examples" / b.markers.get("file", "-")).is_file()]
    assert shown, "no page shows a file of examples/"
    for b in shown:
        assert b.code == (ROOT / "examples" / b.markers["file"]).read_text(encoding="utf-8"), b.id


def test_markers_are_known() -> None:
    known = {"skip", "sketch", "continue", "timeout", "prelude", "file", "tolerance"}
    for b in BLOCKS:
        assert set(b.markers) <= known, f"{b.id}: unknown docs-test marker(s) {set(b.markers) - known}"
        assert ROOT in b.page.parents or b.page.parent == ROOT

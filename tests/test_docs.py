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

from docs_blocks import ROOT, Block, all_blocks, output_problem, parse_page, undefined_names

BLOCKS = all_blocks()
RUN = [b for b in BLOCKS if b.runnable]
_results: dict = {}  # Block.id -> None (did what the page says) or why not
_folders: dict = {}  # id of the first block of a folder -> the folder


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
    """Runs ``block`` after the blocks before it in its folder (each once); None when it did what the page says."""
    first = block.chain or block
    chain = [b for b in BLOCKS if b is first or b.chain is first]
    folder = _folders.setdefault(first.id, tmp_path_factory.mktemp("docs"))
    scripts = _folders.setdefault("scripts", tmp_path_factory.mktemp("scripts"))
    for b in chain[:chain.index(block) + 1]:
        if b.id in _results:
            continue
        if "skip" in b.markers or "sketch" in b.markers:
            _results[b.id] = None
        elif failed := next((p.id for p in chain[:chain.index(b)] if _results.get(p.id)), None):
            _results[b.id] = f"not run: {failed}, whose folder it continues, failed"
        else:
            _results[b.id] = _run(b, folder, scripts, env)
    return _results[block.id]


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


def test_the_collector_reads_markers_and_catches_wrong_output(tmp_path, monkeypatch) -> None:
    """The parser and the output check on a made-up page: a test of the docs that could not fail would be no test."""
    monkeypatch.setattr("docs_blocks.ROOT", tmp_path)
    page = tmp_path / "page.md"
    page.write_text("<!-- docs-test: prelude\nx = 2\n-->\n```python\nprint(x * 1.01, 'mm')\n```\n\nIt prints:\n\n"
                    "<!-- docs-test: tolerance: 5% -->\n```text\n2 mm\n```\n\n<!-- docs-test: file: a.yaml -->\n"
                    "```yaml\nk: 1\n```\n<!-- docs-test: continue -->\n<!-- docs-test: timeout: 5 -->\n```bash\ncat a.yaml\n```\n"
                    "\n## Later\n\n```text\nnot an output\n```\n")
    first, file_block, last = parse_page(page)
    assert (first.line, first.prelude, first.expected, first.tolerance) == (4, "x = 2\n", "2 mm\n", "5%")
    assert file_block.markers["file"] == "a.yaml" and last.chain is file_block and last.markers["timeout"] == "5"
    assert last.expected is None  # a ```text block under another heading is not an output
    assert output_problem(first.expected, "2.02 mm\n", first.tolerance) is None
    assert "not 2.0 within 5%" in output_problem(first.expected, "2.2 mm\n", first.tolerance)
    assert "differs" in output_problem("converged ... 3\n", "converged 1 2 4\n")
    assert output_problem("a\n...\nd\n", "a\nb\nc\nd  \n") is None
    assert undefined_names("import numpy as np\nfor k in q:\n    np.f(points, k)\n") == ["points", "q"]
    page.write_text("<!-- docs-test: prelude\nx = 1\n```python\n")
    with pytest.raises(ValueError, match=r"page.md:1: a docs-test marker without its `-->` line"):
        parse_page(page)

"""The package's architecture rules (docs/architecture.md), checked on its source: the layers
contract of pyproject.toml (import-linter, function-local imports included), no module that
imports another's private names, few function-local imports of the package's own modules,
and at most 20 top-level modules and packages that mirror the compiled core's areas."""

from __future__ import annotations

import ast
import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import scanalign
from scanalign import _core

PACKAGE = Path(scanalign.__file__).parent
ROOT = Path(__file__).resolve().parents[1]
AREAS = {"common", "io", "registration", "features", "segmentation", "fitting", "cga", "calibration", "evaluation",
         "kinematics", "reconstruction", "pose", "grasp", "synthetic"}
DATA = {"data"}  # what ships and what is fetched: below the areas that use the built-in parts
APPLICATIONS = {"datasets", "pipelines", "viz", "cli"}


def _sources():
    return sorted(p for p in PACKAGE.rglob("*.py"))


def _module_of(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _own_imports(path: Path):
    """(node, imported module, names, is_local) for each import of scanalign's own modules."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    local = set()
    for fn in ast.walk(tree):
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            local |= {id(n) for n in ast.walk(fn) if isinstance(n, (ast.Import, ast.ImportFrom))}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "scanalign":
            yield node, node.module, [a.name for a in node.names], id(node) in local
        elif isinstance(node, ast.ImportFrom) and node.level:
            yield node, "(relative)", [a.name for a in node.names], id(node) in local
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == "scanalign":
                    yield node, a.name, [], id(node) in local


def test_top_level_is_the_area_map():
    top = {p.stem for p in PACKAGE.glob("*.py") if p.stem != "__init__"} | {
        p.name for p in PACKAGE.iterdir() if p.is_dir() and (p / "__init__.py").exists()}
    assert top == AREAS | DATA | APPLICATIONS, sorted(top ^ (AREAS | DATA | APPLICATIONS))
    assert len(top) + 1 <= 20  # + the compiled core
    # Every area of the compiled core has its Python area of the same name.
    core_areas = {n for n in dir(_core) if not n.startswith("_") and type(getattr(_core, n)).__name__ == "module"}
    assert core_areas <= AREAS, sorted(core_areas - AREAS)
    assert sorted(scanalign.__all__[1:]) == sorted(top)


def test_no_relative_or_private_cross_module_imports():
    bad = []
    for path in _sources():
        me = _module_of(path)
        for node, module, names, _ in _own_imports(path):
            if module == "(relative)":
                bad.append(f"{path.name}:{node.lineno}: relative import")
                continue
            if module == "scanalign._core" or module.startswith("scanalign._core."):
                continue
            private = [n for n in names if n.startswith("_") and n != "_core" and not n.startswith("__")]
            if private and module != me:
                bad.append(f"{me}:{node.lineno}: imports {private} from {module}")
            hidden = [p for p in module.split(".")[1:] if p.startswith("_") and p != "_core"]
            if hidden:
                bad.append(f"{me}:{node.lineno}: imports private module {module}")
    assert not bad, "\n".join(bad)


def test_few_function_local_imports_of_own_modules():
    local = [f"{_module_of(p)}:{node.lineno} {module}" for p in _sources()
             for node, module, _, is_local in _own_imports(p) if is_local]
    assert len(local) <= 20, "\n".join(local)


def test_areas_import_no_application_and_nothing_imports_the_cli():
    """A cheap restatement of the layers contract that runs without import-linter."""
    bad = []
    for path in _sources():
        me = _module_of(path).split(".")
        top = me[1] if len(me) > 1 else ""
        for node, module, names, _ in _own_imports(path):
            target = module.split(".")
            other = target[1] if len(target) > 1 else (names[0] if names else "")
            if top in AREAS | DATA and other in APPLICATIONS:
                bad.append(f"{'.'.join(me)}:{node.lineno} imports {module} {names}")
            if other == "cli" and top != "cli":
                bad.append(f"{'.'.join(me)}:{node.lineno} imports the CLI")
    assert not bad, "\n".join(bad)


@pytest.mark.skipif(importlib.util.find_spec("importlinter") is None, reason="import-linter not installed")
def test_layers_contract_holds():
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent)) or shutil.which("lint-imports")
    assert exe, "import-linter is installed but lint-imports is not on PATH"
    r = subprocess.run([exe, "--config", str(ROOT / "pyproject.toml")], capture_output=True, text=True, cwd=ROOT,
                       timeout=300)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]
    assert "2 kept, 0 broken" in r.stdout

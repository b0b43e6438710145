"""The installed package ships type stubs (.pyi) of the compiled module, generated from the
C++ bindings at build time, and they declare every class and function the module has."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import pytest

from scanalign import _core


def _stub_dir() -> Path:
    so = Path(_core.__file__)
    if so.is_symlink():  # a developer's source checkout linking the build folder's module
        pytest.skip("stubs are installed with the package, not linked into a source checkout")
    return so.parent / "_core"


def _declared(path: Path) -> set:
    tree = ast.parse(path.read_text())
    return {n.name for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef))}


@pytest.mark.parametrize("name", sorted(n for n, m in inspect.getmembers(_core, inspect.ismodule)))
def test_every_class_and_function_of_a_submodule_is_in_its_stub(name):
    stub = _stub_dir() / f"{name}.pyi"
    assert stub.is_file(), f"missing {stub}"
    module = getattr(_core, name)
    public = {n for n, v in vars(module).items()
              if not n.startswith("_") and (inspect.isclass(v) or callable(v)) and not inspect.ismodule(v)}
    missing = public - _declared(stub)
    assert not missing, f"{name}.pyi lacks {sorted(missing)}"
    assert "detail::" not in stub.read_text()  # no raw C++ types leaked into signatures

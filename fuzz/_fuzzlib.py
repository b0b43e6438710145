"""Shared set-up of the atheris fuzz targets in this folder (see README.md).

Each target hands :func:`run` its one-input function and a few valid files of its format.
Without a corpus folder on the command line, those seeds are written to a fresh temporary
folder that becomes the corpus, so every run starts from well-formed input and mutates it.
The contract every reader must keep: return a valid object or raise ValueError (including
scanalign's TumFormatError) or OSError; any other exception, a crash, a hang (-timeout) or
memory beyond -rss_limit_mb is a finding and ends the run with a non-zero exit status.
"""

from __future__ import annotations

import os
import re
import sys
import tempfile
import zlib
from pathlib import Path
from typing import Callable, Dict

import atheris

#: Exceptions a reader may raise on bad input; anything else is a finding.
ALLOWED = (ValueError, OSError)

_scratch = Path(tempfile.mkdtemp(prefix="scanalign-fuzz-"))


def as_file(data: bytes, suffix: str) -> Path:
    """``data`` written to a scratch file with the given extension (readers pick the format by it)."""
    path = _scratch / f"input{suffix}"
    path.write_bytes(data)
    return path


# The C++ parsers give atheris no coverage (see README.md), so a target reports which outcome an
# input reached (the error message without its numbers, or what was read) through one of
# _OUTCOMES branches of an instrumented function: an input reaching a new check in the C++
# code then counts as new coverage and stays in the corpus instead of being reduced away.
_OUTCOMES = 256
_namespace: dict = {}
exec("def _outcome(k):\n" + "".join(f"    if k == {i}:\n        return {i}\n" for i in range(_OUTCOMES)), _namespace)
_outcome = atheris.instrument_func(_namespace["_outcome"])


def outcome(label: str) -> None:
    """Feeds the outcome ``label`` (e.g. an error message) back to atheris as coverage."""
    _outcome(zlib.crc32(re.sub(r"\d[\d.e+-]*|'[^']*'|/\S+", "#", label).encode()) % _OUTCOMES)


def run(test_one_input: Callable[[bytes], None], seeds: Dict[str, bytes]) -> None:
    args = list(sys.argv)
    if not any(not a.startswith("-") for a in args[1:]):
        corpus = Path(tempfile.mkdtemp(prefix=f"{Path(args[0]).stem}-corpus-"))
        for name, data in seeds.items():
            (corpus / name).write_bytes(data)
        args.append(str(corpus))
    if not any(a.startswith("-max_len=") for a in args):
        args.append(f"-max_len={max(4096, 2 * max(map(len, seeds.values())))}")
    atheris.Setup(args, test_one_input)
    atheris.Fuzz()


def instrumented():
    """Context manager instrumenting scanalign's Python modules (and plyfile, Pillow) for
    atheris' coverage feedback; the C++ core is not instrumented (see README.md)."""
    return atheris.instrument_imports(include=["scanalign", "plyfile", "PIL"])


os.environ.setdefault("OMP_NUM_THREADS", "1")

"""Reproductions of the two source works' experiments, assembled into one report by
``bench/reproduce.py``.

Each module has ``run(out: Path, quick: bool, log) -> list[Section]``: it runs its
experiments (``quick``: a reduced size for CI), writes its PNG figures under ``out`` and
returns one ``Section`` per figure or table of the source, with the source's own numbers
beside ours and the qualitative claims checked.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, List


@dataclass
class Check:
    """A qualitative claim of the source, checked on our run (``--quick`` fails if not)."""

    claim: str  # the source's claim in one line, e.g. "LLS fails below 10 images per loop"
    passed: bool
    detail: str  # the measured figures behind the verdict


@dataclass
class Section:
    """One figure or table of a source work, reproduced."""

    title: str  # e.g. "Eye-in-hand paper, Fig. 7: ATE vs images per loop"
    markdown: str  # our tables beside the source's numbers, the set-up, and what differs
    figures: List[Path] = field(default_factory=list)  # PNGs written under the output folder
    checks: List[Check] = field(default_factory=list)
    seconds: float = 0.0  # wall time spent on this section


Log = Callable[[str], None]


class Timer:
    """``with Timer() as t: ...; t.seconds``"""

    def __enter__(self) -> "Timer":
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc) -> None:
        self.seconds = time.perf_counter() - self.t0

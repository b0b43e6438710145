"""The fenced code blocks of README.md and docs/**/*.md, read as tests (docs/testing.md, "The docs
are tests"): which blocks run, with which markers, and what output the text states."""

from __future__ import annotations

import ast
import builtins
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Dict, List, Optional

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
LANGS = {"python": "python", "bash": "bash", "sh": "bash"}
_FENCE = re.compile(r"^```\s*([\w+-]*)\s*$")
_MARKER = re.compile(r"^<!--\s*docs-test:\s*([\w-]+)\s*:?\s*(.*?)\s*(-->)?\s*$")
_NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?"


@dataclass
class Block:
    """One fenced block and the ``<!-- docs-test: ... -->`` markers right above it."""

    page: Path
    line: int  # of the opening fence, 1-based
    lang: str
    code: str
    markers: Dict[str, str] = field(default_factory=dict)
    expected: Optional[str] = None  # the ```text block below it (no other block or heading between): its stdout
    tolerance: Optional[str] = None  # the expected block's own `tolerance:` marker
    chain: Optional["Block"] = None  # the first block of the folder it shares (`continue`), else None
    end: int = 0  # 0-based index of the closing fence

    @property
    def id(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"

    @property
    def runnable(self) -> bool:
        return self.lang in LANGS

    @property
    def prelude(self) -> str:
        return self.markers.get("prelude", "")


def parse_page(page: Path) -> List[Block]:
    """The runnable and `file:` blocks of ``page``, with their markers, expected output and chain."""
    lines = page.read_text(encoding="utf-8").split("\n")
    blocks: List[Block] = []
    markers: Dict[str, str] = {}
    last = None  # the previous fenced block of any language
    i = 0
    while i < len(lines):
        if m := _MARKER.match(lines[i]):
            key, value = m.group(1), m.group(2)
            if not m.group(3):  # a multi-line marker: its value runs to the line `-->`
                start, body = i, [value] if value else []
                while (i := i + 1) < len(lines) and lines[i].strip() != "-->":
                    body.append(lines[i])
                if i == len(lines):
                    raise ValueError(f"{page.relative_to(ROOT)}:{start + 1}: a docs-test marker without its `-->` line")
                value = "\n".join(body) + "\n"
            markers[key] = value
        elif m := _FENCE.match(lines[i]):
            end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
            block = Block(page, i + 1, m.group(1), "\n".join(lines[i + 1:end]) + "\n", markers, end=end)
            between = lines[last.end + 1:i] if last else []
            if (block.lang == "text" and last is not None and last.runnable and last.expected is None
                    and not any(s.startswith("#") for s in between)):
                last.expected, last.tolerance = block.code, markers.get("tolerance")
            elif block.runnable or "file" in markers:
                if "continue" in markers:
                    if not blocks:
                        raise ValueError(f"{block.id}: `continue` on the first block of the page")
                    block.chain = blocks[-1].chain or blocks[-1]
                blocks.append(block)
            markers, last, i = {}, block, end
        elif lines[i].strip():
            markers = {}  # markers belong to the block right below them
        i += 1
    return blocks


def all_blocks() -> List[Block]:
    """The runnable and `file:` blocks of every page."""
    return [b for page in PAGES for b in parse_page(page)]


def undefined_names(code: str) -> List[str]:
    """Names a Python block reads but never binds (imports, assignments, defs, loop and `with`
    targets, arguments) and that are not builtins: a sketch's inputs, which its prelude must define."""
    tree = ast.parse(code)
    bound, read = set(dir(builtins)), []
    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            (read.append(node.id) if isinstance(node.ctx, ast.Load) else bound.add(node.id))
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            bound.update((a.asname or a.name).split(".")[0] for a in node.names)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            bound.add(node.name)
        elif isinstance(node, ast.arg):
            bound.add(node.arg)
        elif isinstance(node, ast.ExceptHandler) and node.name:
            bound.add(node.name)
    return sorted(set(read) - bound)


def output_problem(expected: str, actual: str, tolerance: Optional[str] = None) -> Optional[str]:
    """None when ``actual`` (stdout) is what ``expected`` states, else why not. Lines are compared
    without trailing blanks; ``...`` stands for any text (also several lines); with ``tolerance``
    ("0.5": absolute, "5%": relative) every number of ``expected`` matches a number within it."""
    def norm(s: str) -> str:
        return "\n".join(line.rstrip() for line in s.strip("\n").split("\n")).strip("\n")

    expected, actual = norm(expected), norm(actual)
    splitter = r"(\.\.\.)" + (f"|({_NUMBER})" if tolerance else "")
    pattern, numbers = "", []
    for piece in re.split(splitter, expected):
        if piece is None or piece == "":
            continue
        if piece == "...":
            pattern += ".*?"
        elif tolerance and re.fullmatch(_NUMBER, piece):
            pattern, numbers = pattern + f"({_NUMBER})", numbers + [float(piece)]
        else:
            pattern += re.escape(piece)
    m = re.fullmatch(pattern, actual, re.DOTALL)
    if m is None:
        return f"the output differs from the page's:\n--- page\n{expected}\n--- actual\n{actual}"
    if tolerance:
        rel = tolerance.endswith("%")
        tol = float(tolerance.rstrip("%")) / (100 if rel else 1)
        for want, got in zip(numbers, (float(g) for g in m.groups())):
            if not math.isclose(got, want, rel_tol=tol if rel else 0, abs_tol=0 if rel else tol):
                return f"{got} is not {want} within {tolerance}:\n--- page\n{expected}\n--- actual\n{actual}"
    return None

"""The settings of the ``scanalign`` commands: a *root* of C++ structs (:mod:`scanalign.common.settings`) set, each
overriding the one before, from the structs' C++ defaults (and a command's preset), ``--config FILE`` (nested YAML /
JSON, as ``dump-config COMMAND`` writes it), the command's alias flags (``--max-distance``: help, unit and default from
the field) and ``--set PATH=VALUE``. The settings a run used are written beside its outputs (``config.yaml``);
``--config`` on that file repeats the run.
"""

from __future__ import annotations

import argparse
import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Dict, Optional, Sequence, Tuple

from scanalign import _core
from scanalign.common import settings as schema

__all__ = ["Alias", "Command", "add_settings_options", "resolve", "dump", "write_effective"]


@dataclass(frozen=True)
class Alias:
    """A flag that sets the field at ``path``. ``value`` turns what argparse parsed into the
    field's value (e.g. a preset name into a Box); ``flag`` is the value a flag without
    argument stores (``--no-require-convergence``: False)."""

    option: str
    path: str
    group: Optional[str] = None
    nargs: Any = None
    metavar: Any = None
    choices: Optional[Sequence[str]] = None
    flag: Any = None
    value: Optional[Callable[[Any], Any]] = None
    help: str = ""


@dataclass(frozen=True)
class Command:
    """What a command's settings are: ``root()`` builds the defaults (a struct or a mapping of
    structs), ``aliases`` are its flags for common fields."""

    root: Callable[[], Any]
    aliases: Tuple[Alias, ...] = field(default_factory=tuple)


def _help(root: Any, alias: Alias) -> str:
    """The alias's help from the field: what it is, its unit and its default."""
    node, _, name = alias.path.rpartition(".")
    owner = schema.get_path(root, node) if node else root
    unit, doc = next(((f[1], f[2]) for f in type(owner).__fields__ if f[0] == name), ("", ""))
    default = schema.get_path(root, alias.path)
    text = alias.help or doc
    if schema.is_struct(default) and schema.field_names(default):  # an alias that sets several fields
        return f"{text} (--set {alias.path}.FIELD=VALUE)".replace("%", "%%")
    shown = schema.dump_yaml({"v": default}, comments=False).strip()[len("v: "):]  # as YAML: 0.02, point_to_plane, null
    return f"{text}{', ' + unit if unit else ''} (default {shown}; --set {alias.path})".replace("%", "%%")


def add_settings_options(parser: argparse.ArgumentParser, command: Command) -> None:
    """``--config FILE``, ``--set PATH=VALUE`` and the command's alias flags."""
    root = command.root()
    parser.add_argument("--config", metavar="FILE",
                        help="YAML/JSON file of settings, nested as 'scanalign dump-config' prints them")
    parser.add_argument("--set", dest="set_values", metavar="PATH=VALUE", action="append", default=[],
                        help="set one setting, e.g. --set frame_to_model.icp.max_iterations=30 (after --config "
                             "and the flags; repeatable)")
    groups: Dict[str, Any] = {}
    for a in command.aliases:
        target = parser if a.group is None else groups.setdefault(a.group, parser.add_argument_group(a.group))
        kwargs: Dict[str, Any] = dict(dest=f"alias:{a.option}", default=None, help=_help(root, a))
        default = schema.get_path(root, a.path)
        if a.flag is not None:
            kwargs.update(action="store_const", const=a.flag)
        elif isinstance(default, bool) and a.nargs is None:
            kwargs.update(action=argparse.BooleanOptionalAction)
        else:
            kind = str if a.value or default is None or isinstance(default, (bool, str)) else (
                int if isinstance(default, int) else float)
            metavar = a.metavar or (None if a.choices else a.option[2:].upper().replace("-", "_"))
            kwargs.update(nargs=a.nargs, metavar=metavar, choices=a.choices, type=kind)
        target.add_argument(a.option, **kwargs)


def resolve(command: Command, args: argparse.Namespace, preset: Optional[Dict[str, Any]] = None) -> Any:
    """The settings of a parsed command line: defaults < preset < --config < flags < --set, validated
    by the structs' C++ checks. ValueError / TypeError name the file, the flag as typed and its value
    (``--max-distance -1``), or the ``--set`` of a bad value, before any work."""
    root = command.root()
    if preset:
        schema.update(root, preset)
    if getattr(args, "config", None):
        try:
            schema.update(root, schema.load_yaml(args.config))
            _validate(root)
        except (TypeError, ValueError) as e:
            raise ValueError(f"{args.config}: {e}") if not str(e).startswith(str(args.config)) else e from None
    given = []  # (the flag or --set as typed, the path it sets), in the order they apply
    for a in command.aliases:
        value = getattr(args, f"alias:{a.option}", None)
        if value is not None:
            typed = a.option if a.flag is not None else f"{a.option} {_shown(value)}"
            try:
                schema.set_path(root, a.path, a.value(value) if a.value else value)
            except (TypeError, ValueError) as e:
                raise ValueError(f"{typed}: {str(e).removeprefix(a.path + ': ')}") from None
            given.append((typed, a.path))
    for text in getattr(args, "set_values", []):
        path, value = schema.parse_assignment(text)
        try:
            schema.set_path(root, path, value)
        except (TypeError, ValueError) as e:
            raise type(e)(f"--set {e}") from None
        given.append((f"--set {text}", path))
    try:
        _validate(root)
    except ValueError as e:  # the C++ check names a field: name the flag that set it, as typed
        culprit = [typed for typed, path in given if re.search(rf"\b{path.rpartition('.')[2]}\b", str(e))]
        if not culprit:
            raise
        raise ValueError(f"{culprit[-1]}: {e}") from None
    return root


def _shown(value: Any) -> str:
    """A flag's value as typed: -1, not -1.0; a list space-separated."""
    return " ".join(map(_shown, value)) if isinstance(value, list) else str(value).removesuffix(".0")


def _validate(node: Any) -> None:
    """The C++ checks of every struct of a root, nested ones too (FindObjectsSettings has no
    ``validate`` of its own, its ``table`` has). PoseSettings binds none, but
    ``describe_model_views`` runs its C++ check first, and with no views nothing else."""
    if hasattr(node, "validate"):
        node.validate()
    elif isinstance(node, _core.pose.PoseSettings):
        _core.pose.describe_model_views([], node)
    for value in (node if isinstance(node, dict) else schema.fields_of(node)).values():
        if schema.is_struct(value) and schema.field_names(value):
            _validate(value)


def dump(command_name: str, root: Any, header: Sequence[str] = ()) -> str:
    """``dump-config``'s YAML: every field with its value, unit and meaning."""
    lines = list(header) or [
        f"# scanalign {command_name}: every setting with its default ([unit] meaning above each).",
        f"# Use: scanalign {command_name} ... --config FILE; flags and --set PATH=VALUE override the file.",
        "# Units: metres, radians, seconds unless stated."]
    return schema.dump_yaml(root, header=lines + [""])


def write_effective(command_name: str, root: Any, args: argparse.Namespace, inputs: Sequence[str], path: Path) -> Path:
    """Writes the settings of this run beside its outputs, with the command that repeats it."""
    repeat = shlex.join(["scanalign", command_name, *inputs, "--config", str(path)])
    source = f" (defaults < {args.config} < flags)" if getattr(args, "config", None) else " (defaults < flags)"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dump(command_name, root, [f"# The settings of this 'scanalign {command_name}' run{source}.",
                                              f"# Repeat it: {repeat}"]))
    return path

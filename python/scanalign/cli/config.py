"""Config files for the ``scanalign`` commands.

The settings of a command are its command-line options, read from its ``argparse`` parser:
the key is the long option name without the dashes (``max-distance`` or ``max_distance``),
the default and the help text (which states the unit) come from the parser. Nothing here
lists the settings by hand, so a new option is a new config key at once.

- :func:`dump` writes every setting of a command with its default as YAML, each preceded
  by a comment with its option, unit and help (``scanalign dump-config COMMAND``).
- :func:`load` reads a YAML or JSON file (PyYAML) into ``{dest: value}``, refusing an
  unknown key (with the closest known one), a wrong type, a value outside the option's
  choices or malformed YAML with a ``ValueError`` naming the file and the key.
- :func:`use_config_file` makes a file's values the parser's defaults, so that the
  precedence is: the parser's defaults < the file < flags given on the command line.
- :func:`write_effective` writes the settings a run used, in the same format, beside its
  outputs; fed back with ``--config`` it repeats the run.

Paths in a config file are taken as given, like the flags: relative to the working directory.
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import re
import shlex
import textwrap
from pathlib import Path
from typing import Any, Optional, Sequence

__all__ = ["COMMANDS", "ConfigFileError", "Setting", "add_config_option", "dump", "effective", "load", "settings", "use_config_file",
           "write_effective"]

COMMANDS = ("pose", "pick")
"""The commands that take ``--config FILE``."""

CONFIG_DEST = "config"

# A unit after a comma, an opening parenthesis or "in": "distance, m (0.05)", "(pixels)",
# "in metres".
_UNIT = re.compile(r"(?:,\s*|\(|\bin\s+)(m|mm|rad|deg|s|px|pixels|metres|meters|radians|degrees|seconds)\b(?![-.])")
_UNIT_NAMES = {"metres": "m", "meters": "m", "radians": "rad", "degrees": "deg", "seconds": "s", "pixels": "px"}


@dataclasses.dataclass(frozen=True)
class Setting:
    """One setting of a command: an optional argument of its parser."""

    key: str  # the long option name with underscores: "max_distance"
    dest: str  # the argparse destination (the Namespace attribute)
    option: str  # "--max-distance"
    default: Any
    help: str
    unit: Optional[str]  # "m", "rad", "m, rad", ... as the help text states it; None: none stated
    group: Optional[str]  # the argument group's title
    action: argparse.Action = dataclasses.field(repr=False, compare=False)

    @property
    def is_flag(self) -> bool:
        """True for an on/off setting (``store_true`` / ``--x/--no-x``)."""
        return self.action.nargs == 0 or isinstance(self.action, argparse.BooleanOptionalAction)


def _key(option: str) -> str:
    return option.lstrip("-").replace("-", "_")


def _unit(help_text: str) -> Optional[str]:
    units = []
    for m in _UNIT.finditer(help_text):
        unit = _UNIT_NAMES.get(m.group(1), m.group(1))
        if unit not in units:
            units.append(unit)
    return ", ".join(units) or None


def settings(parser: argparse.ArgumentParser) -> list[Setting]:
    """The settings of a command's parser: every optional argument but ``--help``,
    ``--version`` and ``--config``, in the parser's order."""
    groups = {id(a): g.title for g in parser._action_groups for a in g._group_actions}  # noqa: SLF001
    out = []
    for action in parser._actions:  # noqa: SLF001 (argparse has no public list)
        if not action.option_strings or action.dest in (argparse.SUPPRESS, CONFIG_DEST):
            continue
        if isinstance(action, (argparse._HelpAction, argparse._VersionAction)):  # noqa: SLF001
            continue
        long = [o for o in action.option_strings if o.startswith("--")] or action.option_strings
        help_text = " ".join((action.help or "").split())
        group = groups.get(id(action))
        numeric = action.type in (int, float)  # units of numbers only ("radians" in a name's help is not one)
        out.append(Setting(_key(long[0]), action.dest, long[0], parser.get_default(action.dest), help_text,
                           _unit(help_text) if numeric else None,
                           None if group in ("options", "optional arguments") else group, action))
    return out


# --------------------------------------------------------------------------- reading


def _type_name(s: Setting) -> str:
    kind = {int: "an integer", float: "a number"}.get(s.action.type, "a string")
    if s.is_flag:
        return "true or false"
    nargs = s.action.nargs
    if isinstance(nargs, int):
        return f"a list of {nargs} values, each {kind}"
    if nargs in ("+", "*"):
        return f"a list of values, each {kind}" + (" (at least one)" if nargs == "+" else "")
    return kind


def _scalar(s: Setting, value: Any) -> Any:
    """One value converted to the option's type; raises TypeError when it has another."""
    kind = s.action.type
    if isinstance(value, bool) or value is None or isinstance(value, (list, dict)):
        raise TypeError
    if kind is float:
        if not isinstance(value, (int, float)):
            raise TypeError
        return float(value)
    if kind is int:
        if not isinstance(value, int):
            raise TypeError
        return value
    if kind is None or kind is str:
        if not isinstance(value, (str, int, float)):
            raise TypeError
        return str(value)
    try:  # another converter (a function of the string, as argparse calls it)
        return kind(str(value))
    except (TypeError, ValueError, argparse.ArgumentTypeError):
        raise TypeError from None


def _flag_value(s: Setting, given: bool) -> Any:
    """The value an on/off option stores when it is given (``true``) or not (``false``)."""
    if isinstance(s.action, argparse.BooleanOptionalAction):
        return given
    const = s.action.const  # store_true: True, store_false: False
    return const if given else (not const if isinstance(const, bool) else s.action.default)


def _flag_given(s: Setting, value: Any) -> Any:
    """Inverse of :func:`_flag_value`: what a config file says for a stored value."""
    if isinstance(s.action, argparse.BooleanOptionalAction) or value is None:
        return value
    return value == s.action.const


def _convert(s: Setting, value: Any, where: str) -> Any:
    """A file's value for setting ``s``, checked and converted; ValueError naming ``where``."""
    if value is None:
        if s.default is None:
            return None
        raise ValueError(f"{where}: null is not allowed; expected {_type_name(s)} (default {s.default!r})")
    try:
        if s.is_flag:
            if not isinstance(value, bool):
                raise TypeError
            return _flag_value(s, value)
        nargs = s.action.nargs
        if nargs is None or nargs == "?":
            out = _scalar(s, value)
            items = [out]
        else:
            if not isinstance(value, list):
                raise TypeError
            if (isinstance(nargs, int) and len(value) != nargs) or (nargs == "+" and not value):
                raise TypeError
            out = [_scalar(s, v) for v in value]
            items = out
    except TypeError:
        raise ValueError(f"{where}: expected {_type_name(s)}, got {value!r}") from None
    if s.action.choices is not None:
        bad = [v for v in items if v not in s.action.choices]
        if bad:
            raise ValueError(f"{where}: {bad[0]!r} is not one of {', '.join(map(str, s.action.choices))}")
    return out


def _read(path: Path) -> dict:
    import yaml

    try:
        text = path.read_text()
    except OSError as e:
        raise ValueError(f"{path}: cannot read the config file ({e.strerror or e})") from None
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file (YAML/JSON expected)") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise ValueError(f"{path}: malformed YAML/JSON{where}: {problem}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a mapping of settings (key: value), got {type(data).__name__}")
    return data


def load(path: str | Path, parser: argparse.ArgumentParser, command: str = "") -> dict:
    """The settings of a YAML/JSON config file for ``parser``'s command, checked and
    converted: ``{dest: value}``. Raises ValueError naming the file and the key for an
    unknown key (suggesting the closest), a key given twice, a wrong type or a value
    outside the option's choices, and for malformed YAML."""
    path = Path(path)
    by_key = {}
    for s in settings(parser):
        for option in s.action.option_strings:
            if option.startswith("--"):
                by_key.setdefault(_key(option), s)
        by_key.setdefault(_key(s.dest), s)
    who = f" of 'scanalign {command}'" if command else ""
    out: dict = {}
    seen: dict = {}
    for raw_key, value in _read(path).items():
        key = _key(str(raw_key))
        s = by_key.get(key)
        if s is None or not isinstance(raw_key, str):
            close = difflib.get_close_matches(key, sorted({x.key for x in by_key.values()}), n=1)
            hint = f"; did you mean {close[0]}?" if close else ""
            raise ValueError(f"{path}: {raw_key}: unknown setting{who}{hint} "
                             f"(scanalign dump-config {command or 'COMMAND'} lists them)")
        if s.dest in seen:
            raise ValueError(f"{path}: {raw_key}: given twice (also as {seen[s.dest]})")
        seen[s.dest] = raw_key
        out[s.dest] = _convert(s, value, f"{path}: {raw_key}")
    return out


# --------------------------------------------------------------------------- the command line


class ConfigFileError(ValueError):
    """A bad ``--config`` file; ``command`` is the command it was given to."""

    def __init__(self, message: str, command: str):
        super().__init__(message)
        self.command = command


def add_config_option(parser: argparse.ArgumentParser, command: str) -> None:
    """Adds ``--config FILE`` to a command's parser."""
    parser.add_argument("--config", dest=CONFIG_DEST, metavar="FILE",
                        help=f"YAML/JSON file of settings (keys: the long option names; 'scanalign dump-config "
                             f"{command}' lists them with defaults and units); flags given here override it")


def use_config_file(subparsers: argparse._SubParsersAction, argv: Sequence[str]) -> Optional[str]:  # noqa: SLF001
    """When ``argv`` runs a command with ``--config FILE``, makes the file's settings that
    command parser's defaults (flags given on the command line still win) and lets the file
    supply required options. Returns the command's name when a file was used, else None.
    Raises ConfigFileError (a ValueError) naming the file and key for a bad file."""
    argv = list(argv)
    command = next((a for a in argv if not a.startswith("-")), None)
    if command not in subparsers.choices or command not in COMMANDS:
        return None
    pre = argparse.ArgumentParser(add_help=False, exit_on_error=False)  # finds --config FILE
    pre.add_argument("--config", dest=CONFIG_DEST)
    rest = argv[argv.index(command) + 1:]
    try:
        known, _ = pre.parse_known_args(rest[:rest.index("--")] if "--" in rest else rest)
    except (argparse.ArgumentError, SystemExit):  # "--config" without a file: the real parser says so
        return None
    path = getattr(known, CONFIG_DEST, None)
    if path is None:
        return None
    parser = subparsers.choices[command]
    try:
        values = load(path, parser, command)
    except ValueError as e:
        raise ConfigFileError(str(e), command) from None
    parser.set_defaults(**values)
    for action in parser._actions:  # noqa: SLF001
        if action.dest in values and values[action.dest] is not None:
            action.required = False
    return command


# --------------------------------------------------------------------------- writing


def _yaml_value(value: Any) -> str:
    import yaml

    if isinstance(value, (list, tuple)):
        return yaml.safe_dump(list(value), default_flow_style=True, width=10**9).strip()
    return yaml.safe_dump(value, width=10**9).splitlines()[0]  # a scalar: drop the "..." end line


def _comment(s: Setting) -> list[str]:
    head = s.option + (f"/--no-{s.option[2:]}" if isinstance(s.action, argparse.BooleanOptionalAction) else "")
    if isinstance(s.action.nargs, int) and s.action.metavar:
        head += f" [{', '.join(s.action.metavar)}]"
    head += f" [{s.unit}]" if s.unit else ""
    text = f"{head}: {s.help}" if s.help else head
    if s.action.choices is not None and not any(str(c) in s.help for c in s.action.choices):
        text += f" (one of {', '.join(map(str, s.action.choices))})"
    if s.action.required:
        text += " (required: give it here or on the command line)"
    return ["# " + line for line in textwrap.wrap(text, 96, break_on_hyphens=False)]


def dump(parser: argparse.ArgumentParser, command: str, values: Optional[dict] = None,
         header: Sequence[str] = ()) -> str:
    """YAML text of every setting of ``parser`` with its value (``values``, keyed by dest)
    or else its default, each preceded by a comment: option, unit, help, choices."""
    positionals = [(a.metavar or a.dest).upper() for a in parser._actions  # noqa: SLF001
                   if not a.option_strings and a.dest != argparse.SUPPRESS]
    use = " ".join(["scanalign", command, *positionals, "--config", "FILE"])
    lines = list(header) or [f"# scanalign {command}: every setting with its default.",
                             f"# Use: {use}; flags given on the command line override the file."]
    lines += ["# Units: metres, radians, seconds unless stated. Keys: the long option names (- or _)."]
    group: Any = object()  # a blank line after the header, and before each group
    for s in settings(parser):
        if s.group != group:
            group = s.group
            lines += ["", f"# --- {group} ---"] if group else [""]
        value = values[s.dest] if values is not None and s.dest in values else s.default
        lines += _comment(s) + [f"{s.key}: {_yaml_value(_flag_given(s, value) if s.is_flag else value)}"]
    return "\n".join(lines) + "\n"


def effective(parser: argparse.ArgumentParser, args: argparse.Namespace) -> dict:
    """The settings a parsed command line resolves to, ``{dest: value}``."""
    return {s.dest: getattr(args, s.dest, s.default) for s in settings(parser)}


def write_effective(parser: argparse.ArgumentParser, command: str, args: argparse.Namespace,
                    path: str | Path) -> Path:
    """Writes the settings of this run (defaults < ``--config`` file < flags) to ``path``,
    with a comment line giving the command that repeats the run from it."""
    path = Path(path)
    positionals = [str(getattr(args, a.dest)) for a in parser._actions  # noqa: SLF001
                   if not a.option_strings and a.dest != argparse.SUPPRESS and getattr(args, a.dest, None) is not None]
    source = getattr(args, CONFIG_DEST, None)
    repeat = shlex.join(["scanalign", command, *positionals, "--config", str(path)])
    header = [f"# The settings of this 'scanalign {command}' run"
              + (f" (defaults < {source} < flags)." if source else " (defaults < flags)."),
              f"# Repeat it: {repeat}"]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(dump(parser, command, effective(parser, args), header))
    return path

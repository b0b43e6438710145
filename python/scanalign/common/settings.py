"""The settings schema: the bound C++ settings structs as dicts, YAML files and dotted paths.

Every bound struct lists its fields in ``__fields__`` (``(name, unit, doc, writable)``, from the one field table of its
binding), so nothing here restates a field, a unit or a default: a new C++ field with its doc is a new key of every
config file, ``--set`` path and ``dump-config`` line at once. A *root* is one struct or a mapping ``{name: struct}`` (a
command that uses two structs side by side). :func:`to_dict` / :func:`update` convert to and from nested dicts (each
value checked by the C++ field's setter), :func:`with_overrides` is what the API functions do with ``settings=`` and
keywords, :func:`set_path` / :func:`parse_assignment` serve ``--set a.b=value``, :func:`leaves` lists every leaf field
(path, unit, doc, value), and :func:`dump_yaml` / :func:`load_yaml` write and read the commented YAML of ``dump-config``
and config files.
"""

from __future__ import annotations

import difflib
import functools
import re
import textwrap
from pathlib import Path
from typing import Any, Dict, Iterator, Mapping, Sequence, Tuple, TypeVar, Union

import numpy as np
import yaml

__all__ = ["UnknownSettingError", "is_struct", "field_names", "fields_of", "to_dict", "update", "set_fields",
           "with_overrides", "get_path", "set_path", "parse_assignment", "leaves", "dump_yaml", "load_yaml"]

T = TypeVar("T")
Root = Union[Any, Mapping[str, Any]]


def is_struct(value: Any) -> bool:
    """True for an instance of a bound C++ struct with a field table."""
    return hasattr(type(value), "__fields__") and not isinstance(value, type)


def field_names(struct: Any, writable: bool = True) -> Tuple[str, ...]:
    """The fields of a struct (or struct type), in declaration order: the settable ones, or all."""
    t = struct if isinstance(struct, type) else type(struct)
    if not hasattr(t, "__fields__"):  # a struct bound without a field table: its properties
        return tuple(k for k in dir(t) if not k.startswith("_") and isinstance(getattr(t, k), property)
                     and (getattr(t, k).fset is not None or not writable))
    return tuple(f[0] for f in t.__fields__ if f[3] or not writable)


class UnknownSettingError(TypeError, ValueError):
    """A settings key that names no field: a TypeError as for an unexpected keyword argument,
    and a ValueError as for any other bad value of a config file."""


def fields_of(struct: Any) -> Dict[str, Any]:
    """The settable fields of a struct and their values (nested structs as they are)."""
    return {name: getattr(struct, name) for name in field_names(struct)}


def _plain(value: Any) -> Any:
    """A field's value as YAML/JSON knows it: numbers, str, bool, None, lists, dicts."""
    if is_struct(value):
        if hasattr(value, "as_tuple") and not field_names(value):  # a value type such as a Box
            return [float(v) for v in value.as_tuple()]
        return to_dict(value)
    if hasattr(type(value), "__members__") and hasattr(value, "name"):  # a py::enum_ member
        return value.name
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _items(root: Root) -> Iterator[Tuple[str, Any]]:
    """(name, value) of a root's settable fields (a struct) or entries (a mapping of structs)."""
    return iter((root if isinstance(root, Mapping) else fields_of(root)).items())


def _child(node: Root, key: str) -> Any:
    return node[key] if isinstance(node, Mapping) else getattr(node, key)


def to_dict(root: Root) -> Dict[str, Any]:
    """The settable fields of a struct (or each struct of a mapping) as a nested dict of plain
    values: enums by name, arrays as lists, boxes as their 6 bounds."""
    return {name: _plain(value) for name, value in _items(root)}


def _unknown(key: str, known: Sequence[str], where: str, what: str = "") -> UnknownSettingError:
    close = difflib.get_close_matches(key, known, n=1)
    hint = f"; did you mean {where}{close[0]}?" if close else f"; known: {', '.join(known)}"
    return UnknownSettingError(f"{where}{key}: unknown {what + ' ' if what else ''}setting{hint}")


def update(root: Root, values: Mapping[str, Any], where: str = "", what: str = "") -> Root:
    """Sets the fields named in ``values`` (nested mappings for nested structs) on ``root`` in place and returns it.
    :class:`UnknownSettingError` names the path of an unknown key (``what`` names the settings in its message); a value
    of the wrong type or range raises the C++ setter's TypeError / ValueError, prefixed by its path."""
    if not isinstance(values, Mapping):
        raise ValueError(f"{where or 'settings'}: expected a mapping of settings, got {type(values).__name__}")
    known = list(root) if isinstance(root, Mapping) else list(field_names(root))
    for key, value in values.items():
        if key not in known:
            raise _unknown(str(key), known, where, what)
        current = _child(root, key)
        if is_struct(current) and field_names(current) and not hasattr(current, "as_tuple"):
            if isinstance(value, Mapping):
                update(current, value, f"{where}{key}.", what)
                continue
            if not isinstance(value, type(current)):
                raise TypeError(f"{where}{key}: expected a mapping of {type(current).__name__} fields, "
                                f"got {type(value).__name__}")
        members = getattr(type(current), "__members__", None)
        if isinstance(value, str) and members is not None:  # a py::enum_ field set by its member's name
            if value not in members:
                raise ValueError(f"{where}{key}: unknown value {value!r}; expected one of {', '.join(members)}")
            value = members[value]
        try:
            setattr(root, key, value) if not isinstance(root, Mapping) else root.__setitem__(key, value)
        except (TypeError, ValueError) as e:  # named by its path, once (not also as the C++ "Class.field")
            message = re.sub(rf"^(\w+\.)?{re.escape(str(key))}: ", "", str(e))
            raise type(e)(f"{where}{key}: {message}") from None
    return root


def set_fields(struct: Any, values: Mapping[str, Any], what: str = "") -> Any:
    """:func:`update` of one struct, named ``what`` in error messages; returns the struct."""
    return update(struct, values, what=what)


def with_overrides(cls: type, settings: Any = None, overrides: Mapping[str, Any] = (), what: str = "settings") -> Any:
    """A new ``cls``: a copy of ``settings`` (default: the C++ defaults) with ``overrides``
    applied (:func:`update`). TypeError for a ``settings`` of another type."""
    if settings is not None and not isinstance(settings, cls):
        raise TypeError(f"{what}: expected a {cls.__name__}, got {type(settings).__name__}")
    out = cls() if settings is None else cls(settings)
    return update(out, dict(overrides), what=what)


def get_path(root: Root, path: str) -> Any:
    """The value at a dotted path (``"frame_to_model.icp.max_iterations"``)."""
    return functools.reduce(_child, path.split("."), root)


def set_path(root: Root, path: str, value: Any) -> None:
    """Sets the field at a dotted path, checked as :func:`update` checks it."""
    head, _, last = path.rpartition(".")
    node, where = root, ""
    for key in head.split(".") if head else []:
        if key not in (known := list(node) if isinstance(node, Mapping) else list(field_names(node))):
            raise _unknown(key, known, where)
        node, where = _child(node, key), f"{where}{key}."
    update(node, {last: value}, where)


def parse_assignment(text: str) -> Tuple[str, Any]:
    """``"a.b=value"`` as ``("a.b", value)``, the value read as YAML (``0.02``, ``true``,
    ``[1, 2, 3]``, ``point_to_point``)."""
    path, sep, raw = text.partition("=")
    if not sep or not path.strip():
        raise ValueError(f"--set {text!r}: expected PATH=VALUE, e.g. frame_to_model.icp.max_iterations=30")
    try:
        return path.strip(), yaml.safe_load(raw) if raw.strip() else ""
    except yaml.YAMLError as e:
        raise ValueError(f"--set {text!r}: the value is not valid YAML ({e})") from None


def leaves(root: Root, prefix: str = "") -> Iterator[Tuple[str, str, str, Any]]:
    """(dotted path, unit, doc, plain value) of every leaf field, depth first, in order."""
    for name, value in _items(root):
        if is_struct(value) and field_names(value):
            yield from leaves(value, f"{prefix}{name}.")
        else:
            unit, doc = "", ""
            if not isinstance(root, Mapping):
                unit, doc = next((f[1], f[2]) for f in type(root).__fields__ if f[0] == name)
            yield f"{prefix}{name}", unit, doc, _plain(value)


def _yaml_scalar(value: Any) -> str:
    return yaml.safe_dump(value, default_flow_style=True, width=10**9).strip().removesuffix("\n...").strip()


def _dump(root: Root, indent: int, comments: bool) -> list:
    pad = "  " * indent
    docs = {f[0]: (f[1], f[2]) for f in type(root).__fields__} if not isinstance(root, Mapping) else {}
    lines = []
    for name, value in _items(root):
        unit, doc = docs.get(name, ("", type(value).__name__ if is_struct(value) else ""))
        members = getattr(type(value), "__members__", None)
        if members is not None and not is_struct(value):  # a py::enum_ field: say what it takes
            doc = f"{doc}; one of: {', '.join(members)}"
        if comments and doc:
            text = (f"[{unit}] " if unit else "") + doc
            lines += [f"{pad}# {line}" for line in textwrap.wrap(text, max(40, 96 - len(pad)), break_on_hyphens=False)]
        if is_struct(value) and field_names(value):
            lines += [f"{pad}{name}:"] + _dump(value, indent + 1, comments)
        else:
            lines.append(f"{pad}{name}: {_yaml_scalar(_plain(value))}")
    return lines


def dump_yaml(root: Root, header: Sequence[str] = (), comments: bool = True) -> str:
    """YAML of every settable field of ``root`` with its value, each preceded (``comments``) by ``# [unit] doc``; nested
    structs as nested blocks. :func:`load_yaml` + :func:`update` read it back to the same values."""
    return "\n".join([*header, *_dump(root, 0, comments)]) + "\n"


def load_yaml(path: Union[str, Path]) -> Dict[str, Any]:
    """A YAML / JSON settings file as a mapping; ValueError naming the file (and line) when it
    cannot be read or is not a mapping."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ValueError(f"{path}: cannot read the settings file ({e.strerror or e})") from None
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file (YAML/JSON expected)") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        raise ValueError(f"{path}: malformed YAML/JSON{where}: {getattr(e, 'problem', None) or e}") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a mapping of settings (key: value), got {type(data).__name__}")
    return data

"""Input validation shared by the public API: clear exceptions before any C++ runs."""

from __future__ import annotations

import functools
import os
import re
from typing import Optional

import numpy as np

_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))


def as_points(array: object, name: str, dtype: Optional[np.dtype] = None) -> np.ndarray:
    """``array`` as an (N, 3) float32/float64 array the C++ core can view, without a copy when
    its layout allows (e.g. ``a[:, :3]`` of an (N, 8) PCL-layout array). TypeError for a
    non-float array (integer, bool, object, complex), ValueError for another shape."""
    a = np.asarray(array)
    if a.dtype not in _FLOATS:
        raise TypeError(f"{name}: expected a float32 or float64 array, got dtype {a.dtype}")
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name}: expected shape (N, 3), got {a.shape}")
    if dtype is not None and a.dtype != dtype:
        a = a.astype(dtype)
    item = a.dtype.itemsize
    if a.shape[0] > 1 and (a.strides[0] < 3 * item or a.strides[0] % item) or a.strides[1] != item:
        a = np.ascontiguousarray(a)
    return a


def as_transform(T: object, name: str = "init") -> np.ndarray:
    """A 4x4 float64 rigid transform (checked for shape and finiteness here, rigidity in C++)."""
    if (m := np.asarray(T)).dtype.kind not in "biuf":  # complex would silently lose its imaginary part
        raise TypeError(f"{name}: expected a real 4x4 matrix, got dtype {m.dtype}")
    m = m.astype(np.float64)
    if m.shape != (4, 4):
        raise ValueError(f"{name}: expected a 4x4 homogeneous transform, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise ValueError(f"{name}: transform has non-finite entries")
    return m


def require_memory(need: float, what: str) -> None:
    """ValueError when ``need`` bytes exceed half of this machine's memory (checked before allocating)."""
    if need > 0.5 * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"):
        raise ValueError(f"{what} need {need / 2**30:.1f} GiB, over half this machine's memory")


def fields_of(obj: object) -> dict:
    """The fields of a bound C++ struct (its properties) and their values."""
    t = type(obj)
    return {k: getattr(obj, k) for k in dir(t) if not k.startswith("_") and isinstance(getattr(t, k), property)}


def set_fields(obj: object, values: dict, what: str) -> object:
    """Sets fields of a bound C++ settings struct by name and returns it. An enum field also
    takes its value's name as a string. TypeError names an unknown field or a value of the
    wrong type, ValueError an unknown enum name."""
    t = type(obj)
    for name, value in values.items():
        if name.startswith("_") or not isinstance(getattr(t, name, None), property):
            known = sorted(k for k in dir(t) if isinstance(getattr(t, k), property))
            raise TypeError(f"unknown {what} setting {name!r}; known: {', '.join(known)}")
        members = getattr(type(getattr(obj, name)), "__members__", None)
        if isinstance(value, str) and members is not None:
            if value not in members:
                raise ValueError(f"{what} setting {name}: unknown value {value!r}; expected one of {sorted(members)}")
            value = members[value]
        try:
            setattr(obj, name, value)
        except TypeError as e:
            raise TypeError(f"{what} setting {name}: {e}") from None
    return obj



_KINDS = (("SupportsFloat", "a real number", (int, float, np.integer, np.floating)), ("SupportsInt", "an integer", (int, np.integer)),
          ("bool", "True or False", (bool, np.bool_)), ("str", "a string", (str,)), ('"[3, 1]"', "3 real numbers", None),
          ("numpy.ndarray", "a NumPy array", (np.ndarray,)), ("ArrayLike", "an array of real numbers", ()))


def _misfit(value: object, annotation: str) -> Optional[str]:
    """What a parameter pybind11 annotated this way expects, when ``value`` cannot fill it."""
    for key, words, types in _KINDS:
        if annotation in (key, {"SupportsFloat": "float", "SupportsInt": "int"}.get(key)) or key[0] in 'SA"' and key in annotation:
            if types is None:  # an Eigen 3-vector
                ok = (a := np.asarray(value, dtype=object)).shape == (3,) and not any(_misfit(x, "float") for x in a)
            elif not types:  # an Eigen array of any size
                ok = np.asarray(value).dtype.kind in "biuf"
            else:
                ok = isinstance(value, types) and (key in ("bool", "str") or not isinstance(value, bool))
                if ok and key == "SupportsInt" and not 0 <= value < 2**31:  # the C++ integer cannot hold it
                    return "a non-negative integer" if value < 0 else "a smaller integer (out of range in C++)"
            return None if ok else words
    return None


def _named_type_error(label: str, args: tuple, kwargs: dict, error: TypeError) -> TypeError:
    """pybind11's "incompatible function arguments" dump, replaced by the first argument whose
    value does not fit its parameter (kept when none is found)."""
    first = str(error).split("1. ", 1)[-1].split("\n", 1)[0]  # the first overload's signature
    first = first[first.index("(") + 1:first.rindex(")", 0, first.find(" -> ") % (len(first) + 1))]
    params = [p.split(" = ")[0] for p in re.split(r", (?=\*(?:,|$)|\w+: |\w+$)", first) if p != "*"]
    annotations = dict((p.split(": ", 1) + [""])[:2] for p in params)
    names = list(annotations)
    for name, value in [*zip(names, args[1:] if "constructor" in str(error) else args), *kwargs.items()]:
        if name not in annotations:
            return TypeError(f"{label}(): unexpected argument {name!r}; parameters: {', '.join(names)}")
        if expected := _misfit(value, annotations[name]):
            shown = repr(value) if len(repr(value)) < 60 else type(value).__name__
            where = label if re.fullmatch(r"arg\d", name) else f"{label}(): {name}"  # argN: a field's setter
            return TypeError(f"{where}: expected {expected}, got {shown}")
    return error


def explain_bad_arguments(module: object) -> None:
    """Wraps the functions and methods of a pybind11 module so that a wrongly typed argument
    raises a TypeError naming it instead of pybind11's dump of every signature."""
    def wrap(fn, label=None):
        @functools.wraps(fn)
        def call(*args, **kwargs):
            try:
                return fn(*args, **kwargs)
            except TypeError as e:
                if "incompatible function arguments" in str(e) or "incompatible constructor" in str(e):
                    raise _named_type_error(label or fn.__name__, args, kwargs, e) from None
                raise
        return call
    for owner in [module, *(v for v in vars(module).values() if isinstance(v, type))]:
        for name, value in list(vars(owner).items()):
            kind, inner = type(value).__name__, getattr(value, "__func__", value)
            if kind in ("builtin_function_or_method", "instancemethod"):
                setattr(owner, name, wrap(inner))
            elif isinstance(value, property) and value.fset is not None:  # a settings field: name it
                setter = wrap(value.fset, f"{owner.__name__}.{name}")
                setattr(owner, name, property(value.fget, setter, value.fdel, value.__doc__))
            elif kind == "staticmethod" and type(inner).__name__ == "builtin_function_or_method":
                setattr(owner, name, staticmethod(wrap(inner)))

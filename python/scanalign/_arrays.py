"""Input validation shared by the public API: clear exceptions before any C++ runs."""

from __future__ import annotations

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

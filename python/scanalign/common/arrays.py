"""Input validation shared by the public API: clear exceptions before any C++ runs."""

from __future__ import annotations

import functools
import os
import re
from typing import Optional, Tuple

import numpy as np

# --- Open3D and trimesh objects, duck-typed: neither package is imported here ---------------

def is_foreign(obj: object) -> bool:
    """Whether ``obj`` is an Open3D or trimesh object (by its type's module)."""
    return type(obj).__module__.startswith(("open3d", "trimesh")) and not isinstance(obj, np.ndarray)


def _tensor(t: object) -> np.ndarray:
    """An Open3D ``core.Tensor`` (any device) as a NumPy array."""
    return t.cpu().numpy() if hasattr(t, "cpu") else np.asarray(t)


def foreign_kind(obj: object) -> Optional[str]:
    """``"cloud"`` (Open3D ``PointCloud``, legacy or ``open3d.t``; ``trimesh.PointCloud``),
    ``"mesh"`` (Open3D ``TriangleMesh``, legacy or ``open3d.t``; ``trimesh.Trimesh``), ``"array"``
    (an Open3D ``Vector3dVector`` / ``Tensor``) or None for anything else."""
    if not is_foreign(obj):
        return None
    kind = {"PointCloud": "cloud", "TriangleMesh": "mesh", "Trimesh": "mesh", "Tensor": "array"}.get(type(obj).__name__)
    return kind or ("array" if type(obj).__name__.startswith("Vector") else None)


def _origin(obj: object) -> str:
    """"o3d.t" (Open3D tensor geometry), "o3d" (legacy Open3D) or "trimesh"."""
    module = type(obj).__module__
    return "trimesh" if module.startswith("trimesh") else "o3d.t" if ".t." in module else "o3d"


def foreign_points(obj: object, name: str = "points") -> np.ndarray:
    """The points of an Open3D / trimesh cloud or the vertices of a mesh, as a NumPy array (float64 for legacy Open3D
    and trimesh, the tensor's dtype for ``open3d.t``). TypeError for another Open3D / trimesh type."""
    kind, origin = foreign_kind(obj), _origin(obj)
    if kind == "array":
        return _tensor(obj)
    if kind in ("cloud", "mesh") and origin == "o3d.t":
        return _tensor(obj.point.positions if kind == "cloud" else obj.vertex.positions)
    if kind in ("cloud", "mesh"):
        return np.asarray(obj.points if kind == "cloud" and origin == "o3d" else obj.vertices)
    raise TypeError(f"{name}: expected points, got {type(obj).__module__}.{type(obj).__name__}")


def foreign_attribute(obj: object, what: str) -> Optional[np.ndarray]:
    """Per-point ``"normals"`` or ``"colors"`` (float in [0, 1] for Open3D, uint8 RGB for
    trimesh) of an Open3D cloud (legacy or tensor) or a trimesh cloud when it has them, else None."""
    if foreign_kind(obj) != "cloud":
        return None
    origin = _origin(obj)
    if origin == "o3d.t":
        return _tensor(obj.point[what]) if what in obj.point else None
    if origin == "o3d":
        return np.asarray(getattr(obj, what)) if getattr(obj, f"has_{what}")() else None
    c = np.asarray(obj.colors) if what == "colors" else np.empty(0)  # trimesh: RGBA, empty when unset
    return c[:, :3] if c.size else None


def mesh_arrays(obj: object) -> Optional[Tuple[np.ndarray, np.ndarray]]:
    """``(vertices (V, 3) float64, faces (F, 3) int64)`` of an Open3D (legacy or tensor) or
    trimesh triangle mesh, None for anything else."""
    if foreign_kind(obj) != "mesh":
        return None
    origin = _origin(obj)
    f = _tensor(obj.triangle.indices) if origin == "o3d.t" else obj.triangles if origin == "o3d" else obj.faces
    return np.asarray(foreign_points(obj), dtype=np.float64), np.asarray(f, dtype=np.int64).reshape(-1, 3)


def native(obj: object) -> object:
    """``obj`` with an Open3D / trimesh geometry replaced by its points (mesh: vertices) as a
    NumPy array; anything else unchanged."""
    return foreign_points(obj) if foreign_kind(obj) is not None else obj


def as_points(array: object, name: str, dtype: Optional[np.dtype] = None) -> np.ndarray:
    """``array`` as an (N, 3) float32/float64 array the C++ core can view, without a copy when its layout allows (e.g.
    ``a[:, :3]`` of an (N, 8) PCL-layout array). An Open3D point cloud (legacy or ``open3d.t``) or triangle mesh, or a
    trimesh ``PointCloud`` / ``Trimesh``, gives its points (vertices). TypeError for a non-float array (integer, bool,
    object, complex), ValueError for another shape."""
    if not isinstance(array, np.ndarray) and is_foreign(array):
        array = foreign_points(array, name)
    try:
        a = np.asarray(array)
    except (ValueError, TypeError) as e:  # a ragged list: numpy's message does not say which argument
        raise ValueError(f"{name}: expected an (N, 3) array of numbers ({e})") from None
    if a.dtype.kind != "f" or a.dtype.itemsize not in (4, 8):  # the C++ rule (cpp/python/arrays.hpp)
        raise TypeError(f"{name}: expected a float32 or float64 array, got dtype {a.dtype}")
    if not a.dtype.isnative:  # big-endian float64 is float64: in native order for the core
        a = a.astype(a.dtype.newbyteorder("="))
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
            if any(map(is_foreign, args)) or any(map(is_foreign, kwargs.values())):  # Open3D / trimesh objects
                args, kwargs = tuple(map(native, args)), {k: native(v) for k, v in kwargs.items()}
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

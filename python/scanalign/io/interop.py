"""Open3D and trimesh geometry to and from scanalign's arrays.

Every scanalign function that takes points or a mesh also takes these objects directly
(``scanalign.common.arrays`` converts them, by duck typing: neither package is imported unless
the object is one of theirs); :func:`to_open3d` / :func:`to_trimesh` convert the other way, and
:func:`from_open3d` / :func:`from_trimesh` explicitly (a :class:`Cloud` or a :class:`scanalign.io.Mesh`).

Open3D and trimesh are optional: the functions that build their objects import them on
first use and raise ImportError naming the PyPI package. Trajectories convert to ``evo``
in :mod:`scanalign.evaluation.trajectory` (:meth:`~scanalign.evaluation.trajectory.Trajectory.to_evo`).
"""

from __future__ import annotations

import importlib
from typing import Any, NamedTuple, Optional, Union

import numpy as np

from scanalign import io
from scanalign.common.arrays import as_points, foreign_attribute, foreign_kind, foreign_points, mesh_arrays

__all__ = ["Cloud", "to_open3d", "to_trimesh", "from_open3d", "from_trimesh"]


class Cloud(NamedTuple):
    """A point cloud: ``points`` (N, 3), metres; ``normals`` (N, 3) and ``colors`` (N, 3) or None
    (colours as the source stored them: float in [0, 1] from Open3D, uint8 from trimesh)."""

    points: np.ndarray
    normals: Optional[np.ndarray] = None
    colors: Optional[np.ndarray] = None


def _require(module: str, package: str, what: str) -> Any:
    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise ImportError(f"{what} needs the optional package {package!r}: pip install {package}") from e


def _mesh(obj: object) -> Optional[io.Mesh]:
    """``obj`` as a Mesh when it is one: io.Mesh, (vertices, faces), an Open3D / trimesh mesh."""
    if isinstance(obj, io.Mesh):
        return obj
    if (vf := mesh_arrays(obj)) is not None:
        return io.Mesh(*vf)
    if isinstance(obj, tuple) and len(obj) == 2:
        return io.Mesh(*obj)
    return None


def _unit_colors(colors: Optional[np.ndarray], n: int) -> Optional[np.ndarray]:
    """(n, 3) float64 colours in [0, 1] (uint8 scaled by 1/255)."""
    if colors is None:
        return None
    c = np.asarray(colors)
    c = c / 255.0 if c.dtype == np.uint8 else c.astype(np.float64)
    if c.shape != (n, 3):
        raise ValueError(f"colors: expected shape ({n}, 3), got {c.shape}")
    return c


def to_open3d(points_or_mesh: Union[np.ndarray, io.Mesh, tuple, Any], normals: Optional[np.ndarray] = None,
              colors: Optional[np.ndarray] = None) -> Any:
    """An ``open3d.geometry.PointCloud`` of (N, 3) points (any :func:`~scanalign.common.arrays.as_points` input), or an
    ``open3d.geometry.TriangleMesh`` of a :class:`scanalign.io.Mesh`, a ``(vertices, faces)`` pair or a trimesh mesh.
    ``normals`` (N, 3) and ``colors`` (N, 3; uint8 or float in [0, 1]) per point (per vertex for a mesh) are optional.

    Raises:
        ImportError: Open3D is not installed (``pip install open3d``).
        TypeError / ValueError: as :func:`scanalign.common.arrays.as_points` for bad points.
    """
    o3d = _require("open3d", "open3d", "to_open3d")
    mesh = _mesh(points_or_mesh)
    vec3 = o3d.utility.Vector3dVector
    if mesh is not None:
        out = o3d.geometry.TriangleMesh(vec3(mesh.vertices), o3d.utility.Vector3iVector(mesh.faces.astype(np.int32)))
        n, prefix = len(mesh.vertices), "vertex_"
    else:
        p = as_points(points_or_mesh, "points", np.dtype(np.float64))
        out, n, prefix = o3d.geometry.PointCloud(vec3(p)), len(p), ""
    if normals is not None:
        setattr(out, prefix + "normals", vec3(as_points(normals, "normals", np.dtype(np.float64))))
    if colors is not None:
        setattr(out, prefix + "colors", vec3(_unit_colors(colors, n)))
    return out


def to_trimesh(mesh: Union[io.Mesh, tuple, np.ndarray, Any], colors: Optional[np.ndarray] = None) -> Any:
    """A ``trimesh.Trimesh`` (vertices and faces exactly as given, ``process=False``) of a
    :class:`scanalign.io.Mesh`, a ``(vertices, faces)`` pair or an Open3D mesh; or a
    ``trimesh.PointCloud`` of (N, 3) points (``colors``: (N, 3) uint8 or float in [0, 1]).

    Raises:
        ImportError: trimesh is not installed (``pip install trimesh``).
    """
    trimesh = _require("trimesh", "trimesh", "to_trimesh")
    m = _mesh(mesh)
    if m is not None:
        return trimesh.Trimesh(m.vertices, m.faces, process=False)
    p = as_points(mesh, "points", np.dtype(np.float64))
    c = _unit_colors(colors, len(p))
    return trimesh.PointCloud(p, colors=None if c is None else np.rint(c * 255).astype(np.uint8))


def from_open3d(geometry: Any) -> Union[Cloud, io.Mesh]:
    """A :class:`Cloud` of an Open3D point cloud (legacy or ``open3d.t``; the tensor's dtype is
    kept), or a :class:`scanalign.io.Mesh` of an Open3D triangle mesh (legacy or ``open3d.t``).

    Raises:
        TypeError: not an Open3D point cloud or triangle mesh.
    """
    return _from(geometry, "open3d", "an Open3D PointCloud or TriangleMesh")


def from_trimesh(geometry: Any) -> Union[Cloud, io.Mesh]:
    """A :class:`scanalign.io.Mesh` of a ``trimesh.Trimesh``, or a :class:`Cloud` (colours uint8
    RGB, no normals) of a ``trimesh.PointCloud``.

    Raises:
        TypeError: not a trimesh mesh or point cloud.
    """
    return _from(geometry, "trimesh", "a trimesh Trimesh or PointCloud")


def _from(geometry: Any, package: str, expected: str) -> Union[Cloud, io.Mesh]:
    kind = foreign_kind(geometry)
    if not type(geometry).__module__.startswith(package) or kind not in ("cloud", "mesh"):
        raise TypeError(f"expected {expected}, got {type(geometry).__name__}")
    if kind == "mesh":
        return io.Mesh(*mesh_arrays(geometry))
    g = geometry
    return Cloud(foreign_points(g), foreign_attribute(g, "normals"), foreign_attribute(g, "colors"))

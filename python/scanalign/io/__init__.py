"""Readers and writers for point clouds and meshes.

Formats:

- **PCD** (PCL Point Cloud Data, v0.5-v0.7): :func:`read_pcd`, :func:`read_pcd_points`, with ``DATA ascii``, ``binary``
  and ``binary_compressed`` (LZF) payloads, parsed by the C++ core (``scanalign/io/pcd.hpp``).
- **Meshes**: :func:`read_mesh` for ``.off``, ``.ply``, ``.stl`` and ``.obj``; polygons
  are fan-triangulated into a :class:`Mesh`.  PLY goes through the ``plyfile`` library,
  the others through the C++ core (``scanalign/io/mesh_text.hpp``).
- **PLY point clouds**: :func:`write_ply` and :func:`read_ply_points` (``plyfile``).

Units: the library works in metres, but files store coordinates in whatever unit they
were written in (CAD meshes are often in millimetres).  The readers return the stored
numbers unchanged; scale them yourself when the file is not in metres.

Every parse error (truncated or corrupt file, unsupported variant, index out of range)
raises :class:`ValueError` whose message starts with the file path.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import warnings
from pathlib import Path
from typing import Union

import numpy as np
import numpy.typing as npt
from plyfile import PlyData, PlyElementParseError, PlyHeaderParseError

from scanalign._core import io as _io

__all__ = ["Mesh", "atomic_open", "lzf_decompress", "read_cloud", "read_mesh", "read_pcd", "read_pcd_points",
           "read_ply_points", "unpack_rgb", "write_pcd", "write_ply"]

PathLike = Union[str, "os.PathLike[str]"]


def _error(path: PathLike, message: str) -> ValueError:
    return ValueError(f"{os.fspath(path)}: {message}")


#: Decompresses an LZF stream (the liblzf format PCL uses for ``binary_compressed``).
lzf_decompress = _io.lzf_decompress


def read_pcd(path: PathLike) -> dict[str, np.ndarray]:
    """Read a PCL ``.pcd`` file (``DATA ascii``, ``binary`` or ``binary_compressed``) into a dict of per-point field
    arrays: field name -> array, in header order, with the dtype given by the header (``TYPE``/``SIZE``).

    A field with ``COUNT 1`` has shape ``(N,)``, otherwise ``(N, COUNT)``. Organised clouds (``HEIGHT > 1``) are
    flattened row by row to ``N = WIDTH * HEIGHT``; invalid points stay in place as NaN.  Coordinates (``x``, ``y``,
    ``z``) are in the file's unit (metres for PCL's own data). Normals come back as their own fields (``normal_x``,
    ``normal_y``, ``normal_z``). Packed colours (``rgb``/``rgba``) are returned raw; see :func:`unpack_rgb`. PCL's
    padding fields named ``_`` are dropped. ValueError: malformed header, unknown DATA type, truncated or corrupt
    payload, or a header claiming more data than the file holds.
    """
    try:
        return _io.parse_pcd(Path(path).read_bytes())[1]
    except ValueError as exc:
        raise _error(path, str(exc)) from None


def read_pcd_points(path: PathLike, dtype: npt.DTypeLike = np.float64, remove_nan: bool = True) -> np.ndarray:
    """The ``x y z`` coordinates of a ``.pcd`` file: an ``(N, 3)`` array of floating ``dtype`` in the file's unit
    (metres for PCL's own data); ``remove_nan`` drops rows with any non-finite coordinate (invalid points of organised
    clouds are stored as NaN). ValueError: the file is not a valid PCD file, has no ``x``, ``y``, ``z`` fields, or one
    of them has ``COUNT`` above 1."""
    points = _pcd_xyz(path, read_pcd(path)).astype(dtype)
    return points[np.isfinite(points).all(axis=1)] if remove_nan else points


def _pcd_xyz(path: PathLike, fields: dict[str, np.ndarray]) -> np.ndarray:
    """The (N, 3) x y z of PCD ``fields``; ValueError naming the file for a missing one or a COUNT above 1."""
    if missing := [k for k in "xyz" if k not in fields]:
        raise _error(path, f"PCD file has no x, y, z fields (missing {'/'.join(missing)}; it has "
                     f"{', '.join(fields) or 'none'})")
    if shaped := [axis for axis in "xyz" if fields[axis].ndim != 1]:  # COUNT > 1: (N, COUNT), not a coordinate
        raise _error(path, f"PCD field(s) {'/'.join(shaped)} must have COUNT 1 to be coordinates")
    return np.column_stack([fields[k] for k in "xyz"])


def unpack_rgb(field: npt.ArrayLike) -> np.ndarray:
    """Unpack PCL's packed ``rgb``/``rgba`` field (``(N,)`` values as :func:`read_pcd` returns them) into an ``(N, 3)``
    uint8 array of ``red, green, blue``. PCL stores a colour as the 32-bit pattern ``0xAARRGGBB``, typed either as a
    float (``rgb``, TYPE F) or as an unsigned integer (``rgba``, TYPE U).  Float input is reinterpreted bit for bit
    (float64 input is first narrowed to float32)."""
    values = np.asarray(field)
    bits = values.astype(np.float32).view(np.uint32) if values.dtype.kind == "f" else values.astype(np.uint32)
    return ((bits[..., None] >> np.array([16, 8, 0], dtype=np.uint32)) & 0xFF).astype(np.uint8)


@dataclasses.dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh: ``vertices`` ``(V, 3)`` float64 positions, in the unit the source file used; ``faces``
    ``(F, 3)`` int64 vertex indices, each in ``[0, V)``, in the file's winding order (counter-clockwise seen from
    outside, by convention)."""

    vertices: np.ndarray
    faces: np.ndarray

    def __post_init__(self) -> None:
        vertices = np.asarray(self.vertices, dtype=np.float64)
        faces = np.asarray(self.faces, dtype=np.int64)
        if vertices.ndim != 2 or vertices.shape[1] != 3 or not np.isfinite(vertices).all():
            raise ValueError(f"Mesh vertices must be finite with shape (V, 3), got shape {vertices.shape}")
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise ValueError(f"Mesh faces must have shape (F, 3), got {faces.shape}")
        if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
            raise ValueError(f"Mesh face indices must lie in [0, {len(vertices)}), got [{faces.min()}, {faces.max()}]")
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "faces", faces)


# Triangle meshes first: a known list length lets plyfile read faces with one array
# read instead of row by row; files with other polygons are read again without it.
_TRIANGLES = {"face": {"vertex_indices": 3, "vertex_index": 3}}


def _read_ply(path: PathLike, triangles: bool = True) -> PlyData:
    _io.check_ply_header(os.fspath(path))  # counts the file cannot hold, refused before plyfile allocates them
    try:
        with warnings.catch_warnings():  # numpy warns about empty ascii elements
            warnings.simplefilter("ignore", UserWarning)
            return PlyData.read(os.fspath(path), known_list_len=_TRIANGLES if triangles else {})
    except PlyHeaderParseError as exc:
        message = str(exc)
        what = ("not a PLY file" if "expected 'ply'" in message
                else "unsupported PLY format" if "format" in message else "malformed PLY header")
        raise _error(path, f"{what} ({message})") from None
    except (PlyElementParseError, ValueError, TypeError, IndexError, OverflowError) as exc:  # numpy's, on corrupt data
        if triangles and "unexpected list length" in str(exc):
            return _read_ply(path, triangles=False)
        what = "PLY element is truncated" if "end-of-file" in str(exc) else "malformed PLY element"
        raise _error(path, f"{what} ({exc})") from None


def _ply_vertex_columns(path: PathLike, ply: PlyData, names: tuple[str, ...] = ("x", "y", "z")) -> np.ndarray | None:
    """Stack scalar vertex properties ``names`` into ``(N, len(names))``; None when absent, but x y z are
    required (a ValueError)."""
    if "vertex" not in ply or any(name not in ply["vertex"].data.dtype.names for name in names):
        if names == ("x", "y", "z"):
            raise _error(path, "PLY file has no vertex element with x, y, z")
        return None
    columns = [ply["vertex"][name] for name in names]
    if any(c.dtype == object for c in columns):
        raise _error(path, f"PLY vertex properties {names} must be scalars")
    stacked = np.stack(columns, axis=1)
    return stacked.astype(stacked.dtype.newbyteorder("="))


def _read_ply_mesh(path: PathLike) -> Mesh:
    ply = _read_ply(path)
    vertices = _ply_vertex_columns(path, ply)
    if "face" not in ply:
        return Mesh(vertices, np.empty((0, 3), dtype=np.int64))
    names = ply["face"].data.dtype.names
    if (key := next((k for k in ("vertex_indices", "vertex_index") if k in names), None)) is None:
        raise _error(path, "PLY face element has no vertex_indices/vertex_index list")
    polygons = ply["face"][key]
    if polygons.dtype != object:  # fixed length, read in one go
        counts, flat = np.full(len(polygons), polygons.shape[1]), polygons.reshape(-1)
    else:
        counts = np.fromiter(map(len, polygons), dtype=np.int64, count=len(polygons))
        flat = np.concatenate(polygons) if len(polygons) else np.empty(0, np.int64)
    try:
        return Mesh(vertices, _io.fan_triangulate(counts, flat, len(vertices)))
    except ValueError as exc:
        raise _error(path, str(exc)) from None


def read_mesh(path: PathLike) -> Mesh:
    """Read a triangle mesh from ``.off``, ``.ply``, ``.stl`` or ``.obj`` (by extension).

    - OFF: ``OFF``, ``COFF``, ``NOFF``, ``CNOFF``, ``STOFF`` headers, ``#`` comments,
      per-vertex/per-face colours ignored.
    - PLY: ascii and binary (little/big endian); vertex ``x y z`` (other properties,
      including lists, are skipped), face list ``vertex_indices`` or ``vertex_index``.
    - STL: ascii and binary; corners with equal coordinates are merged into shared
      vertices, in order of first appearance.
    - OBJ: ``v`` and ``f`` records (``f 1 2 3``, ``f 1/1/1 ...``, ``f 1//1 ...``,
      negative relative indices); everything else is ignored.

    Polygons with more than three corners are fan-triangulated. Returns a :class:`Mesh` with ``(V, 3)`` float64
    vertices in the file's unit (CAD files are frequently in millimetres; scale to metres yourself) and ``(F, 3)`` int64
    faces. ValueError: unknown extension, malformed or truncated file, a header claiming more vertices or faces than
    the file holds (refused before allocating), a non-finite vertex, a face index out of range, or a face with fewer
    than 3 corners.
    """
    suffix = Path(path).suffix.lower()
    if suffix == ".ply":
        return _read_ply_mesh(path)
    if suffix not in (".off", ".stl", ".obj"):
        raise _error(path, f"unsupported mesh extension {suffix!r} (use .off, .ply, .stl, .obj)")
    try:  # parsed by the C++ core (scanalign/io/mesh_text.hpp)
        return Mesh(*_io.parse_mesh(Path(path).read_bytes(), suffix[1:]))
    except ValueError as exc:
        raise _error(path, str(exc)) from None


@contextlib.contextmanager
def atomic_open(path: PathLike, mode: str = "w", **kwargs):
    """``open(path, mode)`` for writing, all or nothing: the data goes to a hidden partial file
    beside ``path`` that replaces it only when the block completes, so an interrupted or
    failing write never leaves a truncated file (nor touches an existing one)."""
    path = Path(path)
    partial = path.with_name(f".{path.name}.{os.getpid()}.partial")
    try:
        with open(partial, mode, **kwargs) as fh:
            yield fh
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)


def write_ply(path: PathLike, points: npt.ArrayLike, normals: npt.ArrayLike | None = None,
              colors: npt.ArrayLike | None = None, binary: bool = True) -> None:
    """Write a point cloud as PLY (readable by MeshLab, CloudCompare, Open3D).

    The vertex element has ``float x y z``, then optionally ``float nx ny nz``, then optionally
    ``uchar red green blue``. Binary output uses ``binary_little_endian 1.0``; ASCII output prints floats with 9
    significant digits, so float32 values survive. (A short numpy writer: plyfile's ASCII writer is ten times slower.)
    ``points``: ``(N, 3)`` coordinates, in metres by library convention (stored as float32); ``normals``: optional
    ``(N, 3)`` (stored as float32); ``colors``: optional ``(N, 3)``, either uint8 / integers in ``[0, 255]`` or floats
    in ``[0, 1]`` (scaled by 255 and rounded). ValueError: wrong shapes or colour values out of range.
    """
    xyz = np.asarray(points, dtype=np.float32)
    if xyz.ndim != 2 or xyz.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {xyz.shape}")
    n = len(xyz)
    columns: list[tuple[str, np.ndarray]] = [("x", xyz[:, 0]), ("y", xyz[:, 1]), ("z", xyz[:, 2])]
    if normals is not None:
        nrm = np.asarray(normals, dtype=np.float32)
        if nrm.shape != (n, 3):
            raise ValueError(f"normals must have shape ({n}, 3), got {nrm.shape}")
        columns += [("nx", nrm[:, 0]), ("ny", nrm[:, 1]), ("nz", nrm[:, 2])]
    if colors is not None:
        rgb = np.asarray(colors)
        if rgb.shape != (n, 3):
            raise ValueError(f"colors must have shape ({n}, 3), got {rgb.shape}")
        if rgb.dtype.kind == "f":
            if rgb.size and not (np.isfinite(rgb).all() and rgb.min() >= 0 and rgb.max() <= 1):
                raise ValueError("float colors must lie in [0, 1]")
            rgb = np.rint(rgb * 255.0)
        elif rgb.dtype.kind not in "ui" or (rgb.size and (rgb.min() < 0 or rgb.max() > 255)):
            raise ValueError("integer colors must lie in [0, 255]")
        rgb = rgb.astype(np.uint8)
        columns += [("red", rgb[:, 0]), ("green", rgb[:, 1]), ("blue", rgb[:, 2])]

    ply_type = {np.dtype(np.float32): "float", np.dtype(np.uint8): "uchar"}
    header = [f"ply\nformat {'binary_little_endian' if binary else 'ascii'} 1.0\ncomment written by scanalign",
              f"element vertex {n}", *(f"property {ply_type[c.dtype]} {name}" for name, c in columns), "end_header"]
    with atomic_open(path, "wb") as fh:
        fh.write(("\n".join(header) + "\n").encode("ascii"))
        if binary:
            record = np.dtype([(name, c.dtype.newbyteorder("<")) for name, c in columns])
            table = np.empty(n, dtype=record)
            for name, c in columns:
                table[name] = c
            fh.write(table.tobytes())
        else:
            fmt = " ".join("%.9g" if c.dtype.kind == "f" else "%d" for _, c in columns)
            np.savetxt(fh, np.column_stack([c.astype(np.float64) for _, c in columns]), fmt=fmt)


def write_pcd(path: PathLike, points: npt.ArrayLike, normals: npt.ArrayLike | None = None) -> None:
    """Write a point cloud as a PCL ``.pcd`` file (``DATA binary``, version 0.7): fields ``x y z`` and, with
    ``normals``, ``normal_x normal_y normal_z``, all float32; an unorganised cloud (``HEIGHT 1``) with the identity
    ``VIEWPOINT``. ``points``: ``(N, 3)``, metres by library convention; ``normals``: optional ``(N, 3)``. PCL,
    Open3D and :func:`read_pcd` read it. ValueError: wrong shapes."""
    xyz = np.asarray(points, dtype=np.float32)
    if xyz.ndim != 2 or xyz.shape[1] != 3:
        raise ValueError(f"points must have shape (N, 3), got {xyz.shape}")
    fields, columns = ["x", "y", "z"], [xyz]
    if normals is not None:
        nrm = np.asarray(normals, dtype=np.float32)
        if nrm.shape != xyz.shape:
            raise ValueError(f"normals must have shape ({len(xyz)}, 3), got {nrm.shape}")
        fields, columns = fields + ["normal_x", "normal_y", "normal_z"], columns + [nrm]
    k, n = len(fields), len(xyz)
    header = ["# .PCD v0.7 - Point Cloud Data file format (written by scanalign)", "VERSION 0.7",
              "FIELDS " + " ".join(fields), "SIZE" + " 4" * k, "TYPE" + " F" * k, "COUNT" + " 1" * k, f"WIDTH {n}",
              "HEIGHT 1", "VIEWPOINT 0 0 0 1 0 0 0", f"POINTS {n}", "DATA binary"]
    with atomic_open(path, "wb") as fh:
        fh.write(("\n".join(header) + "\n").encode("ascii"))
        fh.write(np.hstack(columns).astype("<f4").tobytes())


def read_ply_points(path: PathLike) -> dict[str, np.ndarray]:
    """Read the vertices of a PLY file (ascii or binary) as a point cloud (faces, if any, are ignored):
    ``{"points": (N, 3) float64}`` in the file's unit, plus ``"normals"`` ``(N, 3)`` float64 if ``nx ny nz`` are present
    and ``"colors"`` ``(N, 3)`` uint8 if ``red green blue`` are present (float colours in ``[0, 1]`` are scaled by
    255). ValueError: malformed file or no ``x y z`` vertex properties."""
    ply = _read_ply(path)
    result = {"points": _ply_vertex_columns(path, ply).astype(np.float64)}
    if (normals := _ply_vertex_columns(path, ply, ("nx", "ny", "nz"))) is not None:
        result["normals"] = normals.astype(np.float64)
    if (colors := _ply_vertex_columns(path, ply, ("red", "green", "blue"))) is not None:
        if colors.dtype.kind == "f":
            colors = np.rint(np.clip(colors, 0.0, 1.0) * 255.0)
        result["colors"] = np.clip(colors, 0, 255).astype(np.uint8)
    return result


def read_cloud(path: PathLike) -> tuple:
    """A point cloud file, PCD or PLY (by suffix): ``(points (N, 3) float64 m, normals (N, 3)
    or None)``. ValueError naming the file for another format or a PCD without x, y, z."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".pcd":
        fields, n = read_pcd(path), ("normal_x", "normal_y", "normal_z")
        normals = np.column_stack([fields[k] for k in n]) if all(k in fields for k in n) else None
        return _pcd_xyz(path, fields).astype(np.float64), normals
    if suffix == ".ply":
        d = read_ply_points(path)
        return d["points"], d.get("normals")
    raise ValueError(f"{path}: unsupported cloud format {path.suffix!r} (use .pcd or .ply)")

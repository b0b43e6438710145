"""Readers and writers for point clouds and meshes (pure Python + numpy).

Formats:

- **PCD** (PCL Point Cloud Data, v0.5-v0.7): :func:`read_pcd`, :func:`read_pcd_points`,
  with ``DATA ascii``, ``binary`` and ``binary_compressed`` (LZF) payloads.
- **Meshes**: :func:`read_mesh` for ``.off``, ``.ply``, ``.stl`` and ``.obj``; polygons
  are fan-triangulated into a :class:`Mesh`.
- **PLY point clouds**: :func:`write_ply` and :func:`read_ply_points`.

Units: the library works in metres, but files store coordinates in whatever unit they
were written in (CAD meshes are often in millimetres).  The readers return the stored
numbers unchanged; scale them yourself when the file is not in metres.

Every parse error (truncated or corrupt file, unsupported variant, index out of range)
raises :class:`ValueError` whose message starts with the file path.
"""

from __future__ import annotations

import dataclasses
import os
import re
import struct
from pathlib import Path
from typing import NamedTuple, Union

import numpy as np
import numpy.typing as npt

__all__ = [
    "Mesh",
    "lzf_decompress",
    "read_mesh",
    "read_pcd",
    "read_pcd_points",
    "read_ply_points",
    "unpack_rgb",
    "write_ply",
]

PathLike = Union[str, "os.PathLike[str]"]


def _error(path: PathLike, message: str) -> ValueError:
    return ValueError(f"{os.fspath(path)}: {message}")


# --------------------------------------------------------------------------- LZF


def lzf_decompress(data: bytes, expected_size: int) -> bytes:
    """Decompress an LZF stream (the liblzf format PCL uses for ``binary_compressed``).

    The stream is a sequence of tokens.  A control byte ``c < 32`` starts a literal run
    of ``c + 1`` bytes copied from the input.  Otherwise ``c >> 5`` is the match length
    minus 2 (7 means "add the next byte"), and ``((c & 31) << 8) + next byte + 1`` is
    the distance back into the output; the match may overlap the bytes it produces.

    Args:
        data: the compressed bytes.
        expected_size: exact size of the decompressed output in bytes.

    Returns:
        The decompressed bytes, of length ``expected_size``.

    Raises:
        ValueError: the stream is truncated, refers before the start of the output,
            or does not decompress to exactly ``expected_size`` bytes.
    """
    src = memoryview(data)
    n_in = len(src)
    out = bytearray(expected_size)
    ip = 0
    op = 0
    while ip < n_in:
        ctrl = src[ip]
        ip += 1
        if ctrl < 32:  # literal run
            length = ctrl + 1
            if ip + length > n_in:
                raise ValueError(f"LZF literal run at input byte {ip - 1} is truncated")
            if op + length > expected_size:
                raise ValueError("LZF output exceeds the expected size")
            out[op : op + length] = src[ip : ip + length]
            ip += length
            op += length
            continue
        length = ctrl >> 5
        if length == 7:
            if ip >= n_in:
                raise ValueError("LZF back-reference is truncated")
            length += src[ip]
            ip += 1
        if ip >= n_in:
            raise ValueError("LZF back-reference is truncated")
        distance = ((ctrl & 31) << 8) + src[ip] + 1
        ip += 1
        length += 2
        start = op - distance
        if start < 0:
            raise ValueError(f"LZF back-reference at output byte {op} points before the start")
        if op + length > expected_size:
            raise ValueError("LZF output exceeds the expected size")
        if distance >= length:
            out[op : op + length] = out[start : start + length]
        else:  # overlapping copy: the last `distance` bytes repeat periodically
            period = bytes(out[start:op])
            out[op : op + length] = (period * (length // distance + 1))[:length]
        op += length
    if op != expected_size:
        raise ValueError(f"LZF stream decompressed to {op} bytes, expected {expected_size}")
    return bytes(out)


# --------------------------------------------------------------------------- PCD

_PCD_TYPES = {
    ("F", 4): np.float32,
    ("F", 8): np.float64,
    ("I", 1): np.int8,
    ("I", 2): np.int16,
    ("I", 4): np.int32,
    ("I", 8): np.int64,
    ("U", 1): np.uint8,
    ("U", 2): np.uint16,
    ("U", 4): np.uint32,
    ("U", 8): np.uint64,
}


class _PcdField(NamedTuple):
    name: str
    dtype: np.dtype
    count: int

    @property
    def nbytes(self) -> int:
        return self.dtype.itemsize * self.count


def _parse_pcd_header(path: PathLike, raw: bytes) -> tuple[list[_PcdField], int, str, int]:
    """Return (fields, number of points, DATA kind, offset of the payload)."""
    header: dict[str, list[str]] = {}
    pos = 0
    while True:
        end = raw.find(b"\n", pos)
        if end < 0:
            raise _error(path, "PCD header has no DATA line (truncated or not a PCD file)")
        line = raw[pos:end].decode("ascii", errors="replace").strip()
        pos = end + 1
        if not line or line.startswith("#"):
            continue
        key, *values = line.split()
        header[key.upper()] = values
        if key.upper() == "DATA":
            break

    def get(key: str) -> list[str]:
        if key not in header:
            raise _error(path, f"PCD header lacks {key}")
        return header[key]

    names = get("FIELDS")
    sizes = get("SIZE")
    types = get("TYPE")
    counts = header.get("COUNT", ["1"] * len(names))
    if not (len(names) == len(sizes) == len(types) == len(counts)):
        raise _error(
            path,
            f"PCD header FIELDS/SIZE/TYPE/COUNT lengths differ "
            f"({len(names)}, {len(sizes)}, {len(types)}, {len(counts)})",
        )
    fields = []
    for name, size, kind, count in zip(names, sizes, types, counts):
        try:
            dtype = np.dtype(_PCD_TYPES[(kind.upper(), int(size))])
            n = int(count)
        except (KeyError, ValueError):
            raise _error(
                path, f"PCD field {name!r} has unsupported TYPE {kind} SIZE {size} COUNT {count}"
            ) from None
        if n < 1:
            raise _error(path, f"PCD field {name!r} has COUNT {n}")
        fields.append(_PcdField(name, dtype.newbyteorder("<"), n))

    try:
        width = int(get("WIDTH")[0])
        height = int(header.get("HEIGHT", ["1"])[0])
        n_points = int(header["POINTS"][0]) if "POINTS" in header else width * height
    except (IndexError, ValueError):
        raise _error(path, "PCD header has a malformed WIDTH, HEIGHT or POINTS") from None
    if n_points < 0 or n_points != width * height:
        raise _error(path, f"PCD POINTS {n_points} does not equal WIDTH*HEIGHT {width}*{height}")
    data = get("DATA")
    kind = data[0].lower() if data else ""
    if kind not in ("ascii", "binary", "binary_compressed"):
        raise _error(path, f"unknown PCD DATA type {' '.join(data)!r}")
    return fields, n_points, kind, pos


def _parse_pcd_ascii(
    path: PathLike, payload: bytes, fields: list[_PcdField], n_points: int
) -> dict[str, np.ndarray]:
    tokens = payload.split()
    per_point = sum(f.count for f in fields)
    if len(tokens) < n_points * per_point:
        raise _error(
            path,
            f"PCD ascii data is truncated: {len(tokens)} values for "
            f"{n_points} points x {per_point} values",
        )
    table = np.array(tokens[: n_points * per_point]).reshape(n_points, per_point)
    result: dict[str, np.ndarray] = {}
    column = 0
    for field in fields:
        text = table[:, column : column + field.count]
        column += field.count
        try:
            if (
                field.name in ("rgb", "rgba")
                and field.dtype.kind == "f"
                and bool(np.char.isdigit(text).all())
            ):
                # Newer PCL writes packed colours as their integer bit pattern.
                values = text.astype(np.uint32).view(np.float32)
            else:
                values = text.astype(field.dtype)
        except (ValueError, OverflowError) as exc:
            raise _error(path, f"PCD ascii field {field.name!r}: {exc}") from None
        result[field.name] = values[:, 0] if field.count == 1 else values
    return result


def _parse_pcd_binary(
    path: PathLike, payload: bytes, fields: list[_PcdField], n_points: int
) -> dict[str, np.ndarray]:
    point_size = sum(f.nbytes for f in fields)
    if len(payload) < n_points * point_size:
        raise _error(
            path,
            f"PCD binary data is truncated: {len(payload)} bytes for "
            f"{n_points} points x {point_size} bytes",
        )
    record = np.dtype(
        {
            "names": [f"f{i}" for i in range(len(fields))],
            "formats": [(f.dtype, (f.count,)) for f in fields],
        }
    )
    table = np.frombuffer(payload, dtype=record, count=n_points)
    return {
        f.name: table[f"f{i}"][:, 0] if f.count == 1 else table[f"f{i}"]
        for i, f in enumerate(fields)
    }


def _parse_pcd_compressed(
    path: PathLike, payload: bytes, fields: list[_PcdField], n_points: int
) -> dict[str, np.ndarray]:
    if len(payload) < 8:
        raise _error(path, "PCD binary_compressed data is truncated (no size header)")
    compressed_size, uncompressed_size = struct.unpack_from("<II", payload)
    point_size = sum(f.nbytes for f in fields)
    if uncompressed_size != n_points * point_size:
        raise _error(
            path,
            f"PCD binary_compressed uncompressed size {uncompressed_size} does not match "
            f"{n_points} points x {point_size} bytes",
        )
    if len(payload) < 8 + compressed_size:
        raise _error(
            path,
            f"PCD binary_compressed data is truncated: {len(payload) - 8} of "
            f"{compressed_size} compressed bytes",
        )
    try:
        raw = lzf_decompress(payload[8 : 8 + compressed_size], uncompressed_size)
    except ValueError as exc:
        raise _error(path, f"corrupt PCD binary_compressed data: {exc}") from None
    result: dict[str, np.ndarray] = {}
    offset = 0
    for field in fields:  # structure of arrays: one block per field
        values = np.frombuffer(raw, dtype=field.dtype, count=n_points * field.count, offset=offset)
        offset += n_points * field.nbytes
        result[field.name] = values if field.count == 1 else values.reshape(n_points, field.count)
    return result


def read_pcd(path: PathLike) -> dict[str, np.ndarray]:
    """Read a PCL ``.pcd`` file into a dict of per-point field arrays.

    Args:
        path: the ``.pcd`` file (``DATA ascii``, ``binary`` or ``binary_compressed``).

    Returns:
        Field name -> array, in header order, with the dtype given by the header
        (``TYPE``/``SIZE``).  A field with ``COUNT 1`` has shape ``(N,)``, otherwise
        ``(N, COUNT)``.  Organised clouds (``HEIGHT > 1``) are flattened row by row to
        ``N = WIDTH * HEIGHT``; invalid points stay in place as NaN.  Coordinates
        (``x``, ``y``, ``z``) are in the file's unit (metres for PCL's own data).
        Normals come back as their own fields (``normal_x``, ``normal_y``, ``normal_z``).
        Packed colours (``rgb``/``rgba``) are returned raw; see :func:`unpack_rgb`.
        PCL's padding fields named ``_`` are dropped.

    Raises:
        ValueError: malformed header, unknown DATA type, truncated or corrupt payload.
    """
    raw = Path(path).read_bytes()
    fields, n_points, kind, offset = _parse_pcd_header(path, raw)
    payload = raw[offset:]
    if kind == "ascii":
        result = _parse_pcd_ascii(path, payload, fields, n_points)
    elif kind == "binary":
        result = _parse_pcd_binary(path, payload, fields, n_points)
    else:
        result = _parse_pcd_compressed(path, payload, fields, n_points)
    # Own, contiguous, writable arrays rather than views into the file buffer.
    return {name: np.array(values) for name, values in result.items() if name != "_"}


def read_pcd_points(
    path: PathLike, dtype: npt.DTypeLike = np.float64, remove_nan: bool = True
) -> np.ndarray:
    """Read the ``x y z`` coordinates of a ``.pcd`` file.

    Args:
        path: the ``.pcd`` file.
        dtype: floating dtype of the result.
        remove_nan: drop rows with any non-finite coordinate (invalid points of
            organised clouds are stored as NaN).

    Returns:
        ``(N, 3)`` array of points in the file's unit (metres for PCL's own data).

    Raises:
        ValueError: the file is not a valid PCD file or has no ``x``, ``y``, ``z`` fields.
    """
    fields = read_pcd(path)
    missing = [axis for axis in "xyz" if axis not in fields]
    if missing:
        raise _error(path, f"PCD file has no {'/'.join(missing)} field(s)")
    points = np.stack([fields["x"], fields["y"], fields["z"]], axis=1).astype(dtype)
    if remove_nan:
        points = points[np.isfinite(points).all(axis=1)]
    return points


def unpack_rgb(field: npt.ArrayLike) -> np.ndarray:
    """Unpack PCL's packed ``rgb``/``rgba`` field into 8-bit colours.

    PCL stores a colour as the 32-bit pattern ``0xAARRGGBB``, typed either as a float
    (``rgb``, TYPE F) or as an unsigned integer (``rgba``, TYPE U).  Float input is
    reinterpreted bit for bit (float64 input is first narrowed to float32).

    Args:
        field: ``(N,)`` packed values as returned by :func:`read_pcd`.

    Returns:
        ``(N, 3)`` uint8 array of ``red, green, blue``.
    """
    values = np.asarray(field)
    if values.dtype.kind == "f":
        bits = values.astype(np.float32).view(np.uint32)
    else:
        bits = values.astype(np.uint32)
    shifts = np.array([16, 8, 0], dtype=np.uint32)
    return ((bits[..., None] >> shifts) & 0xFF).astype(np.uint8)


# --------------------------------------------------------------------------- meshes


@dataclasses.dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh.

    Attributes:
        vertices: ``(V, 3)`` float64 vertex positions, in the unit the source file used.
        faces: ``(F, 3)`` int64 vertex indices, each in ``[0, V)``.  Winding order is
            kept from the file (counter-clockwise seen from outside, by convention).
    """

    vertices: np.ndarray
    faces: np.ndarray

    def __post_init__(self) -> None:
        vertices = np.asarray(self.vertices, dtype=np.float64)
        faces = np.asarray(self.faces, dtype=np.int64)
        if vertices.ndim != 2 or vertices.shape[1] != 3:
            raise ValueError(f"Mesh vertices must have shape (V, 3), got {vertices.shape}")
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise ValueError(f"Mesh faces must have shape (F, 3), got {faces.shape}")
        if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
            raise ValueError(
                f"Mesh face indices must lie in [0, {len(vertices)}), "
                f"got [{faces.min()}, {faces.max()}]"
            )
        object.__setattr__(self, "vertices", vertices)
        object.__setattr__(self, "faces", faces)


def _fan_triangulate(
    path: PathLike, counts: np.ndarray, flat: np.ndarray, n_vertices: int
) -> np.ndarray:
    """Fan-triangulate polygons given as vertex counts + concatenated indices.

    Polygon ``(p0, p1, ..., pk)`` becomes ``(p0, p1, p2), (p0, p2, p3), ...``.
    Indices are validated against ``n_vertices``.
    """
    counts = np.asarray(counts, dtype=np.int64)
    flat = np.asarray(flat, dtype=np.int64)
    if counts.size and counts.min() < 3:
        bad = int(np.argmax(counts < 3))
        raise _error(path, f"face {bad} has {counts[bad]} vertices (at least 3 needed)")
    if flat.size and (flat.min() < 0 or flat.max() >= n_vertices):
        raise _error(
            path,
            f"face vertex index out of range [0, {n_vertices}): "
            f"found {flat.min() if flat.min() < 0 else flat.max()}",
        )
    starts = np.cumsum(counts) - counts
    n_tris = counts - 2
    first = np.repeat(starts, n_tris)
    # k-th triangle of a polygon uses its corners 0, k+1, k+2.
    k = np.arange(int(n_tris.sum())) - np.repeat(np.cumsum(n_tris) - n_tris, n_tris)
    return np.stack([flat[first], flat[first + k + 1], flat[first + k + 2]], axis=1)


def _content_lines(text: str) -> list[str]:
    """Lines with ``#`` comments removed, blank lines dropped."""
    lines = (line.split("#", 1)[0].strip() for line in text.splitlines())
    return [line for line in lines if line]


def _read_off(path: PathLike) -> Mesh:
    lines = _content_lines(Path(path).read_text(encoding="utf-8", errors="replace"))
    if not lines:
        raise _error(path, "empty OFF file")
    keyword, *rest = lines[0].split()
    match = re.fullmatch(r"(ST)?(C)?(N)?(4)?(n)?OFF", keyword)
    if match is None:
        raise _error(path, f"not an OFF file (header {keyword!r})")
    if match.group(4) or match.group(5):
        raise _error(path, f"{keyword}: only 3D OFF files are supported")
    if rest and rest[0].upper() == "BINARY":
        raise _error(path, "binary OFF files are not supported")
    body = lines[1:]
    if not rest:  # counts on their own line
        if not body:
            raise _error(path, "OFF file has no vertex/face counts")
        rest = body[0].split()
        body = body[1:]
    try:
        n_vertices, n_faces = int(rest[0]), int(rest[1])
    except (IndexError, ValueError):
        raise _error(path, f"malformed OFF counts line {' '.join(rest)!r}") from None
    if len(body) < n_vertices + n_faces:
        raise _error(
            path,
            f"OFF file is truncated: {len(body)} data lines for "
            f"{n_vertices} vertices + {n_faces} faces",
        )
    try:
        coords = [line.split()[:3] for line in body[:n_vertices]]
        if any(len(c) != 3 for c in coords):
            raise ValueError("a vertex line has fewer than 3 coordinates")
        vertices = np.array(coords, dtype=np.float64).reshape(n_vertices, 3)
        counts = np.empty(n_faces, dtype=np.int64)
        flat: list[str] = []
        for i, line in enumerate(body[n_vertices : n_vertices + n_faces]):
            tokens = line.split()
            k = int(tokens[0])
            if len(tokens) < k + 1:
                raise ValueError(f"face {i} lists fewer than {k} indices")
            counts[i] = k
            flat.extend(tokens[1 : k + 1])
        indices = np.array(flat, dtype=np.int64)
    except ValueError as exc:
        raise _error(path, f"malformed OFF data: {exc}") from None
    return Mesh(vertices, _fan_triangulate(path, counts, indices, n_vertices))


# PLY ------------------------------------------------------------------------

_PLY_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}


class _PlyList(NamedTuple):
    """A PLY list property: per-row lengths and all values concatenated."""

    counts: np.ndarray
    values: np.ndarray


class _PlyProperty(NamedTuple):
    name: str
    dtype: np.dtype
    count_dtype: np.dtype | None  # None for scalar properties


class _PlyElement(NamedTuple):
    name: str
    count: int
    properties: list[_PlyProperty]


def _parse_ply_header(path: PathLike, raw: bytes) -> tuple[str, list[_PlyElement], int]:
    """Return (format, elements, offset of the body)."""
    end = raw.find(b"end_header")
    if not raw.startswith(b"ply") or end < 0:
        raise _error(path, "not a PLY file (missing 'ply' magic or 'end_header')")
    body_start = raw.find(b"\n", end)
    if body_start < 0:
        raise _error(path, "PLY file is truncated after end_header")
    lines = raw[:end].decode("ascii", errors="replace").splitlines()[1:]
    fmt = ""
    elements: list[_PlyElement] = []
    for line in lines:
        tokens = line.split()
        if not tokens or tokens[0] in ("comment", "obj_info"):
            continue
        try:
            if tokens[0] == "format":
                fmt = tokens[1]
            elif tokens[0] == "element":
                elements.append(_PlyElement(tokens[1], int(tokens[2]), []))
            elif tokens[0] == "property" and tokens[1] == "list":
                count_type, item_type = _PLY_TYPES[tokens[2]], _PLY_TYPES[tokens[3]]
                elements[-1].properties.append(
                    _PlyProperty(tokens[4], np.dtype(item_type), np.dtype(count_type))
                )
            elif tokens[0] == "property":
                elements[-1].properties.append(
                    _PlyProperty(tokens[2], np.dtype(_PLY_TYPES[tokens[1]]), None)
                )
            else:
                raise ValueError(f"unknown keyword {tokens[0]!r}")
        except (IndexError, KeyError, ValueError) as exc:
            raise _error(path, f"malformed PLY header line {line!r} ({exc})") from None
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise _error(path, f"unsupported PLY format {fmt!r}")
    return fmt, elements, body_start + 1


def _ply_ascii_element(
    path: PathLike, element: _PlyElement, tokens: list[bytes], pos: int
) -> tuple[dict[str, np.ndarray | _PlyList], int]:
    props = element.properties
    if all(p.count_dtype is None for p in props):
        n = element.count * len(props)
        if pos + n > len(tokens):
            raise _error(path, f"PLY element {element.name!r} is truncated")
        table = np.array(tokens[pos : pos + n]).reshape(element.count, len(props))
        try:
            columns: dict[str, np.ndarray | _PlyList] = {
                p.name: table[:, j].astype(p.dtype) for j, p in enumerate(props)
            }
        except ValueError as exc:
            raise _error(path, f"malformed PLY element {element.name!r}: {exc}") from None
        return columns, pos + n
    # Rows of varying length: walk the tokens.
    scalars: dict[str, list[bytes]] = {p.name: [] for p in props if p.count_dtype is None}
    lists: dict[str, tuple[list[int], list[bytes]]] = {
        p.name: ([], []) for p in props if p.count_dtype is not None
    }
    try:
        for _ in range(element.count):
            for p in props:
                if p.count_dtype is None:
                    scalars[p.name].append(tokens[pos])
                    pos += 1
                else:
                    k = int(tokens[pos])
                    if k < 0 or pos + 1 + k > len(tokens):
                        raise IndexError
                    lists[p.name][0].append(k)
                    lists[p.name][1].extend(tokens[pos + 1 : pos + 1 + k])
                    pos += 1 + k
        result: dict[str, np.ndarray | _PlyList] = {}
        for p in props:
            if p.count_dtype is None:
                result[p.name] = np.array(scalars[p.name]).astype(p.dtype)
            else:
                counts, values = lists[p.name]
                result[p.name] = _PlyList(
                    np.array(counts, dtype=np.int64), np.array(values).astype(p.dtype)
                )
    except IndexError:
        raise _error(path, f"PLY element {element.name!r} is truncated") from None
    except ValueError as exc:
        raise _error(path, f"malformed PLY element {element.name!r}: {exc}") from None
    return result, pos


def _ply_binary_element(
    path: PathLike, element: _PlyElement, raw: bytes, pos: int, order: str
) -> tuple[dict[str, np.ndarray | _PlyList], int]:
    props = element.properties

    def truncated() -> ValueError:
        return _error(path, f"PLY element {element.name!r} is truncated")

    def read_length(prop: _PlyProperty, at: int) -> int:
        assert prop.count_dtype is not None
        if at + prop.count_dtype.itemsize > len(raw):
            raise truncated()
        return int(np.frombuffer(raw, prop.count_dtype.newbyteorder(order), 1, at)[0])

    # Fast path: assume every row has the list lengths of the first row (true for
    # triangle meshes), read all rows with one structured dtype, then verify.
    lengths: dict[int, int] = {}
    at = pos
    for j, p in enumerate(props):
        if p.count_dtype is None:
            at += p.dtype.itemsize
        else:
            lengths[j] = read_length(p, at) if element.count else 0
            at += p.count_dtype.itemsize + lengths[j] * p.dtype.itemsize
    names: list[str] = []
    formats: list[object] = []
    for j, p in enumerate(props):
        item = p.dtype.newbyteorder(order)
        if p.count_dtype is None:
            names.append(f"p{j}")
            formats.append(item)
        else:
            names += [f"n{j}", f"p{j}"]
            formats += [p.count_dtype.newbyteorder(order), (item, (lengths[j],))]
    record = np.dtype({"names": names, "formats": formats})
    end = pos + element.count * record.itemsize
    if end <= len(raw):
        table = np.frombuffer(raw, record, element.count, pos)
        if all((table[f"n{j}"] == k).all() for j, k in lengths.items()):
            result: dict[str, np.ndarray | _PlyList] = {}
            for j, p in enumerate(props):
                column = table[f"p{j}"].astype(p.dtype)
                if p.count_dtype is None:
                    result[p.name] = column
                else:
                    counts = np.full(element.count, lengths[j], dtype=np.int64)
                    result[p.name] = _PlyList(counts, column.reshape(-1))
            return result, end
    elif not lengths:
        raise truncated()

    # Slow path: rows whose lists vary in length.
    chunks: dict[int, list[bytes]] = {j: [] for j in range(len(props))}
    list_lengths: dict[int, list[int]] = {j: [] for j in lengths}
    for _ in range(element.count):
        for j, p in enumerate(props):
            if p.count_dtype is None:
                size = p.dtype.itemsize
            else:
                k = read_length(p, pos)
                list_lengths[j].append(k)
                pos += p.count_dtype.itemsize
                size = k * p.dtype.itemsize
            if pos + size > len(raw):
                raise truncated()
            chunks[j].append(raw[pos : pos + size])
            pos += size
    result = {}
    for j, p in enumerate(props):
        values = np.frombuffer(b"".join(chunks[j]), p.dtype.newbyteorder(order)).astype(p.dtype)
        if p.count_dtype is None:
            result[p.name] = values
        else:
            result[p.name] = _PlyList(np.array(list_lengths[j], dtype=np.int64), values)
    return result, pos


def _read_ply(path: PathLike) -> dict[str, dict[str, np.ndarray | _PlyList]]:
    """Parse a PLY file into element name -> property name -> values."""
    raw = Path(path).read_bytes()
    fmt, elements, pos = _parse_ply_header(path, raw)
    result: dict[str, dict[str, np.ndarray | _PlyList]] = {}
    if fmt == "ascii":
        tokens = raw[pos:].split()
        token_pos = 0
        for element in elements:
            result[element.name], token_pos = _ply_ascii_element(path, element, tokens, token_pos)
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        for element in elements:
            result[element.name], pos = _ply_binary_element(path, element, raw, pos, order)
    return result


def _ply_vertex_columns(
    path: PathLike, ply: dict[str, dict[str, np.ndarray | _PlyList]], names: tuple[str, ...]
) -> np.ndarray | None:
    """Stack scalar vertex properties ``names`` into ``(N, len(names))``, or None."""
    vertex = ply.get("vertex", {})
    columns = [vertex.get(name) for name in names]
    if any(c is None for c in columns):
        return None
    if any(isinstance(c, _PlyList) for c in columns):
        raise _error(path, f"PLY vertex properties {names} must be scalars")
    return np.stack(columns, axis=1)  # type: ignore[arg-type]


def _read_ply_mesh(path: PathLike) -> Mesh:
    ply = _read_ply(path)
    vertices = _ply_vertex_columns(path, ply, ("x", "y", "z"))
    if vertices is None:
        raise _error(path, "PLY file has no vertex element with x, y, z")
    faces_element = ply.get("face", {})
    polygons = faces_element.get("vertex_indices", faces_element.get("vertex_index"))
    if polygons is None:
        if faces_element:
            raise _error(path, "PLY face element has no vertex_indices/vertex_index list")
        return Mesh(vertices, np.empty((0, 3), dtype=np.int64))
    if not isinstance(polygons, _PlyList):
        raise _error(path, "PLY face vertex_indices is not a list property")
    return Mesh(vertices, _fan_triangulate(path, polygons.counts, polygons.values, len(vertices)))


# STL / OBJ --------------------------------------------------------------------


def _merge_vertices(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge bit-identical corner positions; keep first-appearance order.

    Args:
        corners: ``(3F, 3)`` triangle corners.

    Returns:
        ``(V, 3)`` unique vertices and ``(F, 3)`` faces indexing them.
    """
    unique, first, inverse = np.unique(corners, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return unique[order], rank[inverse.reshape(-1)].reshape(-1, 3)


def _read_stl(path: PathLike) -> Mesh:
    raw = Path(path).read_bytes()
    if len(raw) >= 84:
        (n_triangles,) = struct.unpack_from("<I", raw, 80)
        if len(raw) == 84 + 50 * n_triangles:
            record = np.dtype(
                [("normal", "<f4", (3,)), ("corners", "<f4", (3, 3)), ("attribute", "<u2")]
            )
            table = np.frombuffer(raw, record, n_triangles, 84)
            return Mesh(*_merge_vertices(table["corners"].reshape(-1, 3).astype(np.float64)))
    if not raw.lstrip().startswith(b"solid"):
        raise _error(path, "neither a binary STL (size mismatch) nor an ASCII STL ('solid')")
    text = raw.decode("ascii", errors="replace")
    loops = len(re.findall(r"\bouter\s+loop\b", text))
    if loops != len(re.findall(r"\bendloop\b", text)) or loops != len(
        re.findall(r"\bendfacet\b", text)
    ):
        raise _error(path, "ASCII STL is truncated or malformed (unbalanced facet/loop)")
    coords = re.findall(r"\bvertex\s+(\S+)\s+(\S+)\s+(\S+)", text)
    if len(coords) != 3 * loops:
        raise _error(path, f"ASCII STL has {len(coords)} vertices for {loops} triangles")
    try:
        corners = np.array(coords, dtype=np.float64).reshape(-1, 3)
    except ValueError as exc:
        raise _error(path, f"malformed ASCII STL vertex: {exc}") from None
    return Mesh(*_merge_vertices(corners))


def _read_obj(path: PathLike) -> Mesh:
    text = Path(path).read_text(encoding="utf-8", errors="replace").replace("\\\n", " ")
    vertices: list[list[str]] = []
    counts: list[int] = []
    flat: list[int] = []
    try:
        for line_no, line in enumerate(text.splitlines(), start=1):
            tokens = line.split("#", 1)[0].split()
            if not tokens:
                continue
            if tokens[0] == "v":
                if len(tokens) < 4:
                    raise ValueError(f"line {line_no}: vertex with fewer than 3 coordinates")
                vertices.append(tokens[1:4])
            elif tokens[0] == "f":
                for corner in tokens[1:]:
                    index = int(corner.split("/", 1)[0])
                    if index == 0:
                        raise ValueError(f"line {line_no}: OBJ indices start at 1")
                    # Negative indices count back from the latest vertex.
                    flat.append(index - 1 if index > 0 else len(vertices) + index)
                counts.append(len(tokens) - 1)
        vertex_array = np.array(vertices, dtype=np.float64).reshape(-1, 3)
    except ValueError as exc:
        raise _error(path, f"malformed OBJ: {exc}") from None
    faces = _fan_triangulate(path, np.array(counts), np.array(flat), len(vertex_array))
    return Mesh(vertex_array, faces)


_MESH_READERS = {".off": _read_off, ".ply": _read_ply_mesh, ".stl": _read_stl, ".obj": _read_obj}


def read_mesh(path: PathLike) -> Mesh:
    """Read a triangle mesh from ``.off``, ``.ply``, ``.stl`` or ``.obj`` (by extension).

    - OFF: ``OFF``, ``COFF``, ``NOFF``, ``CNOFF``, ``STOFF`` headers, ``#`` comments,
      per-vertex/per-face colours ignored.
    - PLY: ascii and binary (little/big endian); vertex ``x y z`` (other properties,
      including lists, are skipped), face list ``vertex_indices`` or ``vertex_index``.
    - STL: ascii and binary; bit-identical corners are merged into shared vertices.
    - OBJ: ``v`` and ``f`` records (``f 1 2 3``, ``f 1/1/1 ...``, ``f 1//1 ...``,
      negative relative indices); everything else is ignored.

    Polygons with more than three corners are fan-triangulated.

    Args:
        path: the mesh file.

    Returns:
        A :class:`Mesh` with ``(V, 3)`` float64 vertices in the file's unit (CAD files
        are frequently in millimetres; scale to metres yourself) and ``(F, 3)`` int64 faces.

    Raises:
        ValueError: unknown extension, malformed or truncated file, face index out of
            range, or a face with fewer than 3 corners.
    """
    suffix = Path(path).suffix.lower()
    if suffix not in _MESH_READERS:
        raise _error(path, f"unsupported mesh extension {suffix!r} (use .off, .ply, .stl, .obj)")
    return _MESH_READERS[suffix](path)


# --------------------------------------------------------------------------- PLY points


def write_ply(
    path: PathLike,
    points: npt.ArrayLike,
    normals: npt.ArrayLike | None = None,
    colors: npt.ArrayLike | None = None,
    binary: bool = True,
) -> None:
    """Write a point cloud as PLY (readable by MeshLab, CloudCompare, Open3D).

    The vertex element has ``float x y z``, then optionally ``float nx ny nz``, then
    optionally ``uchar red green blue``.  Binary output uses ``binary_little_endian 1.0``;
    ASCII output prints floats with 9 significant digits, so float32 values survive.

    Args:
        path: output file.
        points: ``(N, 3)`` coordinates, in metres by library convention (stored as float32).
        normals: optional ``(N, 3)`` normals (stored as float32).
        colors: optional ``(N, 3)`` colours, either uint8 / integers in ``[0, 255]`` or
            floats in ``[0, 1]`` (scaled by 255 and rounded).
        binary: binary little endian (default) or ASCII.

    Raises:
        ValueError: wrong shapes or colour values out of range.
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
    header = [
        "ply",
        f"format {'binary_little_endian' if binary else 'ascii'} 1.0",
        "comment written by scanalign",
        f"element vertex {n}",
        *(f"property {ply_type[c.dtype]} {name}" for name, c in columns),
        "end_header",
    ]
    with open(path, "wb") as fh:
        fh.write(("\n".join(header) + "\n").encode("ascii"))
        if binary:
            record = np.dtype([(name, c.dtype.newbyteorder("<")) for name, c in columns])
            table = np.empty(n, dtype=record)
            for name, c in columns:
                table[name] = c
            fh.write(table.tobytes())
        else:
            fmt = " ".join("%.9g" if c.dtype.kind == "f" else "%d" for _, c in columns)
            table = np.empty((n, len(columns)), dtype=object)
            for j, (_, c) in enumerate(columns):
                table[:, j] = c.tolist()
            np.savetxt(fh, table, fmt=fmt)


def read_ply_points(path: PathLike) -> dict[str, np.ndarray]:
    """Read the vertices of a PLY file as a point cloud (faces, if any, are ignored).

    Args:
        path: a PLY file (ascii or binary).

    Returns:
        ``{"points": (N, 3) float64}`` in the file's unit, plus ``"normals"``
        ``(N, 3)`` float64 if ``nx ny nz`` are present and ``"colors"`` ``(N, 3)`` uint8
        if ``red green blue`` are present (float colours in ``[0, 1]`` are scaled by 255).

    Raises:
        ValueError: malformed file or no ``x y z`` vertex properties.
    """
    ply = _read_ply(path)
    points = _ply_vertex_columns(path, ply, ("x", "y", "z"))
    if points is None:
        raise _error(path, "PLY file has no vertex element with x, y, z")
    result = {"points": points.astype(np.float64)}
    normals = _ply_vertex_columns(path, ply, ("nx", "ny", "nz"))
    if normals is not None:
        result["normals"] = normals.astype(np.float64)
    colors = _ply_vertex_columns(path, ply, ("red", "green", "blue"))
    if colors is not None:
        if colors.dtype.kind == "f":
            colors = np.rint(np.clip(colors, 0.0, 1.0) * 255.0)
        result["colors"] = np.clip(colors, 0, 255).astype(np.uint8)
    return result

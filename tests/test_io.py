"""Tests for scanalign.io: PCD, mesh formats, PLY point clouds."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from scanalign import io

# --------------------------------------------------------------------------- helpers

# Unit cube, quads counter-clockwise seen from outside.
CUBE_VERTICES = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=np.float64,
)
CUBE_QUADS = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (2, 3, 7, 6), (0, 4, 7, 3), (1, 2, 6, 5)]
# Fan triangulation of each quad (a, b, c, d) -> (a, b, c), (a, c, d).
CUBE_TRIANGLES = np.array([t for a, b, c, d in CUBE_QUADS for t in ((a, b, c), (a, c, d))])

TETRA_VERTICES = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
TETRA_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def signed_volume(mesh: io.Mesh) -> float:
    a, b, c = (mesh.vertices[mesh.faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->", a, np.cross(b, c)) / 6.0)


def triangle_set(vertices: np.ndarray, faces: np.ndarray) -> set[tuple]:
    """Triangles as coordinate tuples, rotated to a canonical start (winding kept)."""
    result = set()
    for face in faces:
        corners = [tuple(vertices[i]) for i in face]
        k = corners.index(min(corners))
        result.add(tuple(corners[k:] + corners[:k]))
    return result


def lzf_literals(data: bytes) -> bytes:
    """A trivial LZF 'compressor' that emits only literal runs."""
    out = bytearray()
    for start in range(0, len(data), 32):
        chunk = data[start : start + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)


def lzf_compress(data: bytes) -> tuple[bytes, dict[str, int]]:
    """Greedy LZF compressor (3-byte hash, matches may overlap their own output).

    Returns the stream and counts of the back-reference kinds it emitted.
    """
    out = bytearray()
    pending = bytearray()
    stats = {"refs": 0, "overlapping": 0, "long": 0}
    last_seen: dict[bytes, int] = {}

    def flush() -> None:
        out.extend(lzf_literals(bytes(pending)))
        pending.clear()

    i = 0
    while i < len(data):
        key = data[i : i + 3]
        candidate = last_seen.get(key) if len(key) == 3 else None
        last_seen[key] = i
        if candidate is None or i - candidate > 8192:
            pending.append(data[i])
            i += 1
            continue
        length = 3
        while (
            i + length < len(data)
            and length < 264
            and data[candidate + length] == data[i + length]
        ):
            length += 1
        flush()
        distance = i - candidate
        code = length - 2
        if code < 7:
            out.append((code << 5) | ((distance - 1) >> 8))
        else:
            out.append((7 << 5) | ((distance - 1) >> 8))
            out.append(code - 7)
        out.append((distance - 1) & 0xFF)
        stats["refs"] += 1
        stats["overlapping"] += distance < length
        stats["long"] += code >= 7
        i += length
    flush()
    return bytes(out), stats


PCD_TYPE = {"f": "F", "i": "I", "u": "U"}


def write_pcd(
    path: Path,
    fields: dict[str, np.ndarray],
    data: str,
    compress=lzf_literals,
    width: int | None = None,
    ascii_rgb_as_int: bool = True,
) -> None:
    """Minimal PCD v0.7 writer. fields: name -> (N,) or (N, count) little-endian array."""
    arrays = [np.asarray(a) for a in fields.values()]
    n = len(arrays[0])
    counts = [1 if a.ndim == 1 else a.shape[1] for a in arrays]
    width = n if width is None else width
    header = (
        "# .PCD v0.7 - Point Cloud Data file format\n"
        "VERSION 0.7\n"
        f"FIELDS {' '.join(fields)}\n"
        f"SIZE {' '.join(str(a.dtype.itemsize) for a in arrays)}\n"
        f"TYPE {' '.join(PCD_TYPE[a.dtype.kind] for a in arrays)}\n"
        f"COUNT {' '.join(map(str, counts))}\n"
        f"WIDTH {width}\nHEIGHT {n // width}\n"
        "VIEWPOINT 0 0 0 1 0 0 0\n"
        f"POINTS {n}\nDATA {data}\n"
    )
    columns = [a.reshape(n, -1) for a in arrays]
    if data == "ascii":
        lines = []
        for i in range(n):
            values = []
            for name, col in zip(fields, columns):
                for v in col[i]:
                    if name in ("rgb", "rgba") and ascii_rgb_as_int:
                        values.append(str(np.asarray(v).view(np.uint32)))
                    elif col.dtype.kind == "f":
                        values.append(repr(float(v)))
                    else:
                        values.append(str(int(v)))
            lines.append(" ".join(values))
        payload = ("\n".join(lines) + "\n").encode()
    elif data == "binary":
        record = np.dtype([(f"f{j}", c.dtype, (c.shape[1],)) for j, c in enumerate(columns)])
        table = np.empty(n, dtype=record)
        for j, c in enumerate(columns):
            table[f"f{j}"] = c
        payload = table.tobytes()
    else:
        raw = b"".join(np.ascontiguousarray(c).tobytes() for c in columns)
        packed = compress(raw)
        payload = struct.pack("<II", len(packed), len(raw)) + packed
    path.write_bytes(header.encode() + payload)


def pack_rgb(rgb: np.ndarray) -> np.ndarray:
    rgb = rgb.astype(np.uint32)
    return ((rgb[:, 0] << 16) | (rgb[:, 1] << 8) | rgb[:, 2]).view(np.float32)


@pytest.fixture
def cloud_fields() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(1)
    n = 300
    xyz = rng.normal(size=(n, 3)).astype(np.float32)
    xyz[:, 2] = np.round(xyz[:, 2], 1)  # repeated values give the compressor matches
    xyz[5] = np.nan  # an invalid point
    normals = rng.normal(size=(n, 3)).astype(np.float32)
    colors = rng.integers(0, 256, size=(n, 3))
    colors[:100] = (200, 10, 30)
    return {
        "x": xyz[:, 0],
        "y": xyz[:, 1],
        "z": xyz[:, 2],
        "normal_x": normals[:, 0],
        "normal_y": normals[:, 1],
        "normal_z": normals[:, 2],
        "rgb": pack_rgb(colors),
        "label": np.repeat(np.arange(n // 30, dtype=np.uint16), 30),
        "hist": rng.integers(-1000, 1000, size=(n, 3)).astype(np.int32),
        "curvature": np.zeros(n, dtype=np.float64),
    }


def assert_fields_equal(result: dict[str, np.ndarray], expected: dict[str, np.ndarray]) -> None:
    assert list(result) == list(expected)
    for name, values in expected.items():
        assert result[name].dtype == values.dtype, name
        assert result[name].shape == values.shape, name
        if name == "rgb":  # compare bit patterns (NaN-safe)
            np.testing.assert_array_equal(result[name].view(np.uint32), values.view(np.uint32))
        else:
            np.testing.assert_array_equal(result[name], values, err_msg=name)


# --------------------------------------------------------------------------- LZF


def test_lzf_literal_and_overlapping_reference_tokens() -> None:
    # literal "abc"; length 6 at distance 3 (overlapping); length 3 at distance 1
    # (overlapping); length 4 at distance 9 (plain copy).
    stream = b"\x02abc" + bytes([4 << 5, 2]) + bytes([1 << 5, 0]) + bytes([2 << 5, 8])
    assert io.lzf_decompress(stream, 16) == b"abcabcabc" + b"ccc" + b"abca"


def test_lzf_long_reference_with_extra_length_byte() -> None:
    # literal "xy", then length 7+2+20 = 29 at distance 2.
    stream = b"\x01xy" + bytes([7 << 5, 20, 1])
    assert io.lzf_decompress(stream, 31) == b"xy" * 15 + b"x"


@pytest.mark.parametrize(
    "stream, size, message",
    [
        (b"\x05ab", 6, "truncated"),  # literal run longer than the input
        (b"\x00a" + bytes([1 << 5, 4]), 4, "before the start"),  # distance 5 > 1 byte out
        (b"\x02abc", 5, "expected 5"),  # too short
        (b"\x02abc", 2, "exceeds"),  # too long
        (b"\x00a" + bytes([7 << 5]), 20, "truncated"),  # missing length byte
    ],
)
def test_lzf_corrupt_streams(stream: bytes, size: int, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        io.lzf_decompress(stream, size)


def test_lzf_roundtrip_with_test_compressor() -> None:
    rng = np.random.default_rng(3)
    data = b"".join(
        [bytes(300), rng.integers(0, 256, 500, dtype=np.uint8).tobytes(), b"abcd" * 400,
         rng.integers(0, 4, 3000, dtype=np.uint8).tobytes(), bytes(9000), b"abcd" * 10]
    )
    packed, stats = lzf_compress(data)
    assert stats["refs"] > 50 and stats["overlapping"] > 0 and stats["long"] > 0
    assert len(packed) < len(data) // 2
    assert io.lzf_decompress(packed, len(data)) == data
    assert io.lzf_decompress(lzf_literals(data), len(data)) == data
    # any bytes-like stream is accepted
    assert io.lzf_decompress(bytearray(packed), len(data)) == data
    assert io.lzf_decompress(memoryview(packed), len(data)) == data


# --------------------------------------------------------------------------- PCD


@pytest.mark.parametrize("data", ["ascii", "binary", "binary_compressed"])
def test_pcd_roundtrip(tmp_path: Path, cloud_fields: dict[str, np.ndarray], data: str) -> None:
    path = tmp_path / f"cloud_{data}.pcd"
    write_pcd(path, cloud_fields, data)
    assert_fields_equal(io.read_pcd(path), cloud_fields)


def test_pcd_compressed_with_back_references(
    tmp_path: Path, cloud_fields: dict[str, np.ndarray]
) -> None:
    stats: dict[str, int] = {}

    def compress(raw: bytes) -> bytes:
        packed, counts = lzf_compress(raw)
        stats.update(counts)
        return packed

    path = tmp_path / "cloud.pcd"
    write_pcd(path, cloud_fields, "binary_compressed", compress=compress)
    assert stats["refs"] > 0 and stats["overlapping"] > 0 and stats["long"] > 0
    assert_fields_equal(io.read_pcd(path), cloud_fields)


def test_pcd_ascii_rgb_written_as_float(tmp_path: Path) -> None:
    colors = np.array([[255, 255, 255], [1, 2, 3], [0, 0, 0]])
    fields = {"x": np.zeros(3, np.float32), "y": np.ones(3, np.float32),
              "z": np.full(3, 2, np.float32), "rgb": pack_rgb(colors)}
    path = tmp_path / "rgb.pcd"
    write_pcd(path, fields, "ascii", ascii_rgb_as_int=False)
    np.testing.assert_array_equal(io.unpack_rgb(io.read_pcd(path)["rgb"]), colors)


def test_read_pcd_points_and_unpack_rgb(
    tmp_path: Path, cloud_fields: dict[str, np.ndarray]
) -> None:
    path = tmp_path / "cloud.pcd"
    write_pcd(path, cloud_fields, "binary")
    xyz = np.stack([cloud_fields[k] for k in "xyz"], axis=1)
    points = io.read_pcd_points(path)
    assert points.dtype == np.float64 and points.shape == (299, 3)
    np.testing.assert_array_equal(points, np.delete(xyz, 5, axis=0))
    raw = io.read_pcd_points(path, dtype=np.float32, remove_nan=False)
    assert raw.dtype == np.float32 and raw.shape == (300, 3) and np.isnan(raw[5]).all()

    colors = io.unpack_rgb(io.read_pcd(path)["rgb"])
    assert colors.dtype == np.uint8 and colors.shape == (300, 3)
    np.testing.assert_array_equal(colors[:100], np.tile([200, 10, 30], (100, 1)))
    # rgba stored as uint32 unpacks the same way, ignoring alpha.
    rgba = cloud_fields["rgb"].view(np.uint32) | np.uint32(0xFF000000)
    np.testing.assert_array_equal(io.unpack_rgb(rgba), colors)


def test_pcd_organised_cloud_and_padding(tmp_path: Path) -> None:
    fields = {"x": np.arange(6, dtype=np.float32), "y": np.zeros(6, np.float32),
              "z": np.ones(6, np.float32), "_": np.zeros(6, np.uint32)}
    path = tmp_path / "organised.pcd"
    write_pcd(path, fields, "binary", width=3)
    assert "HEIGHT 2" in path.read_text(errors="replace")
    result = io.read_pcd(path)
    assert list(result) == ["x", "y", "z"]
    np.testing.assert_array_equal(result["x"], np.arange(6))


def _corrupt(tmp_path: Path, cloud: dict[str, np.ndarray], data: str, edit) -> Path:
    path = tmp_path / "bad.pcd"
    write_pcd(path, cloud, data)
    path.write_bytes(edit(path.read_bytes()))
    return path


@pytest.mark.parametrize(
    "data, edit, message",
    [
        ("binary", lambda b: b[:-10], "truncated"),
        ("ascii", lambda b: b[: len(b) // 2], "truncated"),
        ("binary_compressed", lambda b: b[:-10], "truncated"),
        ("binary", lambda b: b.replace(b"DATA binary", b"DATA lzma"), "unknown PCD DATA type"),
        ("binary", lambda b: b.replace(b"POINTS 300", b"POINTS 301"), "WIDTH"),
        ("binary", lambda b: b.replace(b"TYPE F", b"TYPE Q"), "unsupported TYPE"),
        ("binary", lambda b: b.replace(b"COUNT 1 1", b"COUNT 1"), "lengths differ"),
        ("binary", lambda b: b[:150], "no DATA line"),
        ("ascii", lambda b: b[:-4] + b"zz\n", "field 'curvature'"),
    ],
)
def test_pcd_bad_files(tmp_path: Path, cloud_fields, data: str, edit, message: str) -> None:
    path = _corrupt(tmp_path, cloud_fields, data, edit)
    with pytest.raises(ValueError, match=message) as info:
        io.read_pcd(path)
    assert str(path) in str(info.value)


def test_pcd_compressed_size_mismatch_and_corrupt_stream(tmp_path: Path, cloud_fields) -> None:
    path = tmp_path / "bad.pcd"
    write_pcd(path, cloud_fields, "binary_compressed")
    raw = path.read_bytes()
    at = raw.index(b"DATA binary_compressed\n") + len(b"DATA binary_compressed\n")
    compressed, uncompressed = struct.unpack_from("<II", raw, at)
    wrong_size = raw[:at] + struct.pack("<II", compressed, uncompressed - 4) + raw[at + 8 :]
    path.write_bytes(wrong_size)
    with pytest.raises(ValueError, match="does not match"):
        io.read_pcd(path)
    # Replace the first literal run by a reference to before the start of the output.
    corrupt = bytearray(raw)
    corrupt[at + 8] = 0x20
    path.write_bytes(bytes(corrupt))
    with pytest.raises(ValueError, match="corrupt"):
        io.read_pcd(path)


def test_read_pcd_points_needs_xyz(tmp_path: Path) -> None:
    path = tmp_path / "intensity.pcd"
    write_pcd(path, {"intensity": np.ones(4, np.float32)}, "ascii")
    with pytest.raises(ValueError, match="x/y/z"):
        io.read_pcd_points(path)


# --------------------------------------------------------------------------- meshes


def off_text(header: str = "OFF") -> str:
    lines = [header, "# a cube", f"{len(CUBE_VERTICES)} {len(CUBE_QUADS)} 12"]
    for v in CUBE_VERTICES:
        extra = {"COFF": " 0.5 0.5 0.5 1", "NOFF": " 0 0 1", "OFF": ""}[header]
        lines.append(" ".join(f"{c:g}" for c in v) + extra + "  # vertex")
    for quad in CUBE_QUADS:
        lines.append(f"4 {' '.join(map(str, quad))}" + (" 255 0 0" if header == "COFF" else ""))
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("header", ["OFF", "COFF", "NOFF"])
def test_read_off_cube(tmp_path: Path, header: str) -> None:
    path = tmp_path / "cube.off"
    path.write_text(off_text(header))
    mesh = io.read_mesh(path)
    assert mesh.vertices.dtype == np.float64 and mesh.faces.dtype == np.int64
    np.testing.assert_array_equal(mesh.vertices, CUBE_VERTICES)
    np.testing.assert_array_equal(mesh.faces, CUBE_TRIANGLES)
    assert signed_volume(mesh) == pytest.approx(1.0)


def test_read_off_counts_on_header_line(tmp_path: Path) -> None:
    path = tmp_path / "tetra.off"
    faces = "\n".join(f"3 {a} {b} {c}" for a, b, c in TETRA_FACES)
    path.write_text("OFF 4 4 6\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n" + faces + "\n")
    mesh = io.read_mesh(path)
    np.testing.assert_array_equal(mesh.faces, TETRA_FACES)
    assert signed_volume(mesh) == pytest.approx(1 / 6)


@pytest.mark.parametrize(
    "text, message",
    [
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "out of range"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n", "at least 3"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n", "truncated"),
        ("OFF\n3 1 0\n0 0 0\n1 0\n0 1 0\n3 0 1 2\n", "fewer than 3"),
        ("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", "fewer than 4"),
        ("PLY\n3 1 0\n", "not an OFF file"),
        ("4OFF\n3 1 0\n", "only 3D"),
        ("", "empty"),
    ],
)
def test_read_off_bad(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.off"
    path.write_text(text)
    with pytest.raises(ValueError, match=message) as info:
        io.read_mesh(path)
    assert str(path) in str(info.value)


def ply_cube(fmt: str, index_name: str = "vertex_indices", triangles_only: bool = False) -> bytes:
    """A cube with extra vertex properties (incl. a list) and quads or triangles."""
    faces = CUBE_TRIANGLES.tolist() if triangles_only else [list(q) for q in CUBE_QUADS]
    header = (
        f"ply\nformat {fmt} 1.0\ncomment test cube\nobj_info nothing\n"
        f"element vertex {len(CUBE_VERTICES)}\n"
        "property double x\nproperty uchar flag\nproperty float y\n"
        "property list uchar short tags\nproperty float z\nproperty uchar red\n"
        f"element face {len(faces)}\n"
        f"property list uchar int {index_name}\nproperty float quality\n"
        "element edge 1\nproperty int vertex1\nproperty int vertex2\n"
        "end_header\n"
    )
    order = ">" if fmt == "binary_big_endian" else "<"
    body = bytearray()
    rows = []
    for i, (x, y, z) in enumerate(CUBE_VERTICES):
        tags = list(range(i % 3))  # lists of varying length
        if fmt == "ascii":
            rows.append(f"{x} 7 {y} {len(tags)} {' '.join(map(str, tags))} {z} 9")
        else:
            body += struct.pack(f"{order}dBfB{len(tags)}hfB", x, 7, y, len(tags), *tags, z, 9)
    for face in faces:
        if fmt == "ascii":
            rows.append(f"{len(face)} {' '.join(map(str, face))} 0.5")
        else:
            body += struct.pack(f"{order}B{len(face)}if", len(face), *face, 0.5)
    if fmt == "ascii":
        rows.append("0 1")
        return (header + "\n".join(rows) + "\n").encode()
    body += struct.pack(f"{order}ii", 0, 1)
    return header.encode() + bytes(body)


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
@pytest.mark.parametrize("triangles_only", [False, True])
def test_read_ply_cube(tmp_path: Path, fmt: str, triangles_only: bool) -> None:
    path = tmp_path / "cube.ply"
    path.write_bytes(ply_cube(fmt, triangles_only=triangles_only))
    mesh = io.read_mesh(path)
    np.testing.assert_array_equal(mesh.vertices, CUBE_VERTICES)
    np.testing.assert_array_equal(mesh.faces, CUBE_TRIANGLES)
    points = io.read_ply_points(path)
    assert set(points) == {"points"}  # red alone is not a colour triple
    np.testing.assert_array_equal(points["points"], CUBE_VERTICES)


def test_read_ply_vertex_index_name(tmp_path: Path) -> None:
    path = tmp_path / "cube.ply"
    path.write_bytes(ply_cube("binary_little_endian", index_name="vertex_index"))
    np.testing.assert_array_equal(io.read_mesh(path).faces, CUBE_TRIANGLES)


@pytest.mark.parametrize(
    "fmt, edit, message",
    [
        ("binary_little_endian", lambda b: b[:-12], "truncated"),
        ("binary_big_endian", lambda b: b[:-40], "truncated"),
        ("ascii", lambda b: b.rsplit(b"\n", 4)[0], "truncated"),
        ("ascii", lambda b: b.replace(b"4 0 3 2 1", b"4 0 3 2 8"), "out of range"),
        ("ascii", lambda b: b.replace(b"format ascii", b"format utf8"), "unsupported PLY format"),
        ("ascii", lambda b: b.replace(b"float z", b"half z"), "malformed PLY header"),
        ("ascii", lambda b: b.replace(b"ply\n", b"plx\n", 1), "not a PLY file"),
        ("ascii", lambda b: b.replace(b" 0.5", b" abc", 1), "malformed PLY element"),
    ],
)
def test_read_ply_bad(tmp_path: Path, fmt: str, edit, message: str) -> None:
    path = tmp_path / "bad.ply"
    path.write_bytes(edit(ply_cube(fmt)))
    with pytest.raises(ValueError, match=message) as info:
        io.read_mesh(path)
    assert str(path) in str(info.value)


def stl_ascii(vertices: np.ndarray, faces: np.ndarray) -> str:
    lines = ["solid tetra"]
    for face in faces:
        lines += ["  facet normal 0 0 0", "    outer loop"]
        lines += [f"      vertex {x:.6e} {y:.6e} {z:.6e}" for x, y, z in vertices[face]]
        lines += ["    endloop", "  endfacet"]
    return "\n".join(lines + ["endsolid tetra"]) + "\n"


def stl_binary(vertices: np.ndarray, faces: np.ndarray, header: bytes = b"binary") -> bytes:
    body = b"".join(
        struct.pack("<12fH", 0, 0, 0, *vertices[face].ravel(), 0) for face in faces
    )
    return header.ljust(80, b" ") + struct.pack("<I", len(faces)) + body


@pytest.mark.parametrize("kind", ["ascii", "binary", "binary_solid_header"])
def test_read_stl_merges_vertices(tmp_path: Path, kind: str) -> None:
    path = tmp_path / "tetra.stl"
    vertices = TETRA_VERTICES * 0.1  # not exactly representable: tests exact merging
    if kind == "ascii":
        path.write_text(stl_ascii(vertices, TETRA_FACES))
        expected_vertices = vertices
    else:
        header = b"solid but binary" if kind == "binary_solid_header" else b"binary"
        path.write_bytes(stl_binary(vertices, TETRA_FACES, header))
        expected_vertices = vertices.astype(np.float32).astype(np.float64)
    mesh = io.read_mesh(path)
    assert mesh.vertices.shape == (4, 3) and mesh.faces.shape == (4, 3)
    # Vertices come in order of first use; faces reference them with the same winding.
    np.testing.assert_array_equal(mesh.vertices, expected_vertices[[0, 2, 1, 3]])
    assert triangle_set(mesh.vertices, mesh.faces) == triangle_set(expected_vertices, TETRA_FACES)
    assert signed_volume(mesh) == pytest.approx(0.1**3 / 6)


@pytest.mark.parametrize(
    "content, message",
    [
        (b"\x00" * 100, "neither a binary STL"),
        (stl_ascii(TETRA_VERTICES, TETRA_FACES).encode()[:-40], "unbalanced"),
        (stl_ascii(TETRA_VERTICES, TETRA_FACES).replace("vertex 0.0", "vertex 0,0", 1).encode(),
         "malformed ASCII STL"),
    ],
)
def test_read_stl_bad(tmp_path: Path, content: bytes, message: str) -> None:
    path = tmp_path / "bad.stl"
    path.write_bytes(content)
    with pytest.raises(ValueError, match=message):
        io.read_mesh(path)


def test_read_obj_forms_and_negative_indices(tmp_path: Path) -> None:
    path = tmp_path / "cube.obj"
    lines = ["# cube", "mtllib none.mtl", "o cube"]
    lines += [f"v {x} {y} {z}" for x, y, z in CUBE_VERTICES]
    lines += ["vt 0 0", "vn 0 0 1", "g sides", "s off"]
    forms = ["{}", "{}/1", "{}/1/1", "{}//1"]
    for k, quad in enumerate(CUBE_QUADS):
        if k == 5:  # negative indices: -1 is the latest vertex
            corners = [str(i - len(CUBE_VERTICES)) for i in quad]
        else:
            corners = [forms[k % 4].format(i + 1) for i in quad]
        lines.append("f " + " ".join(corners))
    path.write_text("\n".join(lines) + "\n")
    mesh = io.read_mesh(path)
    np.testing.assert_array_equal(mesh.vertices, CUBE_VERTICES)
    np.testing.assert_array_equal(mesh.faces, CUBE_TRIANGLES)


@pytest.mark.parametrize(
    "text, message",
    [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "start at 1"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n", "out of range"),
        ("v 0 0\nf 1 1 1\n", "fewer than 3"),
        ("v 0 0 0\nv 1 0 0\nf 1 2\n", "at least 3"),
    ],
)
def test_read_obj_bad(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        io.read_mesh(path)


def test_read_mesh_unknown_extension(tmp_path: Path) -> None:
    path = tmp_path / "mesh.3ds"
    path.write_bytes(b"")
    with pytest.raises(ValueError, match="unsupported mesh extension"):
        io.read_mesh(path)


def test_mesh_validates() -> None:
    with pytest.raises(ValueError, match=r"\(F, 3\)"):
        io.Mesh(CUBE_VERTICES, np.array([[0, 1]]))
    with pytest.raises(ValueError, match="lie in"):
        io.Mesh(CUBE_VERTICES, np.array([[0, 1, 8]]))


# --------------------------------------------------------------------------- PLY points


@pytest.mark.parametrize("binary", [True, False])
def test_write_read_ply_roundtrip(tmp_path: Path, binary: bool) -> None:
    rng = np.random.default_rng(7)
    points = rng.normal(scale=3.0, size=(500, 3)).astype(np.float32)
    normals = rng.normal(size=(500, 3)).astype(np.float32)
    colors = rng.integers(0, 256, size=(500, 3), dtype=np.uint8)
    path = tmp_path / "cloud.ply"
    io.write_ply(path, points, normals=normals, colors=colors, binary=binary)

    header = path.read_bytes().split(b"end_header\n")[0].decode()
    assert header.startswith("ply\n")
    assert ("format binary_little_endian 1.0" if binary else "format ascii 1.0") in header
    expected_props = [f"property float {p}" for p in ("x", "y", "z", "nx", "ny", "nz")]
    expected_props += [f"property uchar {c}" for c in ("red", "green", "blue")]
    assert [ln for ln in header.splitlines() if ln.startswith("property")] == expected_props
    if binary:
        assert path.stat().st_size == len(header) + len("end_header\n") + 500 * 27

    result = io.read_ply_points(path)
    assert result["points"].dtype == np.float64
    np.testing.assert_array_equal(result["points"], points)
    np.testing.assert_array_equal(result["normals"], normals)
    np.testing.assert_array_equal(result["colors"], colors)
    mesh = io.read_mesh(path)
    assert mesh.faces.shape == (0, 3)
    np.testing.assert_array_equal(mesh.vertices, points)


def test_write_ply_points_only_and_float_colors(tmp_path: Path) -> None:
    path = tmp_path / "cloud.ply"
    io.write_ply(path, np.eye(3), colors=np.array([[0.0, 0.5, 1.0]] * 3))
    result = io.read_ply_points(path)
    assert set(result) == {"points", "colors"}
    np.testing.assert_array_equal(result["points"], np.eye(3))
    np.testing.assert_array_equal(result["colors"], [[0, 128, 255]] * 3)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"points": np.zeros((4, 2))}, "points"),
        ({"points": np.zeros((4, 3)), "normals": np.zeros((3, 3))}, "normals"),
        ({"points": np.zeros((4, 3)), "colors": np.full((4, 3), 1.5)}, r"\[0, 1\]"),
        ({"points": np.zeros((4, 3)), "colors": np.full((4, 3), 256)}, r"\[0, 255\]"),
    ],
)
def test_write_ply_rejects_bad_input(tmp_path: Path, kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        io.write_ply(tmp_path / "bad.ply", **kwargs)


def test_read_ply_points_needs_xyz(tmp_path: Path) -> None:
    path = tmp_path / "no_xyz.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 1\nproperty float a\nend_header\n1\n")
    with pytest.raises(ValueError, match="x, y, z"):
        io.read_ply_points(path)


@pytest.mark.parametrize("data", ["ascii", "binary", "binary_compressed"])
def test_pcd_header_claiming_more_data_than_the_file_holds(tmp_path: Path, data: str) -> None:
    # A trillion points: refused from the sizes alone (a clear error, not MemoryError).
    n = 10**12
    path = tmp_path / "huge.pcd"
    header = f"FIELDS x\nSIZE 4\nTYPE F\nWIDTH {n}\nPOINTS {n}\nDATA {data}\n".encode()
    payload = b"1.0\n" if data == "ascii" else bytes(4)
    if data == "binary_compressed":  # a consistent-looking size header over 4 bytes
        header = header.replace(str(n).encode(), b"1000000000")
        payload = struct.pack("<II", 4, 4_000_000_000) + b"\x02abc"
    path.write_bytes(header + payload)
    with pytest.raises(ValueError, match="truncated|cannot decompress") as info:
        io.read_pcd(path)
    assert str(path) in str(info.value)


def test_lzf_refuses_an_output_size_no_stream_of_that_length_reaches() -> None:
    with pytest.raises(ValueError, match="cannot decompress"):
        io.lzf_decompress(b"\x02abc", 1 << 40)
    with pytest.raises(ValueError, match="expected_size"):
        io.lzf_decompress(b"", -1)

"""atheris target: PCD files (ascii, binary, binary_compressed) through scanalign.io.read_pcd."""

from __future__ import annotations

import struct

import numpy as np

import _fuzzlib

with _fuzzlib.instrumented():
    from scanalign import io

XYZ = np.array([[0.0, 0.0, 0.0], [1.0, 0.5, -2.0], [np.nan, np.nan, np.nan], [3.25, -1.0, 0.125]], np.float32)


def header(data: str, points: int = 4, fields: str = "x y z rgb", sizes: str = "4 4 4 4", types: str = "F F F U",
           counts: str = "1 1 1 1") -> bytes:
    return (f"# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS {fields}\nSIZE {sizes}\nTYPE {types}\n"
            f"COUNT {counts}\nWIDTH 2\nHEIGHT {points // 2}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {points}\n"
            f"DATA {data}\n").encode()


def seeds() -> dict:
    rgb = np.array([0x00FF0000, 0x0000FF00, 0, 0x000000FF], np.uint32)
    records = b"".join(XYZ[i].tobytes() + rgb[i].tobytes() for i in range(4))
    blocks = XYZ[:, 0].tobytes() + XYZ[:, 1].tobytes() + XYZ[:, 2].tobytes() + rgb.tobytes()  # one block per field
    literal = b"".join(bytes([len(blocks[k:k + 32]) - 1]) + blocks[k:k + 32] for k in range(0, len(blocks), 32))
    ascii_rows = "".join(f"{x} {y} {z} {c}\n" for (x, y, z), c in zip(XYZ.tolist(), rgb.tolist()))
    return {
        "ascii.pcd": header("ascii") + ascii_rows.encode(),
        "binary.pcd": header("binary") + records,
        "compressed.pcd": header("binary_compressed") + struct.pack("<II", len(literal), len(blocks)) + literal,
        "normals.pcd": header("binary", 2, "x y z normal_x normal_y normal_z _", "8 8 8 4 4 4 1", "F F F F F F U",
                              "1 1 1 1 1 1 3") + (np.arange(3, dtype="<f8").tobytes() + np.ones(3, "<f4").tobytes()
                                                  + b"\0\0\0") * 2,
    }


def test_one_input(data: bytes) -> None:
    path = _fuzzlib.as_file(data, ".pcd")
    try:
        fields = io.read_pcd(path)
    except _fuzzlib.ALLOWED as e:
        _fuzzlib.outcome(f"{type(e).__name__}: {e}")
        return
    header_, columns = io._io.parse_pcd(data)
    _fuzzlib.outcome(f"ok {header_.data} {' '.join(f'{f.type}{f.size}' for f in header_.fields)}")
    assert header_.points == header_.width * header_.height >= 0, (header_.width, header_.height, header_.points)
    assert list(fields) == list(columns)
    for name, column in fields.items():
        assert column.shape[0] == header_.points, (name, column.shape, header_.points)
    if all(axis in fields for axis in "xyz"):
        if any(fields[axis].ndim != 1 for axis in "xyz"):  # COUNT > 1: not one coordinate per point
            try:
                io.read_pcd_points(path)
            except ValueError as e:
                assert "COUNT 1" in str(e) and str(path) in str(e), e
                _fuzzlib.outcome("coordinates with COUNT > 1")
                return
            raise AssertionError("read_pcd_points accepted a coordinate field with COUNT > 1")
        points = io.read_pcd_points(path)
        assert points.ndim == 2 and points.shape[1] == 3 and np.isfinite(points).all()


if __name__ == "__main__":
    _fuzzlib.run(test_one_input, seeds())

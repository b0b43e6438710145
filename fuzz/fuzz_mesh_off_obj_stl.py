"""atheris target: OFF, OBJ and STL meshes through scanalign.io.read_mesh (byte 0 picks the
format, the rest is the file)."""

from __future__ import annotations

import struct

import numpy as np

import _fuzzlib

with _fuzzlib.instrumented():
    from scanalign import io

FORMATS = (".off", ".obj", ".stl")
V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


def seeds() -> dict:
    off = "OFF\n# tetrahedron\n4 4 6\n" + "".join(f"{x} {y} {z}\n" for x, y, z in V) + "".join(
        f"3 {a} {b} {c}\n" for a, b, c in F)
    quad = "COFF\n4 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n1 1 0 0 0 255 255\n0 1 0 9 9 9 255\n4 0 1 2 3\n"
    obj = "# tetrahedron\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in V) + "vt 0 0\nvn 0 0 1\n" + \
        "f 1/1/1 3/1/1 2/1/1\nf 1//1 2//1 4//1\nf -4 -1 -2\nf 2 3 \\\n 4\n"
    stl_ascii = "solid tetra\n" + "".join(
        " facet normal 0 0 0\n  outer loop\n" + "".join(f"   vertex {x} {y} {z}\n" for x, y, z in V[f]) +
        "  endloop\n endfacet\n" for f in F) + "endsolid tetra\n"
    stl_binary = b"solid binary".ljust(80, b" ") + struct.pack("<I", len(F)) + b"".join(
        struct.pack("<12fH", 0, 0, 0, *V[f].ravel(), 0) for f in F)
    return {"tetra.off": b"\0" + off.encode(), "quad.off": b"\0" + quad.encode(), "tetra.obj": b"\1" + obj.encode(),
            "ascii.stl": b"\2" + stl_ascii.encode(), "binary.stl": b"\2" + stl_binary}


def test_one_input(data: bytes) -> None:
    if not data:
        return
    path = _fuzzlib.as_file(data[1:], FORMATS[data[0] % len(FORMATS)])
    try:
        mesh = io.read_mesh(path)
    except _fuzzlib.ALLOWED as e:
        _fuzzlib.outcome(f"{type(e).__name__}: {e}")
        return
    v, f = mesh.vertices, mesh.faces
    _fuzzlib.outcome(f"ok {path.suffix} {min(len(f), 8)}")
    assert v.ndim == 2 and v.shape[1] == 3 and v.dtype == np.float64 and np.isfinite(v).all()
    assert f.ndim == 2 and f.shape[1] == 3 and f.dtype == np.int64
    assert f.size == 0 or (f.min() >= 0 and f.max() < len(v))


if __name__ == "__main__":
    _fuzzlib.run(test_one_input, seeds())

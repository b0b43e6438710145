"""atheris target: PLY files (ascii, binary little and big endian) through scanalign.io.read_mesh
and scanalign.io.read_ply_points."""

from __future__ import annotations

import numpy as np

import _fuzzlib

with _fuzzlib.instrumented():
    from scanalign import io

V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.5]])


def header(fmt: str, faces: int = 2, extra: str = "") -> bytes:
    return (f"ply\nformat {fmt} 1.0\ncomment fuzz seed\nelement vertex 4\nproperty float x\nproperty float y\n"
            f"property float z\n{extra}element face {faces}\nproperty list uchar int vertex_indices\n"
            "end_header\n").encode()


def seeds() -> dict:
    ascii_body = "".join(f"{x} {y} {z}\n" for x, y, z in V) + "3 0 1 2\n4 0 1 2 3\n"
    coloured = "".join(f"{x} {y} {z} 10 20 30\n" for x, y, z in V) + "3 0 1 2\n3 0 2 3\n"
    out = {"ascii.ply": header("ascii") + ascii_body.encode(),
           "colour.ply": header("ascii", extra="property uchar red\nproperty uchar green\nproperty uchar blue\n")
           + coloured.encode()}
    for name, order in (("le", "<"), ("be", ">")):
        body = V.astype(f"{order}f4").tobytes() + b"\x03" + np.array([0, 1, 2], f"{order}i4").tobytes() + \
            b"\x03" + np.array([0, 2, 3], f"{order}i4").tobytes()
        out[f"{name}.ply"] = header(f"binary_{'little' if order == '<' else 'big'}_endian") + body
    return out


def test_one_input(data: bytes) -> None:
    path = _fuzzlib.as_file(data, ".ply")
    try:
        mesh = io.read_mesh(path)
    except _fuzzlib.ALLOWED as e:
        _fuzzlib.outcome(f"{type(e).__name__}: {e}")
        pass
    else:
        v, f = mesh.vertices, mesh.faces
        assert v.ndim == 2 and v.shape[1] == 3 and np.isfinite(v).all()
        assert f.ndim == 2 and f.shape[1] == 3 and (f.size == 0 or (f.min() >= 0 and f.max() < len(v)))
    try:
        cloud = io.read_ply_points(path)
    except _fuzzlib.ALLOWED as e:
        _fuzzlib.outcome(f"{type(e).__name__}: {e}")
        return
    n = len(cloud["points"])
    assert cloud["points"].shape == (n, 3) and cloud["points"].dtype == np.float64
    for key, dtype in (("normals", np.float64), ("colors", np.uint8)):
        assert key not in cloud or (cloud[key].shape == (n, 3) and cloud[key].dtype == dtype), key


if __name__ == "__main__":
    _fuzzlib.run(test_one_input, seeds())

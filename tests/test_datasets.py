"""Tests for scanalign.data.parts (mesh sampling, the built-in part) and scanalign.data.downloads (the
package cache)."""

from __future__ import annotations

import os
import shutil
import subprocess
import tarfile
from pathlib import Path

import numpy as np
import pytest

from scanalign import io
from scanalign.data import downloads as datasets
from scanalign.data import parts

# Unit cube [0, 1]^3 as 12 outward-facing triangles.
CUBE_VERTICES = np.array(
    [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
    dtype=np.float64,
)
CUBE_QUADS = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (2, 3, 7, 6), (0, 4, 7, 3), (1, 2, 6, 5)]
CUBE_FACES = np.array([t for a, b, c, d in CUBE_QUADS for t in ((a, b, c), (a, c, d))])


# --------------------------------------------------------------------------- sample_mesh


def test_sample_mesh_cube_on_surface_with_axis_normals() -> None:
    n = 60000
    points, normals = parts.sample_mesh((CUBE_VERTICES, CUBE_FACES), n, seed=3)
    assert points.shape == (n, 3) and normals.shape == (n, 3)
    assert points.min() >= 0.0 and points.max() <= 1.0
    # Every normal is +-e_k and the point lies on the matching face.
    axis = np.argmax(np.abs(normals), axis=1)
    sign = normals[np.arange(n), axis]
    np.testing.assert_array_equal(np.abs(sign), 1.0)
    np.testing.assert_array_equal(np.count_nonzero(normals, axis=1), 1)
    face_coord = np.where(sign > 0, 1.0, 0.0)
    np.testing.assert_allclose(points[np.arange(n), axis], face_coord, atol=1e-12)

    # Area-uniform: each of the 6 faces gets n/6 points (binomial, 5 sigma bound) ...
    face_id = 2 * axis + (sign > 0)
    counts = np.bincount(face_id, minlength=6)
    sigma = np.sqrt(n * (1 / 6) * (5 / 6))
    assert np.all(np.abs(counts - n / 6) < 5 * sigma), counts
    # ... and within a face, a 4x4 grid is filled evenly (chi-square test, 15 dof;
    # 45 is far beyond its 99.9% quantile of 37.7).  Sampling without the sqrt trick
    # piles points up at the first corner of each triangle and fails this.
    for f in range(6):
        on_face = points[face_id == f]
        in_plane = np.delete(on_face, f // 2, axis=1)
        cells = np.minimum((in_plane * 4).astype(int), 3)
        grid = np.bincount(cells[:, 0] * 4 + cells[:, 1], minlength=16)
        expected = len(on_face) / 16
        assert np.sum((grid - expected) ** 2 / expected) < 45.0, grid


def test_sample_mesh_skips_degenerate_faces_and_is_deterministic() -> None:
    vertices = np.vstack([CUBE_VERTICES, [[2.0, 2.0, 2.0], [3.0, 3.0, 3.0]]])
    faces = np.vstack([CUBE_FACES, [[8, 8, 9], [0, 8, 9]]])  # zero-area: repeated, collinear
    mesh = io.Mesh(vertices, faces)
    points, normals = parts.sample_mesh(mesh, 5000, seed=11)
    assert np.isfinite(normals).all()
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
    assert points.max() <= 1.0  # nothing on the degenerate faces out at (2..3)^3
    again, _ = parts.sample_mesh(mesh, 5000, seed=11)
    other, _ = parts.sample_mesh(mesh, 5000, seed=12)
    np.testing.assert_array_equal(points, again)
    assert not np.array_equal(points, other)


def test_sample_mesh_triangle_normal_follows_winding() -> None:
    triangle = (np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0]], float), np.array([[0, 2, 1]]))
    points, normals = parts.sample_mesh(triangle, 2000)
    np.testing.assert_array_equal(normals, np.tile([0.0, 0.0, -1.0], (2000, 1)))
    assert points[:, 2].max() == 0.0 and (points[:, 0] + points[:, 1]).max() <= 2.0 + 1e-12
    # Uniform: the half of the area farther than x + y = sqrt(2) from the corner at the
    # origin holds half the points (without the sqrt trick it would hold 29%).
    upper = np.count_nonzero(points[:, 0] + points[:, 1] > np.sqrt(2))
    assert abs(upper - 1000) < 5 * np.sqrt(500)


def test_sample_mesh_zero_area_raises() -> None:
    flat = (np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2]], float), np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="zero total area"):
        parts.sample_mesh(flat, 10)
    with pytest.raises(ValueError, match="zero total area"):
        parts.sample_mesh((CUBE_VERTICES, np.empty((0, 3), int)), 10)


# --------------------------------------------------------------------------- builtin_object

# The geometry documented in scanalign.data.parts' docstring (metres).
BOX_HALF = np.array([0.040, 0.025, 0.015])
TOP = 0.015
BOSS_XY, BOSS_R, BOSS_TOP = np.array([-0.015, 0.0]), 0.012, 0.030
CAP_CENTER, CAP_R = np.array([0.020, 0.006, 0.006]), 0.015
CAP_BASE_R = np.sqrt(CAP_R**2 - (TOP - CAP_CENTER[2]) ** 2)


def classify_builtin(points: np.ndarray, normals: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """Label each point with the surface part it lies on (normal must match); -1 = none.

    Labels: 0..5 box faces (-x, +x, -y, +y, -z, +z), 6 boss side, 7 boss top, 8 cap.
    """
    labels = np.full(len(points), -1)
    inside_box = np.all(np.abs(points) <= BOX_HALF + tol, axis=1)
    for axis in range(3):
        for side, sign in enumerate((-1.0, 1.0)):
            normal = np.zeros(3)
            normal[axis] = sign
            on = (
                inside_box
                & (np.abs(points[:, axis] - sign * BOX_HALF[axis]) < tol)
                & np.all(np.abs(normals - normal) < tol, axis=1)
            )
            if axis == 2 and sign > 0:  # top face: not under the boss or the cap
                on &= np.linalg.norm(points[:, :2] - BOSS_XY, axis=1) >= BOSS_R - tol
                on &= np.linalg.norm(points[:, :2] - CAP_CENTER[:2], axis=1) >= CAP_BASE_R - tol
            labels[on] = 2 * axis + side
    radial = points[:, :2] - BOSS_XY
    rho = np.linalg.norm(radial, axis=1)
    boss_side = (
        (np.abs(rho - BOSS_R) < tol)
        & (points[:, 2] >= TOP - tol)
        & (points[:, 2] <= BOSS_TOP + tol)
        & np.all(np.abs(normals[:, :2] - radial / BOSS_R) < 1e-6, axis=1)
        & (np.abs(normals[:, 2]) < tol)
    )
    labels[boss_side] = 6
    boss_top = (
        (np.abs(points[:, 2] - BOSS_TOP) < tol)
        & (rho <= BOSS_R + tol)
        & np.all(np.abs(normals - [0, 0, 1]) < tol, axis=1)
    )
    labels[boss_top] = 7
    offset = points - CAP_CENTER
    cap = (
        (np.abs(np.linalg.norm(offset, axis=1) - CAP_R) < tol)
        & (points[:, 2] >= TOP - tol)
        & np.all(np.abs(normals - offset / CAP_R) < 1e-6, axis=1)
    )
    labels[cap] = 8
    return labels


def test_builtin_object_lies_on_its_exposed_surface() -> None:
    n = 20000
    points, normals = parts.builtin_object(n, seed=5)
    assert points.shape == (n, 3) and normals.shape == (n, 3)
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-12)
    labels = classify_builtin(points, normals)
    assert np.all(labels >= 0), points[labels < 0][:5]

    # Uniform area density: each part gets its share of the points (5 sigma).
    areas = np.array(
        [4 * BOX_HALF[1] * BOX_HALF[2]] * 2
        + [4 * BOX_HALF[0] * BOX_HALF[2]] * 2
        + [4 * BOX_HALF[0] * BOX_HALF[1]]
        + [4 * BOX_HALF[0] * BOX_HALF[1] - np.pi * (BOSS_R**2 + CAP_BASE_R**2)]
        + [2 * np.pi * BOSS_R * (BOSS_TOP - TOP), np.pi * BOSS_R**2]
        + [2 * np.pi * CAP_R * (CAP_R - (TOP - CAP_CENTER[2]))]
    )
    p = areas / areas.sum()
    counts = np.bincount(labels, minlength=9)
    assert np.all(np.abs(counts - n * p) < 5 * np.sqrt(n * p * (1 - p))), (counts, n * p)

    # About 10 cm across: 80 x 50 x 45 mm bounding box.
    np.testing.assert_allclose(points.min(axis=0), [-0.040, -0.025, -0.015], atol=1e-3)
    np.testing.assert_allclose(points.max(axis=0), [0.040, 0.025, 0.030], atol=1e-3)


def test_builtin_object_constrains_point_to_plane_icp() -> None:
    points, normals = parts.builtin_object(5000)
    # Point-to-plane Jacobian rows [p x n, n]: full rank and well conditioned.
    jacobian = np.hstack([np.cross(points - points.mean(axis=0), normals) / 0.05, normals])
    singular = np.linalg.svd(jacobian, compute_uv=False)
    assert singular[-1] / singular[0] > 0.05, singular


def test_builtin_object_is_deterministic() -> None:
    a = parts.builtin_object(1000, seed=1)
    b = parts.builtin_object(1000, seed=1)
    c = parts.builtin_object(1000, seed=2)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert not np.array_equal(a[0], c[0])


# --------------------------------------------------------------------------- cache / fetch


def test_cache_dir_follows_environment(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("SCANALIGN_DATA", str(tmp_path))
    assert datasets.cache_dir() == tmp_path
    monkeypatch.delenv("SCANALIGN_DATA")
    assert datasets.cache_dir() == Path.home() / ".cache" / "scanalign"


def fake_apt_get(bin_dir: Path, calls: Path) -> None:
    """An ``apt-get`` that records its call and fails like one with stale package lists."""
    script = bin_dir / "apt-get"
    script.write_text(
        f"#!/bin/sh\necho \"$@\" >> {calls}\n"
        "echo 'E: Unable to locate package' >&2\nexit 100\n"
    )
    script.chmod(0o755)


def test_missing_apt_get_raises(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("SCANALIGN_DATA", str(tmp_path / "cache"))
    monkeypatch.delenv(datasets.OFFLINE_ENV, raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))  # nothing on PATH
    with pytest.raises(datasets.DatasetUnavailableError, match="apt-get update") as info:
        datasets.fetch_all()
    assert "not available" in str(info.value) and "libcgal-demo" in str(info.value)
    assert datasets.OFFLINE_ENV in str(info.value)  # how to supply the file by hand


def test_failing_apt_get_raises(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    calls = tmp_path / "calls.txt"
    fake_apt_get(tmp_path, calls)
    monkeypatch.setenv("SCANALIGN_DATA", str(tmp_path / "cache"))
    monkeypatch.delenv(datasets.OFFLINE_ENV, raising=False)
    monkeypatch.setenv("PATH", f"{tmp_path}{os.pathsep}{os.environ['PATH']}")
    with pytest.raises(datasets.DatasetUnavailableError, match="apt-get update") as info:
        datasets.fetch_all()
    assert "Unable to locate package" in str(info.value)
    # The pinned version is asked for, and nothing partial is left behind.
    assert calls.read_text().split() == ["download", "libcgal-demo=5.5.1-2"]
    assert not list((tmp_path / "cache" / "debs").iterdir())


def test_pinned_files_are_well_formed() -> None:
    assert set(datasets.PINNED_FILES) == {datasets.CGAL_PACKAGE, datasets.PCL_PACKAGE, datasets.SMALL_GICP}
    for pin in datasets.PINNED_FILES.values():
        assert len(pin.sha256) == 64 and int(pin.sha256, 16) >= 0
        assert pin.url.startswith("https://")
    for key in (datasets.CGAL_PACKAGE, datasets.PCL_PACKAGE):  # the Debian pool address of the pinned .deb
        pin = datasets.PINNED_FILES[key]
        assert pin.url.rsplit("/", 1)[1].replace("%7e", "~").replace("%2b", "+") == pin.filename
        assert pin.fetched_with.startswith(f"apt-get download {key}")


def make_deb(path: Path, package: str, files: dict) -> Path:
    """A tiny stand-in ``.deb`` of ``package`` holding ``files`` ({relative path: bytes})."""
    tree = path.parent / f"tree-{path.name}"
    (tree / "DEBIAN").mkdir(parents=True)
    (tree / "DEBIAN" / "control").write_text(
        f"Package: {package}\nVersion: 1.0\nArchitecture: all\n"
        "Maintainer: test <test@example.com>\nDescription: test package\n"
    )
    for name, data in files.items():
        (tree / name).parent.mkdir(parents=True, exist_ok=True)
        (tree / name).write_bytes(data)
    path.parent.mkdir(parents=True, exist_ok=True)
    subprocess.run(["dpkg-deb", "--root-owner-group", "--build", str(tree), str(path)],
                   check=True, capture_output=True)
    shutil.rmtree(tree)
    return path


TINY_PCD = (b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 1\n"
            b"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n0 0 0\nnan nan nan\n0.1 0.2 0.3\n")


def pin(monkeypatch: pytest.MonkeyPatch, key: str, path: Path) -> None:
    """Pins ``path`` (name and sha256) as the file of ``key``."""
    old = datasets.PINNED_FILES[key]
    monkeypatch.setitem(datasets.PINNED_FILES, key, datasets.PinnedFile(
        path.name, datasets.sha256_file(path), old.url, old.fetched_with))


@pytest.fixture
def fake_pcl_deb(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> Path:
    """A pinned stand-in for python3-pcl holding one cloud (outside the cache), an empty
    cache, no offline folder, and an ``apt-get`` that records calls and fails."""
    if shutil.which("dpkg-deb") is None:
        pytest.skip("needs dpkg-deb")
    deb = make_deb(tmp_path / "files" / "python3-pcl_1.0_all.deb", "python3-pcl",
                   {"usr/share/doc/python3-pcl/examples/tutorials/tiny.pcd": TINY_PCD})
    pin(monkeypatch, datasets.PCL_PACKAGE, deb)
    fake_apt_get(tmp_path, tmp_path / "calls.txt")
    monkeypatch.setenv("SCANALIGN_DATA", str(tmp_path / "cache"))
    monkeypatch.delenv(datasets.OFFLINE_ENV, raising=False)
    monkeypatch.setenv("PATH", f"{tmp_path}{os.pathsep}{os.environ['PATH']}")
    return deb


def test_cached_deb_is_reused(fake_pcl_deb: Path, tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    (cache / "debs").mkdir(parents=True)
    shutil.copy(fake_pcl_deb, cache / "debs")

    assert datasets.pcl_cloud_names() == ["tiny"]
    path = datasets.pcl_cloud_path("tiny")
    assert path.is_relative_to(cache / "packages" / "python3-pcl")
    expected = np.array([[0, 0, 0], [0.1, 0.2, 0.3]], dtype=np.float32)
    np.testing.assert_array_equal(datasets.load_pcl_cloud("tiny"), expected)
    assert not (tmp_path / "calls.txt").exists()  # apt-get was never needed
    with pytest.raises(ValueError, match="did you mean tiny"):
        datasets.pcl_cloud_path("tiyn")
    # The unpacked tree records the .deb it came from.
    marker = cache / "packages" / "python3-pcl" / ".complete"
    assert marker.read_text().strip() == datasets.sha256_file(fake_pcl_deb)


def test_missing_dataset_names_the_fetch_command(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """No loader downloads: each raises an error naming the fetch command and the offline
    folder, and runs no subprocess (no apt-get, no pip)."""
    monkeypatch.setenv("SCANALIGN_DATA", str(tmp_path / "cache"))
    monkeypatch.delenv(datasets.OFFLINE_ENV, raising=False)

    def no_subprocess(*args, **kwargs):
        raise AssertionError(f"a loader ran {args}")

    monkeypatch.setattr(datasets.subprocess, "run", no_subprocess)
    for load, pinned in ((lambda: datasets.load_cgal_mesh("fandisk"), datasets.CGAL_PACKAGE),
                         (datasets.cgal_mesh_names, datasets.CGAL_PACKAGE),
                         (lambda: datasets.load_pcl_cloud("milk"), datasets.PCL_PACKAGE),
                         (datasets.pcl_cloud_names, datasets.PCL_PACKAGE),
                         (datasets.small_gicp_lidar_pair, datasets.SMALL_GICP)):
        with pytest.raises(datasets.DatasetUnavailableError) as info:
            load()
        message = str(info.value)
        assert "`python -m scanalign.data fetch`" in message
        assert datasets.PINNED_FILES[pinned].filename in message and datasets.OFFLINE_ENV in message
        assert datasets.PINNED_FILES[pinned].sha256 in message and datasets.PINNED_FILES[pinned].url in message
    assert not (tmp_path / "cache" / "debs").exists() or not list((tmp_path / "cache" / "debs").iterdir())


def test_corrupted_cached_deb_is_detected(fake_pcl_deb: Path, tmp_path: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    cached = tmp_path / "cache" / "debs" / fake_pcl_deb.name
    cached.parent.mkdir(parents=True)
    cgal = shutil.copy(fake_pcl_deb, cached.parent / "libcgal-demo_1.0_all.deb")  # a good CGAL stand-in
    pin(monkeypatch, datasets.CGAL_PACKAGE, Path(cgal))
    data = bytearray(fake_pcl_deb.read_bytes())
    data[len(data) // 2] ^= 0xFF
    cached.write_bytes(bytes(data))
    expected, actual = datasets.sha256_file(fake_pcl_deb), datasets.sha256_file(cached)
    for call in (datasets.pcl_cloud_names, datasets.fetch_all):
        with pytest.raises(datasets.DatasetIntegrityError) as info:
            call()
        message = str(info.value)
        assert str(cached) in message and expected in message and actual in message
        assert "`python -m scanalign.data fetch`" in message
    assert not (tmp_path / "cache" / "packages" / "python3-pcl").exists()  # nothing unpacked from it

    # A good copy unpacks; `fetch` checks the cached .deb again even then.
    shutil.copy(fake_pcl_deb, cached)
    assert datasets.pcl_cloud_names() == ["tiny"]
    cached.write_bytes(bytes(data))
    with pytest.raises(datasets.DatasetIntegrityError, match=actual):
        datasets.fetch_all()


def test_mismatching_download_is_not_kept(fake_pcl_deb: Path, tmp_path: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """An apt-get that 'downloads' another file under the pinned name: refused, not cached."""
    calls = tmp_path / "calls.txt"
    cgal = datasets.PINNED_FILES[datasets.CGAL_PACKAGE].filename
    script = tmp_path / "apt-get"  # CGAL's stand-in is fine, python3-pcl's is not
    script.write_text(f"#!/bin/sh\necho \"$@\" >> {calls}\n"
                      f"case \"$2\" in python3-pcl*) echo other > '{fake_pcl_deb.name}';; "
                      f"*) cp '{fake_pcl_deb}' '{cgal}';; esac\n")
    script.chmod(0o755)
    monkeypatch.setitem(datasets.PINNED_FILES, datasets.CGAL_PACKAGE, datasets.PinnedFile(
        cgal, datasets.sha256_file(fake_pcl_deb), "https://example.org/cgal.deb", "apt-get download libcgal-demo"))
    with pytest.raises(datasets.DatasetIntegrityError) as info:
        datasets.fetch_all()
    message = str(info.value)
    assert "as downloaded by `apt-get download python3-pcl" in message
    assert datasets.sha256_file(fake_pcl_deb) in message
    assert len(calls.read_text().splitlines()) == 2
    assert (tmp_path / "cache" / "debs" / cgal).exists()
    assert not (tmp_path / "cache" / "debs" / fake_pcl_deb.name).exists()
    assert sorted(p.name for p in (tmp_path / "cache" / "debs").iterdir()) == [cgal]  # no scratch left


def test_offline_folder_is_used(fake_pcl_deb: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    offline = tmp_path / "offline"
    offline.mkdir()
    shutil.copy(fake_pcl_deb, offline)
    monkeypatch.setenv(datasets.OFFLINE_ENV, str(offline))
    # A loader copies the verified file into the cache; apt-get is never run.
    np.testing.assert_array_equal(datasets.load_pcl_cloud("tiny"), np.float32([[0, 0, 0], [0.1, 0.2, 0.3]]))
    assert (tmp_path / "cache" / "debs" / fake_pcl_deb.name).read_bytes() == fake_pcl_deb.read_bytes()
    assert not (tmp_path / "calls.txt").exists()

    # A corrupt file in the offline folder is refused, naming it.
    monkeypatch.setenv("SCANALIGN_DATA", str(tmp_path / "cache2"))
    (offline / fake_pcl_deb.name).write_bytes(b"not a deb")
    with pytest.raises(datasets.DatasetIntegrityError) as info:
        datasets.pcl_cloud_names()
    assert str(offline / fake_pcl_deb.name) in str(info.value)
    assert datasets.sha256_file(fake_pcl_deb) in str(info.value)
    assert not (tmp_path / "cache2" / "debs" / fake_pcl_deb.name).exists()


def test_missing_offline_folder_is_an_error(monkeypatch: pytest.MonkeyPatch, tmp_path: Path,
                                            capsys: pytest.CaptureFixture) -> None:
    # A mistyped $SCANALIGN_OFFLINE_DATA is named, with its path, before any download is tried.
    missing = tmp_path / "media" / "usb" / "scanalign-data"
    monkeypatch.setenv(datasets.OFFLINE_ENV, str(missing))
    monkeypatch.setenv("SCANALIGN_DATA", str(tmp_path / "cache"))
    monkeypatch.setattr(datasets.subprocess, "run", lambda *a, **k: pytest.fail(f"ran {a[0]}"))
    for fetch in (datasets.fetch_all, datasets.fetch_small_gicp):
        with pytest.raises(datasets.DatasetUnavailableError, match="not a folder") as info:
            fetch()
        assert datasets.OFFLINE_ENV in str(info.value) and str(missing) in str(info.value)
    assert datasets.main(["fetch"]) == 1
    assert f"{datasets.OFFLINE_ENV} is '{missing}', which is not a folder" in capsys.readouterr().err
    (tmp_path / "file").write_text("")  # a file is not a folder either
    monkeypatch.setenv(datasets.OFFLINE_ENV, str(tmp_path / "file"))
    with pytest.raises(datasets.DatasetUnavailableError, match="not a folder"):
        datasets.offline_dir()


def make_small_gicp_sdist(path: Path) -> Path:
    """A stand-in small_gicp sdist with a 3-point LiDAR pair and its pose."""
    root = path.parent / "sdist-tree" / "small_gicp-1.0.1" / "data"
    root.mkdir(parents=True)
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    io.write_ply(root / "source.ply", pts)
    io.write_ply(root / "target.ply", pts + 1.0)
    np.savetxt(root / "T_target_source.txt", np.eye(4))
    with tarfile.open(path, "w:gz") as tar:
        tar.add(root.parent, arcname="small_gicp-1.0.1")
    return path


def test_small_gicp_sdist_offline_and_corrupted(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    offline = tmp_path / "offline"
    offline.mkdir()
    sdist = make_small_gicp_sdist(offline / datasets.SMALL_GICP_SDIST)
    pin(monkeypatch, datasets.SMALL_GICP, sdist)
    monkeypatch.setenv("SCANALIGN_DATA", str(tmp_path / "cache"))
    monkeypatch.setenv(datasets.OFFLINE_ENV, str(offline))
    monkeypatch.setattr(datasets, "_pip_download", lambda scratch: pytest.fail("pip was run"))
    source, target, T = datasets.fetch_small_gicp() and datasets.small_gicp_lidar_pair()
    assert source.shape == (3, 3) and np.array_equal(T, np.eye(4))
    np.testing.assert_array_equal(target, source + 1.0)
    cached = tmp_path / "cache" / "sdists" / datasets.SMALL_GICP_SDIST
    assert cached.exists()
    # A corrupted cached sdist: `fetch` names it with both hashes.
    cached.write_bytes(cached.read_bytes()[:-10])
    with pytest.raises(datasets.DatasetIntegrityError) as info:
        datasets.fetch_small_gicp()
    assert str(cached) in str(info.value) and datasets.sha256_file(sdist) in str(info.value)
    assert datasets.sha256_file(cached) in str(info.value)


def test_fetch_command_reports_a_mismatch(fake_pcl_deb: Path, tmp_path: Path,
                                          capsys: pytest.CaptureFixture) -> None:
    cached = tmp_path / "cache" / "debs" / datasets.PINNED_FILES[datasets.CGAL_PACKAGE].filename
    cached.parent.mkdir(parents=True)
    cached.write_bytes(b"corrupt")
    assert datasets.main(["fetch"]) == 1
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "sha256 mismatch" in err and str(cached) in err


# --------------------------------------------------------------------------- real data


def pcd_header_points(path: Path) -> int:
    with open(path, "rb") as fh:
        for line in fh:
            if line.startswith(b"POINTS"):
                return int(line.split()[1])
    raise AssertionError(f"{path} has no POINTS line")


@pytest.mark.data
def test_pcl_bun0(dataset_cache: Path) -> None:
    path = datasets.pcl_cloud_path("bun0")
    assert path.is_relative_to(dataset_cache)
    points = datasets.load_pcl_cloud("bun0")
    assert points.dtype == np.float64 and points.shape == (pcd_header_points(path), 3)
    assert points.shape[0] == 112586
    # Despite its name, python3-pcl's bun0.pcd is not the Stanford bunny but an indoor
    # lidar scan (scan rings around the sensor at the origin), roughly 29 x 14 x 3 m.
    extent = np.ptp(points, axis=0)
    assert np.all((extent > [20, 10, 2]) & (extent < [40, 20, 5])), extent


@pytest.mark.data
def test_pcl_milk(dataset_cache: Path) -> None:
    path = datasets.pcl_cloud_path("milk")
    fields = io.read_pcd(path)
    assert set(fields) == {"x", "y", "z", "rgba"}
    points = datasets.load_pcl_cloud("milk")
    assert np.isfinite(points).all()
    assert 0 < len(points) <= pcd_header_points(path) == 12575
    # A milk carton: a 10-30 cm object about 0.6-0.9 m from the camera.
    assert np.all((np.ptp(points, axis=0) > 0.1) & (np.ptp(points, axis=0) < 0.3))
    assert 0.5 < np.linalg.norm(points.mean(axis=0)) < 1.0
    assert sorted(datasets.pcl_cloud_names())[:3] == ["bun0", "lamppost", "milk"]


@pytest.mark.data
def test_cgal_fandisk(dataset_cache: Path) -> None:
    names = datasets.cgal_mesh_names()
    for expected in ("bunny00", "fandisk", "rotor", "pinion", "anchor", "joint",
                     "couplingdown", "part", "spool"):
        assert expected in names
    path = datasets.cgal_mesh_path("fandisk")
    header = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")][:2]
    n_vertices, n_faces, _ = map(int, header[1].split())
    mesh = datasets.load_cgal_mesh("fandisk")
    assert mesh.vertices.shape == (n_vertices, 3) and mesh.faces.shape == (n_faces, 3)
    assert mesh.faces.min() >= 0 and mesh.faces.max() < n_vertices
    # A closed, consistently oriented surface: every directed edge appears once and its
    # reverse appears too; the enclosed volume is positive (outward normals).
    edges = mesh.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    directed = {tuple(e) for e in edges.tolist()}
    assert len(directed) == len(edges)
    assert all((b, a) in directed for a, b in directed)
    a, b, c = (mesh.vertices[mesh.faces[:, k]] for k in range(3))
    assert np.einsum("ij,ij->", a, np.cross(b, c)) / 6 > 0
    # Sampling the CAD surface works end to end.
    points, normals = parts.sample_mesh(mesh, 1000)
    assert points.shape == (1000, 3)
    assert np.all(points >= mesh.vertices.min(axis=0) - 1e-12)
    assert np.all(points <= mesh.vertices.max(axis=0) + 1e-12)


@pytest.mark.data
def test_small_gicp_lidar_pair() -> None:
    try:
        datasets.fetch_small_gicp()  # explicit: the loader itself never downloads
        source, target, T = datasets.small_gicp_lidar_pair()
    except datasets.DatasetUnavailableError as exc:
        if os.environ.get("CI") or os.environ.get("SCANALIGN_REQUIRE_DATA"):
            pytest.fail(f"test data unavailable: {exc}")
        pytest.skip(f"test data unavailable: {exc}")
    assert (datasets.cache_dir() / "sdists" / datasets.SMALL_GICP_SDIST).exists()
    assert source.dtype == target.dtype == T.dtype == np.float64
    assert source.shape == (69792, 3) and target.shape == (69088, 3)
    assert np.isfinite(source).all() and np.isfinite(target).all()
    # Outdoor LiDAR scans in metres: tens of metres across.
    assert np.all((np.ptp(source, axis=0) > [20, 20, 5]) & (np.ptp(source, axis=0) < [100, 100, 30]))
    # The reference pose is rigid: a rotation and a translation of about half a metre.
    assert T.shape == (4, 4)
    np.testing.assert_array_equal(T[3], [0, 0, 0, 1])
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
    assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(T[:3, 3], [0.488882, 0.121214, -0.0253342], atol=1e-6)
    # ... and it aligns the pair better than identity does.
    from scipy.spatial import cKDTree

    tree = cKDTree(target)
    before = np.median(tree.query(source)[0])
    after = np.median(tree.query(source @ T[:3, :3].T + T[:3, 3])[0])
    assert after < 0.9 * before, (before, after)
    # A second call reads the cache (no pip): same arrays.
    again = datasets.small_gicp_lidar_pair()
    np.testing.assert_array_equal(again[0], source)
    np.testing.assert_array_equal(again[2], T)

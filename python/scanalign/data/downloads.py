"""Test data: real scans and CAD meshes from Debian packages and PyPI, downloaded once and cached.

The cache is ``$SCANALIGN_DATA`` if set, else ``~/.cache/scanalign``: ``debs/`` and ``sdists/``
(the pinned files), ``packages/<package>/`` (``.deb`` files unpacked with ``dpkg-deb -x``),
``cgal_meshes/`` and ``small_gicp_data/`` (files taken from the archives on first use).

- ``libcgal-demo``: about 140 CGAL example meshes (``fandisk``, ``bunny00``, ``rotor``, ...), in
  arbitrary units (mostly about 1 unit across);
- ``python3-pcl``: PCL tutorial clouds (``table_scene_lms400``, ``milk``, ``bun0``, ...), in metres;
- PyPI: :func:`small_gicp_lidar_pair`, from the ``small_gicp`` 1.0.1 source distribution.

Only ``python -m scanalign.data fetch`` (:func:`fetch_all`, :func:`fetch_small_gicp`) downloads
(``apt-get download``, ``pip download``); a loader whose file is missing raises
:class:`DatasetUnavailableError` naming that command. Every file of :data:`PINNED_FILES` is
checked against its sha256 after a download, when taken from the offline folder
(``$SCANALIGN_OFFLINE_DATA``, or dropped into ``debs/`` / ``sdists/``), when unpacked and on
every ``fetch``; a mismatch raises :class:`DatasetIntegrityError` naming the file and both
hashes. See docs/testing.md.
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import hashlib
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from scanalign import io

__all__ = ["CGAL_PACKAGE", "FETCH_COMMAND", "OFFLINE_ENV", "PCL_PACKAGE", "PINNED_FILES", "SMALL_GICP",
           "DatasetIntegrityError", "DatasetUnavailableError", "PinnedFile", "cache_dir", "cgal_mesh_names",
           "cgal_mesh_path", "fetch_all", "fetch_small_gicp", "load_cgal_mesh", "load_pcl_cloud", "offline_dir",
           "pcl_cloud_names", "pcl_cloud_path", "sha256_file", "small_gicp_lidar_pair", "verify_file"]

CGAL_PACKAGE = "libcgal-demo"
PCL_PACKAGE = "python3-pcl"

_CGAL_TARBALL = "usr/share/doc/libcgal-dev/data.tar.gz"
_CGAL_MESH_PREFIX = "data/meshes/"
_MESH_EXTENSIONS = (".off", ".ply", ".stl", ".obj")  # preference order for bare names
_PCL_EXAMPLES = "usr/share/doc/python3-pcl/examples"
_COMPLETE_MARKER = ".complete"
_SMALL_GICP_DATA = ("source.ply", "target.ply", "T_target_source.txt")

SMALL_GICP = "small_gicp"
FETCH_COMMAND = "python -m scanalign.data fetch"
OFFLINE_ENV = "SCANALIGN_OFFLINE_DATA"


@dataclasses.dataclass(frozen=True)
class PinnedFile:
    """One file the data comes from: its name, its sha256, where it is published and how
    ``fetch`` downloads it."""

    filename: str
    sha256: str
    url: str
    fetched_with: str


# Every downloaded file, pinned. The .deb hashes equal Debian bookworm's package index
# (``apt-cache show PACKAGE=VERSION``); the sdist's is that of small_gicp 1.0.1 on PyPI.
PINNED_FILES: dict[str, PinnedFile] = {
    CGAL_PACKAGE: PinnedFile(
        "libcgal-demo_5.5.1-2_all.deb", "78b09b23d4d6d1bf15552a1060b419ab3fc09918486462faed197e5fc6ac3735",
        "https://deb.debian.org/debian/pool/main/c/cgal/libcgal-demo_5.5.1-2_all.deb",
        "apt-get download libcgal-demo=5.5.1-2"),
    PCL_PACKAGE: PinnedFile(
        "python3-pcl_0.3.0~rc1+dfsg-14+b2_amd64.deb",
        "64de9bb742996e7c8a55c0cb22422dacbf69c003894cc98d33f601c4e486667e",
        "https://deb.debian.org/debian/pool/main/p/python-pcl/python3-pcl_0.3.0%7erc1%2bdfsg-14%2bb2_amd64.deb",
        "apt-get download python3-pcl:amd64=0.3.0~rc1+dfsg-14+b2"),  # data only: amd64's on every machine
    SMALL_GICP: PinnedFile(
        "small_gicp-1.0.1.tar.gz", "e0b1a03a87da154b53b489cce7079b5be02ba17723f89c4161f8311b564ca0b1",
        "https://pypi.org/project/small-gicp/1.0.1/#files",
        "pip download --no-deps --no-binary :all: small_gicp==1.0.1"),
}
SMALL_GICP_SDIST = PINNED_FILES[SMALL_GICP].filename


class DatasetUnavailableError(RuntimeError):
    """The data is not in the cache, or could not be fetched (no ``apt-get``, no network,
    stale package lists)."""


class DatasetIntegrityError(DatasetUnavailableError):
    """A data file's sha256 differs from the one pinned in :data:`PINNED_FILES`."""


def cache_dir() -> Path:
    """The data cache: ``$SCANALIGN_DATA`` if set, else ``~/.cache/scanalign``."""
    env = os.environ.get("SCANALIGN_DATA")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "scanalign"


def offline_dir() -> Path | None:
    """The folder of pinned files supplied by hand, ``$SCANALIGN_OFFLINE_DATA``, or None. Set to
    something that is not a folder, it is an error: a mistyped path would otherwise send ``fetch``
    to the network (or fail offline) without a word about the folder."""
    if not (env := os.environ.get(OFFLINE_ENV)):
        return None
    if not (path := Path(env).expanduser()).is_dir():
        raise DatasetUnavailableError(f"${OFFLINE_ENV} is {env!r}, which is not a folder: put the pinned files "
                                      f"into an existing folder and name it there, or unset {OFFLINE_ENV}")
    return path


def sha256_file(path: Path) -> str:
    """The sha256 of a file, hex."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def verify_file(path: Path, key: str, what: str | None = None, advice: str | None = None) -> Path:
    """Checks ``path`` against the sha256 pinned for ``key`` (a :data:`PINNED_FILES` key);
    returns it, or raises DatasetIntegrityError naming the file (``what``, default the
    path), the expected and the actual hash."""
    pin = PINNED_FILES[key]
    actual = sha256_file(path)
    if actual != pin.sha256:
        advice = advice or f"a corrupt or different file: delete it and run `{FETCH_COMMAND}`"
        raise DatasetIntegrityError(f"{what or path}: sha256 mismatch: expected {pin.sha256}, got {actual} "
                                    f"({advice}; the pinned file is {pin.url})")
    return path


def _offline_hint(key: str) -> str:
    pin, offline = PINNED_FILES[key], offline_dir()
    where = f"${OFFLINE_ENV} ({offline})" if offline else f"a folder named by ${OFFLINE_ENV}"
    return f"put {pin.filename} (from {pin.url}, sha256 {pin.sha256}) into {where} or {_folder(key)}"


def _how_to_supply(key: str) -> str:
    return f"run `{FETCH_COMMAND}` (it runs `{PINNED_FILES[key].fetched_with}`), or, offline, {_offline_hint(key)}"


def _folder(key: str) -> Path:
    """Where the cache keeps the pinned file of ``key``."""
    return cache_dir() / ("sdists" if key == SMALL_GICP else "debs")


def _pinned_file(key: str, download: bool) -> Path:
    """The pinned file of ``key`` in the cache, verified. Absent: copied (verified) from the
    offline folder if it is there, else (``download``) fetched, else DatasetUnavailableError."""
    pin, folder = PINNED_FILES[key], _folder(key)
    target = folder / pin.filename
    if target.exists():
        return verify_file(target, key)
    supplied = offline_dir() / pin.filename if offline_dir() else None
    if not download and not (supplied and supplied.exists()):
        raise DatasetUnavailableError(f"{pin.filename} ({key} test data) is not in the data cache {cache_dir()}; "
                                      f"{_how_to_supply(key)}")
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=folder) as scratch:
        # Copy or download into a scratch folder so that only a verified, whole file lands.
        if supplied is not None and supplied.exists():
            verify_file(supplied, key, advice="a corrupt or different file in the offline folder: replace it")
            fetched = Path(scratch) / pin.filename
            shutil.copyfile(supplied, fetched)
            verify_file(fetched, key, f"{pin.filename} copied from {supplied}", "the copy failed: try again")
        else:
            fetched = (_pip_download(Path(scratch)) if key == SMALL_GICP
                       else _run(pin.fetched_with.split(), Path(scratch), key, pin.filename))
            verify_file(fetched, key, f"{pin.filename} as downloaded by `{pin.fetched_with}`",
                        "the download was not kept: a corrupt download or a mirror serving another file")
        os.replace(fetched, target)
    return target


def _run(command: list[str], cwd: Path, package: str, produces: str = "") -> Path:
    """Runs a packaging command in ``cwd``, turning every failure (and no file ``produces``
    left in ``cwd``) into DatasetUnavailableError; returns ``cwd / produces``."""
    manual = f"run `sudo apt-get update` first, then {_how_to_supply(package)}"
    if shutil.which(command[0]) is None:
        raise DatasetUnavailableError(f"`{command[0]}` is not available, so {package} cannot be fetched. On a "
                                      f"Debian/Ubuntu machine, {manual}.")
    try:
        subprocess.run(command, cwd=cwd, check=True, capture_output=True, text=True)
    except subprocess.CalledProcessError as exc:
        detail = (exc.stderr or exc.stdout or "").strip().splitlines()[-3:]
        raise DatasetUnavailableError(f"`{' '.join(command)}` failed (exit {exc.returncode}): "
                                      f"{' | '.join(detail)}. To fix, {manual}.") from exc
    if produces and not (cwd / produces).exists():
        raise DatasetUnavailableError(f"`{' '.join(command)}` produced no {produces}; {_how_to_supply(package)}")
    return cwd / produces


def _unpacked(root: Path, key: str, download: bool) -> bool:
    """Whether ``root`` holds what was unpacked from the pinned file of ``key``: its marker
    holds that file's sha256 (a tree unpacked from another file is unpacked again)."""
    marker, expected = root / _COMPLETE_MARKER, PINNED_FILES[key].sha256
    if not marker.exists():
        return False
    recorded = marker.read_text().strip()
    cached = _folder(key) / PINNED_FILES[key].filename
    if recorded == expected:
        if download and cached.exists():
            verify_file(cached, key)  # ``fetch`` checks the cached file again
        return True
    if not recorded and cached.exists():
        # Unpacked by an older scanalign (empty marker): kept if its file is the pinned one.
        verify_file(cached, key)
        marker.write_text(expected + "\n")
        return True
    return False


def _unpack(key: str, root: Path, download: bool, unpack: Callable[[Path, Path], object]) -> Path:
    """``root``, holding what ``unpack(pinned file, folder)`` takes from the verified pinned
    file of ``key`` and a marker with that file's sha256 (see :func:`_unpacked`)."""
    if _unpacked(root, key, download):
        return root
    pinned = _pinned_file(key, download)
    root.parent.mkdir(parents=True, exist_ok=True)
    # Unpack beside the target and rename, so a crash never leaves a half tree behind.
    scratch = Path(tempfile.mkdtemp(prefix=f".{key}-", dir=root.parent))
    try:
        unpack(pinned, scratch)
        (scratch / _COMPLETE_MARKER).write_text(PINNED_FILES[key].sha256 + "\n")
        shutil.rmtree(root, ignore_errors=True)  # left by an interrupted older version
        try:
            os.replace(scratch, root)
        except OSError:
            if not (root / _COMPLETE_MARKER).exists():  # else another process finished first
                raise
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return root


def _package_root(package: str, download: bool = False) -> Path:
    """The unpacked package tree (``dpkg-deb -x``) of the verified pinned ``.deb``."""
    return _unpack(package, cache_dir() / "packages" / package, download,
                   lambda deb, into: _run(["dpkg-deb", "-x", str(deb), str(into)], into.parent, package))


def _write_atomic(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with io.atomic_open(path, "wb") as fh:
        fh.write(data)


def _extract(tarball: Path, members: dict[str, Path]) -> None:
    """Writes the regular files ``members`` (name in the .tar.gz -> target) of ``tarball``,
    each atomically, reading the archive once and only as far as needed."""
    left = dict(members)
    try:
        with tarfile.open(tarball, "r|gz") as tar:
            for member in tar:
                if member.name in left and member.isfile():
                    _write_atomic(left.pop(member.name), tar.extractfile(member).read())
                    if not left:
                        return
    except (tarfile.TarError, OSError, EOFError) as exc:  # cannot happen with the pinned hash
        raise DatasetUnavailableError(f"{tarball} is not a readable tarball ({exc}); delete {cache_dir()}") from exc
    raise DatasetUnavailableError(f"{tarball} has no {', '.join(left)}; delete {cache_dir()}")


def fetch_all() -> list[Path]:
    """Downloads (or takes from the offline folder) and unpacks both Debian packages, each
    ``.deb`` verified (also when already cached); returns the unpacked package folders.
    Raises DatasetUnavailableError when ``apt-get``/``dpkg-deb`` are missing or fail, or
    ``$SCANALIGN_OFFLINE_DATA`` names no folder; DatasetIntegrityError on a hash mismatch."""
    offline_dir()  # checked even when everything is cached
    return [_package_root(CGAL_PACKAGE, download=True), _package_root(PCL_PACKAGE, download=True)]


def _unknown(kind: str, name: str, known: Sequence[str], lister: str) -> ValueError:
    close = difflib.get_close_matches(name, known, n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    return ValueError(f"unknown {kind} {name!r}{hint} (see {lister}())")


def _cgal_tar_members() -> list[str]:
    """File names (with extension) of the meshes in CGAL's data tarball."""
    names_file = cache_dir() / "cgal_meshes" / "index.txt"
    if names_file.exists():
        return names_file.read_text().split("\n")
    tarball = _package_root(CGAL_PACKAGE) / _CGAL_TARBALL
    with tarfile.open(tarball, "r:gz") as tar:
        names = sorted(name for m in tar.getmembers() if m.isfile() and m.name.startswith(_CGAL_MESH_PREFIX)
                       and "/" not in (name := m.name[len(_CGAL_MESH_PREFIX):])
                       and Path(name).suffix.lower() in _MESH_EXTENSIONS)
    _write_atomic(names_file, "\n".join(names).encode())
    return names


def cgal_mesh_names() -> list[str]:
    """Names of CGAL's example meshes, without extension (e.g. ``"fandisk"``), from the
    fetched ``libcgal-demo``. A few exist in several formats (``sphere`` as .off, .ply
    and .stl): the bare name means the ``.off`` one, the others are reachable with their
    extension through :func:`cgal_mesh_path`."""
    return sorted({Path(name).stem for name in _cgal_tar_members()})


def cgal_mesh_path(name: str) -> Path:
    """The cached file of a CGAL example mesh, extracted from the package on first use.
    ``name``: without extension (``"fandisk"``, ``"bunny00"``), or with one to pick a format
    (``"pig.stl"``). Raises ValueError for an unknown name, DatasetUnavailableError (naming
    the fetch command) when the package has not been fetched."""
    members = _cgal_tar_members()
    filename = next((name + ext for ext in ("",) + _MESH_EXTENSIONS if name + ext in members), None)
    if filename is None:
        raise _unknown("CGAL mesh", name, cgal_mesh_names(), "cgal_mesh_names")
    target = cache_dir() / "cgal_meshes" / filename
    if not target.exists():
        _extract(_package_root(CGAL_PACKAGE) / _CGAL_TARBALL, {_CGAL_MESH_PREFIX + filename: target})
    return target


def load_cgal_mesh(name: str) -> io.Mesh:
    """A CGAL example mesh (``name`` as for :func:`cgal_mesh_path`), triangulated, in the
    file's own unit (mostly about one unit across; not metres)."""
    return io.read_mesh(cgal_mesh_path(name))


def _pcl_clouds() -> dict[str, Path]:
    root = _package_root(PCL_PACKAGE) / _PCL_EXAMPLES
    return {path.stem: path for path in sorted(root.rglob("*.pcd"))}


def pcl_cloud_names() -> list[str]:
    """Names of the PCL tutorial clouds (``"table_scene_lms400"``, ``"milk"``, ...), from
    the fetched ``python3-pcl``."""
    return sorted(_pcl_clouds())


def pcl_cloud_path(name: str) -> Path:
    """Path of the PCL tutorial cloud ``name`` (without extension: ``"bun0"``, ``"milk"``,
    ...). Raises ValueError for an unknown name, DatasetUnavailableError (naming the fetch
    command) when the package has not been fetched."""
    clouds = _pcl_clouds()
    if name not in clouds:
        raise _unknown("PCL cloud", name, list(clouds), "pcl_cloud_names")
    return clouds[name]


def load_pcl_cloud(name: str) -> np.ndarray:
    """The finite ``x y z`` points of a PCL tutorial cloud, ``(N, 3)`` float64 metres (NaN
    points removed). PCL's names are not always descriptive: ``bun0`` is an indoor lidar
    scan about 29 m across, not the Stanford bunny."""
    return io.read_pcd_points(pcl_cloud_path(name), dtype=np.float64, remove_nan=True)


def _pip_download(scratch: Path) -> Path:
    """small_gicp's source distribution from PyPI with ``pip download`` (no build, no install)."""
    command = PINNED_FILES[SMALL_GICP].fetched_with
    base = [sys.executable, "-m", *command.split(), "--disable-pip-version-check"]
    errors = []
    # pip prepares the sdist's metadata even for a download; --no-build-isolation does
    # that with the scikit-build-core already installed (no extra download). Without it
    # in the environment, the second try lets pip fetch the build backend itself.
    for extra in (["--no-build-isolation"], []):
        try:
            subprocess.run(base + extra + ["-d", str(scratch)], check=True, capture_output=True, text=True,
                           timeout=600)
        except subprocess.TimeoutExpired:
            errors.append("pip download timed out")
        except subprocess.CalledProcessError as exc:
            detail = (exc.stderr or exc.stdout or "").strip().splitlines()[-2:]
            errors.append(f"exit {exc.returncode}: {' | '.join(detail)}")
        else:
            if (scratch / SMALL_GICP_SDIST).exists():
                return scratch / SMALL_GICP_SDIST
            errors.append(f"pip saved no {SMALL_GICP_SDIST}")
    raise DatasetUnavailableError(f"`{command}` (source distribution) failed: "
                                  f"{'; '.join(errors)}. To fix, check network access to PyPI, or, offline, "
                                  f"{_offline_hint(SMALL_GICP)}")


def _small_gicp_data_dir(download: bool = False) -> Path:
    """``<cache>/small_gicp_data`` holding small_gicp's ``data/`` LiDAR pair, unpacked from
    the verified sdist."""
    prefix = SMALL_GICP_SDIST[: -len(".tar.gz")] + "/data/"
    return _unpack(SMALL_GICP, cache_dir() / "small_gicp_data", download,
                   lambda sdist, into: _extract(sdist, {prefix + name: into / name for name in _SMALL_GICP_DATA}))


def fetch_small_gicp() -> Path:
    """As :func:`fetch_all`, for small_gicp's sdist (with ``pip download``); returns
    ``<cache>/small_gicp_data``, where its LiDAR pair is unpacked."""
    offline_dir()
    return _small_gicp_data_dir(download=True)


def small_gicp_lidar_pair() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The outdoor LiDAR scan pair of small_gicp's examples, with its reference pose:
    ``(source (N, 3), target (M, 3), T_target_source (4, 4))``, float64, metres.

    Two downsampled outdoor LiDAR scans (about 70k points each, about 60 x 40 x 12 m) and the
    pose shipped with them in the ``small_gicp`` 1.0.1 sdist (``data/``), stored with 6
    significant digits: its rotation is projected onto the nearest rotation matrix (a change
    below 1e-6), so the result is exactly rigid. Raises DatasetUnavailableError (naming the
    fetch command) when the sdist has not been fetched."""
    root = _small_gicp_data_dir()
    source, target = (io.read_ply_points(root / f"{name}.ply")["points"] for name in ("source", "target"))
    T = np.loadtxt(root / "T_target_source.txt", dtype=np.float64).reshape(4, 4)
    u, _, vt = np.linalg.svd(T[:3, :3])
    T[:3, :3] = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
    T[3] = (0.0, 0.0, 0.0, 1.0)
    return source, target, T


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m scanalign.data {fetch,list}``."""
    parser = argparse.ArgumentParser(prog="python -m scanalign.data", description=__doc__)
    parser.add_argument("command", choices=["fetch", "list"], help="download data / list names")
    args = parser.parse_args(argv)
    try:
        if args.command == "fetch":
            for root in fetch_all():
                print(f"ready: {root}")
            print(f"ready: {fetch_small_gicp()}")
            print("sha256 verified: " + ", ".join(pin.filename for pin in PINNED_FILES.values()))
        else:
            print("CGAL meshes:", " ".join(cgal_mesh_names()))
            print("PCL clouds:", " ".join(pcl_cloud_names()))
            print("small_gicp LiDAR pair: small_gicp_lidar_pair()")
    except DatasetUnavailableError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Test data: real scans and CAD meshes downloaded from Debian packages and PyPI, and cached.

Debian packages are fetched with ``apt-get download`` (no root needed, nothing installed) and
unpacked with ``dpkg-deb -x`` into the cache, ``$SCANALIGN_DATA`` if set, else
``~/.cache/scanalign``: ``<cache>/debs/`` (the .deb files, downloaded once),
``<cache>/packages/<package>/usr/...`` (unpacked) and ``<cache>/cgal_meshes/`` (meshes taken
from CGAL's data.tar.gz the first time each is asked for).

- ``libcgal-demo``: CGAL's example data, whose ``data/meshes/`` holds about 140 meshes
  (``fandisk``, ``bunny00``, ``rotor``, ``pinion``, ``anchor``, ``joint``, ``couplingdown``,
  ``part``, ``spool``, ...), in arbitrary units (mostly about 1 unit across).
- ``python3-pcl``: PCL tutorial clouds (``table_scene_lms400``, ``milk``, ``bun0``, ...), in metres.
- PyPI: :func:`small_gicp_lidar_pair`, the outdoor LiDAR pair with its reference pose shipped
  in the ``small_gicp`` 1.0.1 source distribution (``pip download`` into ``<cache>/sdists/``,
  its ``data/`` unpacked into ``<cache>/small_gicp_data/``).

``python -m scanalign.datasets fetch`` downloads everything ahead of time. The built-in part
and mesh sampling live in :mod:`scanalign.parts` (no download).
"""

from __future__ import annotations

import argparse
import difflib
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path
from typing import Sequence

import numpy as np

from scanalign import io

__all__ = ["CGAL_PACKAGE", "PCL_PACKAGE", "DatasetUnavailableError", "cache_dir", "cgal_mesh_names", "cgal_mesh_path",
           "fetch_all", "load_cgal_mesh", "load_pcl_cloud", "pcl_cloud_names", "pcl_cloud_path",
           "small_gicp_lidar_pair"]

CGAL_PACKAGE = "libcgal-demo"
PCL_PACKAGE = "python3-pcl"

_CGAL_TARBALL = "usr/share/doc/libcgal-dev/data.tar.gz"
_CGAL_MESH_PREFIX = "data/meshes/"
_MESH_EXTENSIONS = (".off", ".ply", ".stl", ".obj")  # preference order for bare names
_PCL_EXAMPLES = "usr/share/doc/python3-pcl/examples"
_COMPLETE_MARKER = ".complete"


class DatasetUnavailableError(RuntimeError):
    """The data could not be fetched (no ``apt-get``, no network, stale package lists)."""


def cache_dir() -> Path:
    """The data cache: ``$SCANALIGN_DATA`` if set, else ``~/.cache/scanalign``."""
    env = os.environ.get("SCANALIGN_DATA")
    return Path(env).expanduser() if env else Path.home() / ".cache" / "scanalign"


# --------------------------------------------------------------------------- packages


def _run(command: list[str], cwd: Path, package: str) -> None:
    """Run a packaging command, turning every failure into DatasetUnavailableError."""
    debs = cache_dir() / "debs"
    manual = (f"run `sudo apt-get update` first, then `python -m scanalign.datasets fetch` "
              f"(or `apt-get download {package}` in {debs})")
    if shutil.which(command[0]) is None:
        raise DatasetUnavailableError(f"`{command[0]}` is not available, so {package} cannot be fetched. On a "
                                      f"Debian/Ubuntu machine, {manual}; elsewhere, copy {package}'s .deb file "
                                      f"into {debs}.")
    try:
        subprocess.run(command, cwd=cwd, check=True, capture_output=True, text=True)
    except subprocess.CalledProcessError as exc:
        detail = (exc.stderr or exc.stdout or "").strip().splitlines()[-3:]
        raise DatasetUnavailableError(f"`{' '.join(command)}` failed (exit {exc.returncode}): "
                                      f"{' | '.join(detail)}. To fix, {manual}.") from exc


def _deb_file(package: str) -> Path:
    """The package's ``.deb`` in the cache, downloaded with ``apt-get download`` if absent."""
    debs = cache_dir() / "debs"
    debs.mkdir(parents=True, exist_ok=True)
    existing = sorted(debs.glob(f"{package}_*.deb"))
    if existing:
        return existing[-1]
    # Download into a scratch folder so an interrupted download leaves no partial .deb.
    with tempfile.TemporaryDirectory(dir=debs) as scratch:
        _run(["apt-get", "download", package], Path(scratch), package)
        downloaded = sorted(Path(scratch).glob(f"{package}_*.deb"))
        if not downloaded:
            raise DatasetUnavailableError(f"`apt-get download {package}` produced no {package}_*.deb; "
                                          f"run `sudo apt-get update` first.")
        target = debs / downloaded[-1].name
        os.replace(downloaded[-1], target)
    return target


def _package_root(package: str) -> Path:
    """The unpacked package tree (``dpkg-deb -x``), fetching the ``.deb`` if needed."""
    root = cache_dir() / "packages" / package
    marker = root / _COMPLETE_MARKER
    if marker.exists():
        return root
    deb = _deb_file(package)
    root.parent.mkdir(parents=True, exist_ok=True)
    # Unpack beside the target and rename, so a crash never leaves a half tree behind.
    scratch = Path(tempfile.mkdtemp(prefix=f".{package}-", dir=root.parent))
    try:
        _run(["dpkg-deb", "-x", str(deb), str(scratch)], root.parent, package)
        (scratch / _COMPLETE_MARKER).touch()
        shutil.rmtree(root, ignore_errors=True)  # left by an interrupted older version
        try:
            os.replace(scratch, root)
        except OSError:
            if not marker.exists():  # else another process finished first
                raise
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return root


def _write_atomic(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with io.atomic_open(path, "wb") as fh:
        fh.write(data)


def fetch_all() -> list[Path]:
    """Downloads and unpacks both data packages (idempotent); returns the unpacked package
    folders (``libcgal-demo``, ``python3-pcl``). Raises DatasetUnavailableError when
    ``apt-get``/``dpkg-deb`` are missing or fail."""
    return [_package_root(CGAL_PACKAGE), _package_root(PCL_PACKAGE)]


def _unknown(kind: str, name: str, known: Sequence[str], lister: str) -> ValueError:
    close = difflib.get_close_matches(name, known, n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    return ValueError(f"unknown {kind} {name!r}{hint} (see {lister}())")


# --------------------------------------------------------------------------- CGAL meshes


def _cgal_tar_members() -> list[str]:
    """File names (with extension) of the meshes in CGAL's data tarball."""
    names_file = cache_dir() / "cgal_meshes" / "index.txt"
    if names_file.exists():
        return names_file.read_text().split("\n")
    tarball = _package_root(CGAL_PACKAGE) / _CGAL_TARBALL
    with tarfile.open(tarball, "r:gz") as tar:
        names = sorted(m.name[len(_CGAL_MESH_PREFIX):] for m in tar.getmembers()
                       if m.isfile() and m.name.startswith(_CGAL_MESH_PREFIX)
                       and "/" not in m.name[len(_CGAL_MESH_PREFIX):] and Path(m.name).suffix.lower() in _MESH_EXTENSIONS)
    _write_atomic(names_file, "\n".join(names).encode())
    return names


def cgal_mesh_names() -> list[str]:
    """Names of CGAL's example meshes, without extension (e.g. ``"fandisk"``); downloads
    ``libcgal-demo`` on first use. A few exist in several formats (``sphere`` as .off, .ply
    and .stl): the bare name means the ``.off`` one, the others are reachable with their
    extension through :func:`cgal_mesh_path`."""
    return sorted({Path(name).stem for name in _cgal_tar_members()})


def cgal_mesh_path(name: str) -> Path:
    """The cached file of a CGAL example mesh, extracted from the package on first use.

    ``name``: without extension (``"fandisk"``, ``"bunny00"``), or with one to pick a format
    (``"pig.stl"``). Raises ValueError for an unknown name, DatasetUnavailableError when the
    package cannot be fetched.
    """
    members = _cgal_tar_members()
    candidates = [name + ext for ext in ("",) + _MESH_EXTENSIONS if name + ext in members]
    if not candidates:
        raise _unknown("CGAL mesh", name, cgal_mesh_names(), "cgal_mesh_names")
    filename = candidates[0]
    target = cache_dir() / "cgal_meshes" / filename
    if target.exists():
        return target
    tarball = _package_root(CGAL_PACKAGE) / _CGAL_TARBALL
    wanted = _CGAL_MESH_PREFIX + filename
    with tarfile.open(tarball, "r|gz") as tar:  # stream: stop at the member we want
        for member in tar:
            if member.name == wanted:
                source = tar.extractfile(member)
                assert source is not None  # members were filtered to regular files
                _write_atomic(target, source.read())
                return target
    raise DatasetUnavailableError(f"{tarball} has no member {wanted}; delete {cache_dir()}")


def load_cgal_mesh(name: str) -> io.Mesh:
    """A CGAL example mesh (``name`` as for :func:`cgal_mesh_path`), triangulated, in the
    file's own unit (mostly about one unit across; not metres)."""
    return io.read_mesh(cgal_mesh_path(name))


# --------------------------------------------------------------------------- PCL clouds


def _pcl_clouds() -> dict[str, Path]:
    root = _package_root(PCL_PACKAGE) / _PCL_EXAMPLES
    return {path.stem: path for path in sorted(root.rglob("*.pcd"))}


def pcl_cloud_names() -> list[str]:
    """Names of the PCL tutorial clouds (``"table_scene_lms400"``, ``"milk"``, ...);
    downloads ``python3-pcl`` on first use."""
    return sorted(_pcl_clouds())


def pcl_cloud_path(name: str) -> Path:
    """Path of the PCL tutorial cloud ``name`` (without extension: ``"bun0"``, ``"milk"``,
    ...), fetching the package on first use. Raises ValueError for an unknown name,
    DatasetUnavailableError when the package cannot be fetched."""
    clouds = _pcl_clouds()
    if name not in clouds:
        raise _unknown("PCL cloud", name, list(clouds), "pcl_cloud_names")
    return clouds[name]


def load_pcl_cloud(name: str) -> np.ndarray:
    """The finite ``x y z`` points of a PCL tutorial cloud, ``(N, 3)`` float64 metres (NaN
    points removed). PCL's names are not always descriptive: ``bun0`` is an indoor lidar
    scan about 29 m across, not the Stanford bunny."""
    return io.read_pcd_points(pcl_cloud_path(name), dtype=np.float64, remove_nan=True)


# --------------------------------------------------------------------------- small_gicp LiDAR pair

SMALL_GICP_SDIST = "small_gicp-1.0.1.tar.gz"
_SMALL_GICP_REQUIREMENT = "small_gicp==1.0.1"
_SMALL_GICP_DATA = ("source.ply", "target.ply", "T_target_source.txt")


def _small_gicp_sdist() -> Path:
    """small_gicp's source distribution in ``<cache>/sdists``, fetched from PyPI with
    ``pip download`` (no build, no install) if absent."""
    sdists = cache_dir() / "sdists"
    target = sdists / SMALL_GICP_SDIST
    if target.exists():
        return target
    sdists.mkdir(parents=True, exist_ok=True)
    manual = (f"download {SMALL_GICP_SDIST} from https://pypi.org/project/small-gicp/1.0.1/#files "
              f"into {sdists}")
    base = [sys.executable, "-m", "pip", "download", "--no-deps", "--no-binary", ":all:", "--disable-pip-version-check",
            _SMALL_GICP_REQUIREMENT]
    errors = []
    # pip prepares the sdist's metadata even for a download; --no-build-isolation does
    # that with the scikit-build-core already installed (no extra download). Without it
    # in the environment, the second try lets pip fetch the build backend itself.
    for extra in (["--no-build-isolation"], []):
        with tempfile.TemporaryDirectory(dir=sdists) as scratch:
            try:
                subprocess.run(base + extra + ["-d", scratch], check=True, capture_output=True, text=True,
                               timeout=600)
            except subprocess.TimeoutExpired:
                errors.append("pip download timed out")
            except subprocess.CalledProcessError as exc:
                detail = (exc.stderr or exc.stdout or "").strip().splitlines()[-2:]
                errors.append(f"exit {exc.returncode}: {' | '.join(detail)}")
            else:
                if (Path(scratch) / SMALL_GICP_SDIST).exists():
                    os.replace(Path(scratch) / SMALL_GICP_SDIST, target)
                    return target
                errors.append(f"pip saved no {SMALL_GICP_SDIST}")
    raise DatasetUnavailableError(f"`pip download {_SMALL_GICP_REQUIREMENT}` (source distribution) failed: "
                                  f"{'; '.join(errors)}. To fix, check network access to PyPI, or {manual}.")


def _small_gicp_data_dir() -> Path:
    """``<cache>/small_gicp_data`` holding small_gicp's ``data/`` LiDAR pair."""
    root = cache_dir() / "small_gicp_data"
    if (root / _COMPLETE_MARKER).exists():
        return root
    sdist = _small_gicp_sdist()
    prefix = SMALL_GICP_SDIST[: -len(".tar.gz")] + "/data/"
    found = {}
    try:
        with tarfile.open(sdist, "r:gz") as tar:
            for member in tar:
                name = member.name[len(prefix):] if member.name.startswith(prefix) else None
                if name in _SMALL_GICP_DATA and member.isfile():
                    source = tar.extractfile(member)
                    assert source is not None
                    found[name] = source.read()
    except (tarfile.TarError, OSError, EOFError) as exc:
        sdist.unlink(missing_ok=True)  # a corrupt download: fetch again next time
        raise DatasetUnavailableError(f"{sdist} is not a readable tarball ({exc}); it was deleted, try again")
    missing = [name for name in _SMALL_GICP_DATA if name not in found]
    if missing:
        raise DatasetUnavailableError(f"{sdist} has no {', '.join(prefix + m for m in missing)}")
    for name, data in found.items():
        _write_atomic(root / name, data)
    (root / _COMPLETE_MARKER).touch()
    return root


def small_gicp_lidar_pair() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The outdoor LiDAR scan pair of small_gicp's examples, with its reference pose:
    ``(source (N, 3), target (M, 3), T_target_source (4, 4))``, float64, metres.

    Two downsampled outdoor LiDAR scans (about 70k points each, about 60 x 40 x 12 m) and the
    ``T_target_source`` shipped with them in the ``small_gicp`` 1.0.1 source distribution on
    PyPI (``data/source.ply``, ``data/target.ply``, ``data/T_target_source.txt``), fetched once
    with ``pip download --no-deps --no-binary :all:`` into ``<cache>/sdists/`` (nothing is
    built or installed), its ``data/`` unpacked into ``<cache>/small_gicp_data/``. The file
    stores the pose with 6 significant digits; its rotation is projected onto the nearest
    rotation matrix (a change below 1e-6), so the result is exactly rigid. Raises
    DatasetUnavailableError when pip cannot download the sdist (no network, no PyPI).
    """
    root = _small_gicp_data_dir()
    source = io.read_ply_points(root / "source.ply")["points"]
    target = io.read_ply_points(root / "target.ply")["points"]
    T = np.loadtxt(root / "T_target_source.txt", dtype=np.float64).reshape(4, 4)
    u, _, vt = np.linalg.svd(T[:3, :3])
    T[:3, :3] = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
    T[3] = (0.0, 0.0, 0.0, 1.0)
    return source, target, T


# --------------------------------------------------------------------------- command line


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m scanalign.datasets {fetch,list}``."""
    parser = argparse.ArgumentParser(prog="python -m scanalign.datasets", description=__doc__)
    parser.add_argument("command", choices=["fetch", "list"], help="download data / list names")
    args = parser.parse_args(argv)
    try:
        if args.command == "fetch":
            for root in fetch_all():
                print(f"ready: {root}")
            print(f"ready: {_small_gicp_data_dir()}")
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

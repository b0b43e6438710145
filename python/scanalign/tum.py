"""Real RGB-D sequences in the TUM RGB-D benchmark folder layout.

A sequence folder (e.g. ``rgbd_dataset_freiburg1_xyz`` as downloaded from the TUM RGB-D
benchmark) holds::

    depth.txt          # lines "timestamp filename" (s, path relative to the folder)
    depth/*.png        # 16-bit single-channel PNG, depth (z) in units of depth_scale m
    rgb.txt            # optional; same line format
    rgb/*.png          # 8-bit colour images registered to the depth images
    groundtruth.txt    # optional; TUM trajectory "timestamp tx ty tz qx qy qz qw"
    camera.json        # optional camera file (or camera.yaml / intrinsics.json|yaml)

Lines starting with ``#`` and blank lines in the lists are skipped; commas and tabs count
as separators (as in the benchmark's ``associate.py``).  TUM depth images store 5000
units per metre (``depth_scale = 1/5000`` m per unit, 0 = no measurement).

Ground truth poses are ``T_world_camera`` of the benchmark's motion-capture world frame
(4x4, metres, mapping camera coordinates into world coordinates); they are handed out as
:attr:`scanalign.camera.Frame.T_base_camera`, i.e. the motion-capture world plays the
part of the robot's base frame.

:class:`TumSequence` reads such a folder lazily (PNGs are decoded when a frame is
requested) and :func:`write_tum_sequence` writes frames into the same layout, so
synthetic data can be stored and replayed like a real recording.  Images go through
Pillow, camera files through PyYAML / json.
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path
from typing import Any, Dict, Iterable, Iterator, List, Optional, Tuple, Union

import numpy as np
import yaml
from PIL import Image

from .camera import INTRINSICS_PRESETS, Frame, Intrinsics
from .trajectory import Trajectory, associate_timestamps, read_tum_trajectory, write_tum_trajectory

__all__ = [
    "TumSequence",
    "TumFormatError",
    "write_tum_sequence",
    "is_tum_folder",
    "read_timestamp_list",
    "TUM_DEPTH_SCALE",
    "CAMERA_FILE_NAMES",
]

#: Metres per unit of a TUM depth PNG (the benchmark stores 5000 units per metre).
TUM_DEPTH_SCALE = 1.0 / 5000.0

#: Camera files looked for in a sequence folder, in this order.  At most one may exist.
CAMERA_FILE_NAMES = ("camera.json", "camera.yaml", "camera.yml", "intrinsics.json", "intrinsics.yaml",
                     "intrinsics.yml")

PathLike = Union[str, "os.PathLike[str]"]


class TumFormatError(ValueError):
    """A sequence folder or one of its files does not follow the TUM layout.

    Attributes:
        path: the offending file (or folder), or None.
        line: 1-based line number in ``path`` where applicable, else None.
    """

    def __init__(self, message: str, path: Optional[PathLike] = None, line: Optional[int] = None) -> None:
        where = ""
        if path is not None:
            where = f"{os.fspath(path)}:{line}: " if line is not None else f"{os.fspath(path)}: "
        super().__init__(where + message)
        self.path = None if path is None else os.fspath(path)
        self.line = line


def _is_number(v: Any) -> bool:
    """A finite real number (not a bool)."""
    return (not isinstance(v, (bool, np.bool_)) and isinstance(v, (int, float, np.integer, np.floating))
            and math.isfinite(float(v)))


# --------------------------------------------------------------------------- lists


def read_timestamp_list(path: PathLike) -> Tuple[np.ndarray, List[str], List[int]]:
    """Reads a TUM image list (``rgb.txt`` / ``depth.txt``): ``timestamp filename`` lines.

    ``#`` comment lines and blank lines are skipped; commas and tabs count as separators.
    Entries are returned sorted by timestamp (a list that is out of order is sorted, not
    rejected: recorders sometimes flush out of order).

    Returns:
        (timestamps (N,) float64 seconds, filenames as written, 1-based line numbers).

    Raises:
        TumFormatError: a line without exactly two fields, a timestamp that is not a finite
            number, or the same timestamp twice (file and line are named).
    """
    stamps: List[float] = []
    names: List[str] = []
    lines: List[int] = []
    try:
        with open(path, "r", encoding="utf-8") as f:
            text_lines = f.read().splitlines()
    except UnicodeDecodeError as e:
        raise TumFormatError(f"not a UTF-8 text file ({e})", path) from None
    for lineno, raw in enumerate(text_lines, 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.replace(",", " ").split()
        if len(parts) != 2:
            raise TumFormatError(f"expected 'timestamp filename', got {raw.strip()!r}", path, lineno)
        try:
            t = float(parts[0])
        except ValueError:
            raise TumFormatError(f"timestamp {parts[0]!r} is not a number", path, lineno) from None
        if not math.isfinite(t):
            raise TumFormatError(f"timestamp {parts[0]!r} is not finite", path, lineno)
        stamps.append(t)
        names.append(parts[1])
        lines.append(lineno)
    ts = np.array(stamps, dtype=np.float64)
    order = np.argsort(ts, kind="stable")
    ts = ts[order]
    names = [names[i] for i in order]
    lines = [lines[i] for i in order]
    if len(ts) > 1:
        dup = np.flatnonzero(np.diff(ts) == 0)
        if dup.size:
            k = int(dup[0])
            raise TumFormatError(f"timestamp {ts[k]:.6f} appears twice (lines {lines[k]} and {lines[k + 1]})",
                                 path, lines[k + 1])
    return ts, names, lines


# --------------------------------------------------------------------------- images

# Pillow's raw mode names the stored pixel layout ("I;16B", "RGB;16B", "LA;16B"); its
# mode alone does not (16-bit RGB and greyscale+alpha PNGs are reduced to 8 bits).
_LAYOUTS = {"1": "greyscale", "L": "greyscale", "I": "greyscale", "LA": "greyscale+alpha", "RGB": "RGB",
            "RGBA": "RGBA", "P": "palette", "PA": "palette+alpha"}


def _open_image(path: PathLike, what: str):
    """Opens an image with Pillow (header only); TumFormatError when it is no image."""
    try:
        return Image.open(path)
    except OSError as e:  # UnidentifiedImageError included
        kind = "a PNG file" if what == "depth image" else "an image file"
        raise TumFormatError(f"{what} is not {kind}, or one truncated before its header ends "
                             f"({type(e).__name__}: {e})", path) from None


def _layout(im) -> Tuple[int, str]:
    """(bits per channel, colour layout) of an opened image, from Pillow's raw mode."""
    tile = getattr(im, "tile", None)  # absent once decoded
    raw = tile[0][3] if tile and isinstance(tile[0][3], str) else im.mode
    base, _, bits = raw.partition(";")
    bit_depth = int(re.match(r"\d*", bits).group() or (1 if base == "1" else 8))
    return bit_depth, _LAYOUTS.get(base, f"mode {im.mode}")


def _decode(im, path: PathLike, mode: Optional[str] = None) -> np.ndarray:
    try:
        im.load()
        return np.array(im if mode is None or im.mode == mode else im.convert(mode))
    except Exception as e:  # PIL raises OSError, SyntaxError, ValueError, zlib errors...
        raise TumFormatError(f"unreadable PNG ({type(e).__name__}: {e})", path) from e


def _checked(path: PathLike, what: str):
    """The opened image, its header validated: a 16-bit greyscale PNG for depth, 8 bits
    per channel for colour."""
    im = _open_image(path, f"{what} image")
    bit_depth, layout = _layout(im)
    if what == "depth" and (im.format != "PNG" or bit_depth != 16 or layout != "greyscale"):
        message = (f"depth image must be a 16-bit single-channel greyscale PNG, this one is {bit_depth}-bit "
                   f"{layout} {im.format}")
    elif what == "colour" and bit_depth != 8 and im.mode != "1":
        message = f"colour image must have 8 bits per channel, this one is {bit_depth}-bit {layout} {im.format}"
    else:
        return im
    im.close()
    raise TumFormatError(message, path)


def _image_size(path: PathLike, what: str) -> Tuple[int, int]:
    """(width, height) of a depth or colour image, header checked."""
    with _checked(path, what) as im:
        return im.size


def _load_depth_png(path: PathLike) -> np.ndarray:
    """A 16-bit greyscale PNG as an (H, W) uint16 array, bit-exact."""
    with _checked(path, "depth") as im:
        arr = _decode(im, path)
    if arr.dtype != np.uint16 and arr.size and (arr.min() < 0 or arr.max() > 0xFFFF):  # Pillow's 32-bit "I"
        raise TumFormatError("depth PNG decoded to values outside 0..65535", path)
    return arr.astype(np.uint16)


def _load_rgb(path: PathLike) -> np.ndarray:
    """An 8-bit colour image as (H, W, 3) uint8 (greyscale / palette / alpha converted)."""
    with _checked(path, "colour") as im:
        return np.ascontiguousarray(_decode(im, path, "RGB"), dtype=np.uint8)


# --------------------------------------------------------------------------- intrinsics


def _find_camera_file(folder: Path) -> Optional[Path]:
    found = [folder / n for n in CAMERA_FILE_NAMES if (folder / n).is_file()]
    if len(found) > 1:
        raise TumFormatError(f"more than one camera file: {[p.name for p in found]}; keep one", folder)
    return found[0] if found else None


# YAML 1.1 (PyYAML) reads exponent notation without a dot ("1e-3") as text.
_EXPONENT_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")


def _camera_mapping(path: PathLike) -> Dict[str, Any]:
    """A camera file's ``key: value`` entries: JSON, or YAML (OpenCV's ``%YAML:1.0`` line,
    which YAML parsers reject as a directive, is skipped)."""
    text = Path(path).read_text(encoding="utf-8")
    try:
        if str(path).lower().endswith(".json") or text.lstrip().startswith("{"):
            d = json.loads(text)
        else:
            d = yaml.safe_load(re.sub(r"\A%YAML:1\.0[^\n]*", "", text))
    except json.JSONDecodeError as e:
        raise ValueError(f"not valid JSON: {e}") from None
    except yaml.YAMLError as e:
        raise ValueError(f"not valid YAML: {e}") from None
    if not isinstance(d, dict):
        raise ValueError(f"expected 'key: value' entries, got {type(d).__name__} {d!r:.60}")
    return {k: float(v) if isinstance(v, str) and _EXPONENT_NUMBER.fullmatch(v) else v for k, v in d.items()}


def _read_camera(path: PathLike) -> Tuple[Intrinsics, Optional[float]]:
    """Intrinsics and optional depth_scale (m per unit) from a camera file."""
    try:
        d = _camera_mapping(path)
    except OSError as e:
        raise TumFormatError(f"cannot read camera file ({e})", path) from e
    except ValueError as e:
        raise TumFormatError(f"malformed camera file ({e})", path) from e
    try:
        intr = Intrinsics.from_dict(d)
    except (ValueError, TypeError) as e:
        raise TumFormatError(f"camera file: {e}", path) from e
    scale = d.get("depth_scale")
    if scale is not None:
        if not _is_number(scale) or not scale > 0:
            raise TumFormatError(f"depth_scale must be a positive number of metres per unit, got {scale!r}", path)
        scale = float(scale)
    return intr, scale


def _folder_hint(folder: Path) -> str:
    m = re.search(r"(?:freiburg|fr)([123])", folder.name.lower())
    if m:
        return f" (the folder name suggests freiburg{m.group(1)}: intrinsics='tum_fr{m.group(1)}')"
    return ""


# --------------------------------------------------------------------------- sequence


class TumSequence:
    """An RGB-D sequence in the TUM RGB-D benchmark layout, read lazily.

    Frames are the depth images listed in ``depth.txt``, in increasing time.  When
    ``rgb.txt`` lists at least one image, every depth image is paired with the colour
    image closest in time within ``max_time_difference``
    (:func:`scanalign.trajectory.associate_timestamps`,
    the benchmark's greedy ``associate.py`` rule, each image used at most once) and depth
    images without a partner are dropped (counted in :attr:`dropped_depth_frames`), so
    every frame has colour.  Without ``rgb.txt`` (or with an empty one) the sequence is
    depth-only and ``Frame.rgb`` is None.  Then ``start``, ``stride`` and ``limit`` select
    frames ``associated[start::stride][:limit]``.

    Ground truth (``groundtruth.txt``, ``T_world_camera`` of the motion-capture world, 4x4,
    metres) is interpolated to each frame's depth timestamp (linear in position,
    spherical-linear in rotation, :meth:`Trajectory.interpolate`).  A frame before the
    first or after the last ground-truth pose, or in a ground-truth gap wider than
    ``max_groundtruth_gap`` seconds, gets ``T_base_camera=None``.

    Args:
        folder: the sequence folder.
        intrinsics: an :class:`Intrinsics`, a preset name from
            :data:`scanalign.camera.INTRINSICS_PRESETS` (e.g. ``"tum_fr1"``), a path to a
            camera file (JSON or flat YAML with width, height, fx, fy, cx, cy and optional
            depth_scale), or None for the folder's own camera file
            (:data:`CAMERA_FILE_NAMES`; more than one is an error).
        depth_scale: metres per depth unit.  Precedence: this argument, then the
            ``depth_scale`` of the camera file given as ``intrinsics``, then that of the
            folder's camera file (it describes the folder's data even when the intrinsics
            come from elsewhere), then 1/5000 (TUM).  The folder's camera file is read only
            when it matters (no ``intrinsics``, or no depth_scale from the argument or the
            explicit camera file); :attr:`camera_file` names the file the intrinsics came
            from (None for a preset or an :class:`Intrinsics`).
        max_time_difference: largest |t_depth - t_rgb| (s) for a depth/colour pair
            (inclusive; the benchmark's default is 0.02 s).
        stride: keep every ``stride``-th associated frame (>= 1).
        start: index of the first associated frame to keep (>= 0).
        limit: at most this many frames (None: all).
        max_groundtruth_gap: largest time (s) between the two ground-truth poses that
            bracket a frame for the frame to get an interpolated pose.  The benchmark's
            motion capture runs at 100 Hz or more; the default 0.1 s tolerates a few
            dropped samples but not a tracking loss.

    Timestamps in the lists may be out of order (they are sorted); the same timestamp
    twice in one list is an error.  The lists and the existence of every selected image
    are checked on construction, together with the header (size and bit depth) of the
    first selected frame's images; every frame's images are checked again when loaded.

    Raises:
        FileNotFoundError: no such folder, no ``depth.txt``, or a listed image is missing.
        NotADirectoryError: ``folder`` is a file.
        TumFormatError (a ValueError): a malformed list or camera file, no intrinsics, an
            image that is unreadable, not 16-bit (depth), or of the wrong size; the
            message names the file and, for lists, the line.
    """

    def __init__(self, folder: PathLike, intrinsics: Union[Intrinsics, str, "os.PathLike[str]", None] = None,
                 depth_scale: Optional[float] = None, max_time_difference: float = 0.02, stride: int = 1,
                 start: int = 0, limit: Optional[int] = None, max_groundtruth_gap: float = 0.1) -> None:
        self._folder = Path(folder)
        if not self._folder.exists():
            raise FileNotFoundError(f"{self._folder}: no such sequence folder")
        if not self._folder.is_dir():
            raise NotADirectoryError(f"{self._folder}: not a folder (expected a TUM sequence folder with depth.txt)")
        depth_list = self._folder / "depth.txt"
        if not depth_list.is_file():
            raise FileNotFoundError(f"{depth_list}: missing; a TUM sequence folder lists its depth images in "
                                    "depth.txt ('timestamp filename' per line)")
        for name, v in (("stride", stride), ("start", start)):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                raise TypeError(f"{name} must be an integer, got {v!r}")
        if stride < 1:
            raise ValueError(f"stride must be >= 1, got {stride}")
        if start < 0:
            raise ValueError(f"start must be >= 0, got {start}")
        if limit is not None and (isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or limit < 0):
            raise ValueError(f"limit must be None or an integer >= 0, got {limit!r}")
        if not _is_number(max_time_difference) or not max_time_difference >= 0:
            raise ValueError(f"max_time_difference must be a finite number >= 0 (s), got {max_time_difference!r}")
        if not _is_number(max_groundtruth_gap) or not max_groundtruth_gap > 0:
            raise ValueError(f"max_groundtruth_gap must be a finite number > 0 (s), got {max_groundtruth_gap!r}")
        max_time_difference = float(max_time_difference)
        max_groundtruth_gap = float(max_groundtruth_gap)

        self._intrinsics, self._depth_scale, self.camera_file = self._resolve_camera(intrinsics, depth_scale)

        # Lists and association.
        d_ts, d_names, d_lines = read_timestamp_list(depth_list)
        rgb_list = self._folder / "rgb.txt"
        self.has_rgb = False
        rgb_ts = np.zeros(0)
        rgb_names: List[str] = []
        rgb_lines: List[int] = []
        if rgb_list.is_file():
            rgb_ts, rgb_names, rgb_lines = read_timestamp_list(rgb_list)
            self.has_rgb = len(rgb_ts) > 0
        if self.has_rgb:
            pairs = associate_timestamps(d_ts, rgb_ts, max_time_difference)
            if len(d_ts) and len(pairs) == 0:
                raise TumFormatError(f"no depth image has a colour image within max_time_difference="
                                     f"{max_time_difference} s (depth {d_ts[0]:.6f}..{d_ts[-1]:.6f}, rgb "
                                     f"{rgb_ts[0]:.6f}..{rgb_ts[-1]:.6f}); check the lists or raise "
                                     "max_time_difference", self._folder)
            di, ri = pairs[:, 0], pairs[:, 1]
        else:
            di, ri = np.arange(len(d_ts)), None
        #: Depth images listed in depth.txt that have no colour partner (dropped).
        self.dropped_depth_frames = int(len(d_ts) - len(di))
        sel = np.arange(len(di))[start::stride]
        if limit is not None:
            sel = sel[:limit]
        self._source_index = sel
        self._timestamps = d_ts[di[sel]]
        self._depth_files = [self._folder / d_names[k] for k in di[sel]]
        self._depth_lines = [d_lines[k] for k in di[sel]]
        if ri is not None:
            self._rgb_timestamps: Optional[np.ndarray] = rgb_ts[ri[sel]]
            self._rgb_files: Optional[List[Path]] = [self._folder / rgb_names[k] for k in ri[sel]]
            rgb_line_of = [rgb_lines[k] for k in ri[sel]]
        else:
            self._rgb_timestamps = None
            self._rgb_files = None
        for p, line in zip(self._depth_files, self._depth_lines):
            if not p.is_file():
                raise FileNotFoundError(f"{depth_list}:{line}: listed depth image {p} does not exist")
        if self._rgb_files is not None:
            for p, line in zip(self._rgb_files, rgb_line_of):
                if not p.is_file():
                    raise FileNotFoundError(f"{rgb_list}:{line}: listed colour image {p} does not exist")
        if len(self) > 0:  # early, cheap check of the first frame's headers
            self._check_size(self._depth_files[0], _image_size(self._depth_files[0], "depth"), "depth")
            if self._rgb_files is not None:
                self._check_size(self._rgb_files[0], _image_size(self._rgb_files[0], "colour"), "colour")

        # Ground truth.
        self.groundtruth: Optional[Trajectory] = None
        self._poses: List[Optional[np.ndarray]] = [None] * len(self)
        gt_path = self._folder / "groundtruth.txt"
        if gt_path.is_file():
            gt = self._read_groundtruth(gt_path)
            self.groundtruth = gt
            if len(gt) > 0 and len(self) > 0:
                self._poses = _interpolate_where_covered(gt, self._timestamps, max_groundtruth_gap)

    # ---------------------------------------------------------------- construction helpers

    def _resolve_camera(self, intrinsics: Any, depth_scale: Optional[float]
                        ) -> Tuple[Intrinsics, float, Optional[Path]]:
        if depth_scale is not None and (not _is_number(depth_scale) or not depth_scale > 0):
            raise ValueError(f"depth_scale must be a positive number of metres per unit, got {depth_scale!r}")
        folder_cache: List[Tuple[Optional[Path], Optional[Intrinsics], Optional[float]]] = []

        def folder_camera() -> Tuple[Optional[Path], Optional[Intrinsics], Optional[float]]:
            # Read only when it matters, so a stray file does not block explicit settings.
            if not folder_cache:
                path = _find_camera_file(self._folder)
                folder_cache.append((path, *_read_camera(path)) if path is not None else (None, None, None))
            return folder_cache[0]

        arg_scale: Optional[float] = None
        camera_file: Optional[Path] = None
        if intrinsics is None:
            camera_file, intr, _ = folder_camera()
            if intr is None:
                raise TumFormatError(
                    "no intrinsics: the folder has no camera file (" + ", ".join(CAMERA_FILE_NAMES) +
                    f"); pass intrinsics (--intrinsics on the command line) as a preset name "
                    f"{sorted(INTRINSICS_PRESETS)} or a camera file" + _folder_hint(self._folder), self._folder)
        elif isinstance(intrinsics, Intrinsics):
            intr = intrinsics
        elif isinstance(intrinsics, str) and intrinsics in INTRINSICS_PRESETS:
            intr = INTRINSICS_PRESETS[intrinsics]
        elif isinstance(intrinsics, (str, os.PathLike)):
            p = Path(intrinsics)
            if not p.is_file():
                raise ValueError(f"intrinsics {os.fspath(intrinsics)!r} is neither a preset "
                                 f"{sorted(INTRINSICS_PRESETS)} nor an existing camera file")
            intr, arg_scale = _read_camera(p)
            camera_file = p
        else:
            raise TypeError(f"intrinsics must be an Intrinsics, a preset name, a camera file path or None, "
                            f"got {type(intrinsics).__name__}")
        if depth_scale is not None:
            scale = float(depth_scale)
        elif arg_scale is not None:
            scale = arg_scale
        else:
            folder_scale = folder_camera()[2]
            scale = folder_scale if folder_scale is not None else TUM_DEPTH_SCALE
        return intr, scale, camera_file

    def _check_size(self, path: Path, size: Tuple[int, int], what: str) -> None:
        w, h = size
        if (h, w) != self._intrinsics.shape:
            raise TumFormatError(f"{what} image is {w}x{h} pixels but the intrinsics are "
                                 f"{self._intrinsics.width}x{self._intrinsics.height}; pass matching intrinsics "
                                 "(Intrinsics.scaled for a resized sequence)", path)

    @staticmethod
    def _read_groundtruth(path: Path) -> Trajectory:
        try:
            gt = read_tum_trajectory(path)
        except ValueError as e:  # already names file and line
            raise TumFormatError(f"malformed ground truth: {e}") from e
        except UnicodeDecodeError as e:
            raise TumFormatError(f"not a UTF-8 text file ({e})", path) from e
        if len(gt) > 1:
            order = np.argsort(gt.timestamps, kind="stable")
            gt = Trajectory(gt.timestamps[order], gt.poses[order])
            dup = np.flatnonzero(np.diff(gt.timestamps) == 0)
            if dup.size:
                raise TumFormatError(f"ground-truth timestamp {gt.timestamps[dup[0]]:.6f} appears twice", path)
        return gt

    # ---------------------------------------------------------------- public API

    @property
    def folder(self) -> Path:
        """The sequence folder."""
        return self._folder

    @property
    def name(self) -> str:
        """The folder's name, e.g. ``rgbd_dataset_freiburg1_xyz``."""
        return Path(os.path.abspath(self._folder)).name

    @property
    def intrinsics(self) -> Intrinsics:
        """The pinhole intrinsics of the depth images (pixels)."""
        return self._intrinsics

    @property
    def depth_scale(self) -> float:
        """Metres per unit of the depth PNGs."""
        return self._depth_scale

    @property
    def timestamps(self) -> np.ndarray:
        """(N,) float64 depth timestamps of the selected frames, seconds (a copy)."""
        return self._timestamps.copy()

    @property
    def rgb_timestamps(self) -> Optional[np.ndarray]:
        """(N,) float64 timestamps of the paired colour images (s), or None when depth-only."""
        return None if self._rgb_timestamps is None else self._rgb_timestamps.copy()

    @property
    def depth_files(self) -> List[Path]:
        return list(self._depth_files)

    @property
    def rgb_files(self) -> Optional[List[Path]]:
        return None if self._rgb_files is None else list(self._rgb_files)

    def __len__(self) -> int:
        return int(self._timestamps.shape[0])

    def __getitem__(self, i: int) -> Frame:
        """Frame ``i`` (negative indices count from the end), PNGs decoded now.

        ``depth`` is (H, W) uint16 in units of :attr:`depth_scale` metres (0 = no
        measurement), ``rgb`` (H, W, 3) uint8 or None, ``timestamp`` the depth timestamp
        (s), ``T_base_camera`` the interpolated ground-truth pose or None, ``index`` = i.
        ``meta`` holds ``depth_file``, ``rgb_file``, ``rgb_timestamp``, ``source_index``
        (position among all associated frames, before start/stride/limit), ``sequence``.
        """
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
            raise TypeError(f"TumSequence indices must be integers, got {type(i).__name__}")
        n = len(self)
        k = int(i) + n if i < 0 else int(i)
        if not 0 <= k < n:
            raise IndexError(f"frame index {i} out of range for a sequence of {n} frames")
        depth_path = self._depth_files[k]
        depth = _load_depth_png(depth_path)
        self._check_size(depth_path, (depth.shape[1], depth.shape[0]), "depth")
        rgb = None
        meta: Dict[str, Any] = {"depth_file": str(depth_path), "source_index": int(self._source_index[k]),
                                "sequence": self.name, "rgb_file": None, "rgb_timestamp": None}
        if self._rgb_files is not None:
            rgb_path = self._rgb_files[k]
            rgb = _load_rgb(rgb_path)
            self._check_size(rgb_path, (rgb.shape[1], rgb.shape[0]), "colour")
            meta["rgb_file"] = str(rgb_path)
            meta["rgb_timestamp"] = float(self._rgb_timestamps[k])  # type: ignore[index]
        pose = self._poses[k]
        return Frame(depth=depth, intrinsics=self._intrinsics, rgb=rgb, depth_scale=self._depth_scale,
                     timestamp=float(self._timestamps[k]), T_base_camera=None if pose is None else pose.copy(),
                     index=k, meta=meta)

    def __iter__(self) -> Iterator[Frame]:
        for k in range(len(self)):
            yield self[k]

    def poses(self) -> List[Optional[np.ndarray]]:
        """Per frame, the interpolated ground-truth ``T_world_camera`` (4x4) or None."""
        return [None if p is None else p.copy() for p in self._poses]

    def reference_trajectory(self) -> Optional[Trajectory]:
        """Ground-truth poses of the frames that have one, at their depth timestamps, as a
        :class:`Trajectory` of ``T_world_camera``; None when no frame has ground truth."""
        idx = [k for k, p in enumerate(self._poses) if p is not None]
        if not idx:
            return None
        return Trajectory(self._timestamps[idx], np.stack([self._poses[k] for k in idx]))

    def __repr__(self) -> str:
        n_gt = sum(p is not None for p in self._poses)
        return (f"TumSequence({os.fspath(self._folder)!r}, frames={len(self)}, rgb={self.has_rgb}, "
                f"groundtruth={n_gt}/{len(self)}, intrinsics={self._intrinsics}, depth_scale={self._depth_scale})")


def _interpolate_where_covered(gt: Trajectory, t: np.ndarray, max_gap: float) -> List[Optional[np.ndarray]]:
    """Ground-truth poses at times ``t`` where the trajectory covers them (inside its span,
    bracketing poses at most ``max_gap`` s + 1 us apart), else None."""
    ts = gt.timestamps
    inside = (t >= ts[0]) & (t <= ts[-1])
    hi = np.clip(np.searchsorted(ts, t, side="left"), 0, len(ts) - 1)
    lo = np.clip(hi - 1, 0, len(ts) - 1)
    exact = np.abs(ts[hi] - t) <= 1e-9  # the same rule as Trajectory.interpolate
    gap = np.where(exact, 0.0, ts[hi] - ts[lo])
    # Timestamps are microsecond-precision decimals: a gap that equals max_gap in the text
    # may exceed it by a rounding error in binary, hence the 1 us slack.
    max_gap = max_gap + 1e-6
    ok = inside & (gap <= max_gap)
    out: List[Optional[np.ndarray]] = [None] * len(t)
    if np.any(ok):
        poses = gt.interpolate(t[ok], max_gap=max_gap).poses
        for k, T in zip(np.flatnonzero(ok), poses):
            out[int(k)] = T
    return out


# --------------------------------------------------------------------------- writing


def is_tum_folder(path: Any) -> bool:
    """True when ``path`` is a folder containing ``depth.txt`` (a TUM RGB-D sequence)."""
    try:
        p = Path(path)
        return p.is_dir() and (p / "depth.txt").is_file()
    except (TypeError, ValueError, OSError):
        return False


def _depth_units(frame: Frame, depth_scale: float, where: str) -> np.ndarray:
    """A frame's depth as uint16 in units of ``depth_scale`` m (nearest, ties to even;
    0 where there is no measurement)."""
    d = np.asarray(frame.depth)
    if d.ndim != 2:
        raise ValueError(f"{where}: depth must be a 2-D (H, W) image, got shape {d.shape}")
    if np.issubdtype(d.dtype, np.integer):
        if d.dtype == np.uint16 and float(frame.depth_scale) == float(depth_scale):
            return d.copy()
        metres = d.astype(np.float64) * float(frame.depth_scale)
        metres[d <= 0] = 0.0
    elif np.issubdtype(d.dtype, np.floating):
        metres = d.astype(np.float64)
        metres[~np.isfinite(metres) | (metres <= 0)] = 0.0
    else:
        raise TypeError(f"{where}: depth must be an integer or floating-point image, got dtype {d.dtype}")
    units = np.rint(metres / depth_scale)
    if units.size and units.max() > 0xFFFF:
        raise ValueError(f"{where}: depth {metres.max():.4f} m exceeds the largest value a 16-bit PNG holds "
                         f"at depth_scale {depth_scale:g} m ({0xFFFF * depth_scale:.4f} m); use a larger depth_scale")
    return units.astype(np.uint16)


def write_tum_sequence(folder: PathLike, frames: Iterable[Frame], intrinsics: Optional[Intrinsics] = None,
                       depth_scale: float = TUM_DEPTH_SCALE, write_groundtruth: bool = True) -> str:
    """Writes RGB-D frames into the TUM RGB-D layout, readable by :class:`TumSequence`.

    Writes ``depth/<timestamp>.png`` (16-bit greyscale, units of ``depth_scale`` m) and
    ``depth.txt``; when the frames have colour, ``rgb/<timestamp>.png`` (8-bit RGB) and
    ``rgb.txt`` with the depth timestamps; ``camera.json`` (intrinsics and depth_scale);
    and ``groundtruth.txt`` with ``Frame.T_base_camera`` (as ``T_world_camera``, metres)
    of every frame that has one, at its timestamp (no file when none has one).  When only
    some frames have a pose, :class:`TumSequence` reads the others back with poses
    interpolated from their neighbours (or None outside the span).  Timestamps are
    written with 6 decimals (microseconds) like the benchmark.  PNGs use zlib level 1
    (several times faster than Pillow's default on noisy depth, files a little larger).

    Depth: integer images are converted from ``Frame.depth_scale`` to ``depth_scale``
    (copied bit for bit when both agree), float images are in metres; values are rounded
    to the nearest unit, and 0, negative, NaN and Inf become 0 (no measurement).  A depth
    beyond ``65535 * depth_scale`` m raises ValueError.

    Args:
        folder: the output folder; created if missing, and must not already hold a
            sequence (``depth.txt``, ``rgb.txt``, ``groundtruth.txt``, images).
        frames: the frames, in any iterable; written in time order.
        intrinsics: the camera written to ``camera.json``; default: the frames' own
            intrinsics, which must then all be equal.  Its size must match every depth
            image.
        depth_scale: metres per depth unit in the PNGs (default 1/5000, TUM).
        write_groundtruth: False to skip ``groundtruth.txt``.

    Returns:
        The folder path, as a string.

    Raises:
        ValueError: no frames, frames of different intrinsics, a size mismatch, colour in
            only some frames, a malformed colour image, timestamps that coincide at 6
            decimals, a non-finite timestamp, or depth out of range.
        FileExistsError: the folder already holds a sequence.
    """
    if not _is_number(depth_scale) or not depth_scale > 0:
        raise ValueError(f"depth_scale must be a positive number of metres per unit, got {depth_scale!r}")
    depth_scale = float(depth_scale)
    frames = list(frames)
    if not frames:
        raise ValueError("write_tum_sequence: no frames to write")
    for k, f in enumerate(frames):
        if not isinstance(f, Frame):
            raise TypeError(f"frame {k}: expected scanalign.camera.Frame, got {type(f).__name__}")
    if intrinsics is None:
        intrinsics = frames[0].intrinsics
        for k, f in enumerate(frames):
            if f.intrinsics != intrinsics:
                raise ValueError(f"frame {k}: intrinsics {f.intrinsics} differ from frame 0's {intrinsics}; "
                                 "one TUM folder has one camera (pass intrinsics explicitly to override)")
    elif not isinstance(intrinsics, Intrinsics):
        raise TypeError(f"intrinsics must be an Intrinsics or None, got {type(intrinsics).__name__}")
    has_rgb = [f.rgb is not None for f in frames]
    if any(has_rgb) and not all(has_rgb):
        raise ValueError(f"frames {[k for k, h in enumerate(has_rgb) if not h][:10]} have no colour image while "
                         "others do; a TUM folder pairs every depth image with a colour image or none")
    stamps = np.array([float(f.timestamp) for f in frames])
    if not np.all(np.isfinite(stamps)):
        raise ValueError("write_tum_sequence: non-finite timestamp")
    order = np.argsort(stamps, kind="stable")
    labels = [f"{stamps[k]:.6f}" for k in order]
    for a, b, la, lb in zip(order[:-1], order[1:], labels[:-1], labels[1:]):
        if la == lb:
            raise ValueError(f"frames {a} and {b} have the same timestamp at microsecond precision ({la} s)")

    out = Path(folder)
    if out.exists() and not out.is_dir():
        raise NotADirectoryError(f"{out}: exists and is not a folder")
    taken = [n for n in ("depth.txt", "rgb.txt", "groundtruth.txt", *CAMERA_FILE_NAMES) if (out / n).exists()]
    taken += [n for n in ("depth", "rgb") if (out / n).is_dir() and any((out / n).iterdir())]
    if taken:
        raise FileExistsError(f"{out}: already holds a sequence ({', '.join(taken)}); write into a new folder")
    (out / "depth").mkdir(parents=True, exist_ok=True)
    if any(has_rgb):
        (out / "rgb").mkdir(exist_ok=True)

    depth_lines, rgb_lines, gt_t, gt_T = [], [], [], []
    for k, label in zip(order, labels):
        f = frames[k]
        where = f"frame {k} (t={label})"
        units = _depth_units(f, depth_scale, where)
        if units.shape != intrinsics.shape:
            raise ValueError(f"{where}: depth image {units.shape[1]}x{units.shape[0]} does not match the "
                             f"intrinsics {intrinsics.width}x{intrinsics.height}")
        name = f"depth/{label}.png"
        # Little-endian uint16 -> Pillow mode "I;16" -> 16-bit greyscale PNG.
        Image.fromarray(np.ascontiguousarray(units, dtype="<u2")).save(out / name, format="PNG", compress_level=1)
        depth_lines.append(f"{label} {name}\n")
        if f.rgb is not None:
            rgb = np.asarray(f.rgb)
            if rgb.dtype != np.uint8 or rgb.shape != units.shape + (3,):
                raise ValueError(f"{where}: rgb must be a ({units.shape[0]}, {units.shape[1]}, 3) uint8 image, got "
                                 f"{rgb.dtype} {rgb.shape}")
            rname = f"rgb/{label}.png"
            Image.fromarray(np.ascontiguousarray(rgb)).save(out / rname, format="PNG", compress_level=1)
            rgb_lines.append(f"{label} {rname}\n")
        if f.T_base_camera is not None:
            T = np.asarray(f.T_base_camera, dtype=np.float64)
            if T.shape != (4, 4) or not np.all(np.isfinite(T)):
                raise ValueError(f"{where}: T_base_camera must be a finite 4x4 matrix")
            gt_t.append(float(label))
            gt_T.append(T)

    title = out.resolve().name
    with open(out / "depth.txt", "w", encoding="utf-8") as fh:
        fh.write(f"# depth maps\n# file: '{title}' (scanalign, depth_scale {depth_scale!r} m per unit)\n"
                 "# timestamp filename\n")
        fh.writelines(depth_lines)
    if rgb_lines:
        with open(out / "rgb.txt", "w", encoding="utf-8") as fh:
            fh.write(f"# color images\n# file: '{title}' (scanalign)\n# timestamp filename\n")
            fh.writelines(rgb_lines)
    with open(out / "camera.json", "w", encoding="utf-8") as fh:
        json.dump({**intrinsics.to_dict(), "depth_scale": depth_scale}, fh, indent=2)
        fh.write("\n")
    if write_groundtruth and gt_T:
        write_tum_trajectory(out / "groundtruth.txt", Trajectory(np.array(gt_t), np.stack(gt_T)),
                             header=f"ground truth trajectory\nfile: '{title}' (scanalign, T_world_camera)")
    return os.fspath(out)

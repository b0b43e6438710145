"""Real RGB-D sequences in the TUM RGB-D benchmark folder layout.

A sequence folder (e.g. ``rgbd_dataset_freiburg1_xyz`` as downloaded from the TUM RGB-D
benchmark) holds::

    depth.txt          # lines "timestamp filename" (s, path relative to the folder)
    depth/*.png        # 16-bit single-channel PNG, depth (z) in units of depth_scale m
    rgb.txt            # optional; same line format
    rgb/*.png          # 8-bit colour images registered to the depth images
    groundtruth.txt    # optional; TUM trajectory "timestamp tx ty tz qx qy qz qw"
    camera.json        # optional camera file (or camera.yaml / intrinsics.json|yaml)

The lists follow :func:`scanalign.evaluation.trajectory.read_tum_rows` (``#`` comments and blank
lines skipped; commas and tabs separate fields, as in the benchmark's ``associate.py``).
TUM depth images store 5000 units per metre (``depth_scale = 1/5000`` m per unit, 0 = no
measurement).

Ground truth poses are ``T_world_camera`` of the benchmark's motion-capture world frame
(4x4, metres, mapping camera coordinates into world coordinates); they are handed out as
:attr:`scanalign.reconstruction.camera.Frame.T_base_camera`, i.e. the motion-capture world plays the
part of the robot's base frame.

:class:`TumSequence` reads such a folder lazily (PNGs are decoded when a frame is
requested) and :func:`write_tum_sequence` writes frames into the same layout, so
synthetic data can be stored and replayed like a real recording.  Images go through
Pillow, camera files through :func:`scanalign.reconstruction.camera.read_camera_file` (scanalign's flat keys, a ROS
``camera_info`` YAML or an OpenCV calibration YAML; distortion included).
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, Iterator, List, Optional, Tuple, Union

import numpy as np
from PIL import Image

from scanalign.evaluation.trajectory import (
    Trajectory,
    TumFormatError,
    associate_timestamps,
    read_tum_rows,
    time_order,
    write_tum_trajectory,
)
from scanalign.reconstruction.camera import (
    INTRINSICS_PRESETS,
    Frame,
    Intrinsics,
    camera_from_dict,
    read_camera_file,
    sequence_index,
)

__all__ = ["TumSequence", "TumFormatError", "write_tum_sequence", "is_tum_folder", "read_timestamp_list",
           "TUM_DEPTH_SCALE", "CAMERA_FILE_NAMES"]

#: Metres per unit of a TUM depth PNG (the benchmark stores 5000 units per metre).
TUM_DEPTH_SCALE = 1.0 / 5000.0

#: Camera files looked for in a sequence folder, in this order.  At most one may exist.
CAMERA_FILE_NAMES = ("camera.json", "camera.yaml", "camera.yml", "intrinsics.json", "intrinsics.yaml",
                     "intrinsics.yml")

PathLike = Union[str, "os.PathLike[str]"]


def _number(name: str, value: Any, low: float, inclusive: bool, what: str) -> float:
    """``value`` as a float after checking it is a finite real number (not a bool) above
    ``low`` (or equal to it when ``inclusive``); ValueError naming ``name`` otherwise."""
    ok = (not isinstance(value, (bool, np.bool_)) and isinstance(value, (int, float, np.integer, np.floating))
          and math.isfinite(float(value)) and (value >= low if inclusive else value > low))
    if not ok:
        raise ValueError(f"{name} must be {what}, got {value!r}")
    return float(value)


def _depth_scale(value: Any) -> float:
    return _number("depth_scale", value, 0.0, False, "a positive number of metres per unit")


def read_timestamp_list(path: PathLike) -> Tuple[np.ndarray, List[str], List[int]]:
    """Reads a TUM image list (``rgb.txt`` / ``depth.txt``): ``timestamp filename`` lines,
    returned sorted by timestamp (a list that is out of order is sorted, not rejected:
    recorders sometimes flush out of order).

    Returns:
        (timestamps (N,) float64 seconds, filenames as written, 1-based line numbers).

    Raises:
        TumFormatError: a line without exactly two fields, a timestamp that is not a finite
            number, or the same timestamp twice (file and line are named).
    """
    values, names, lines = read_tum_rows(path, 2, "'timestamp filename'")
    order = time_order(values[:, 0], path, lines)
    return values[order, 0], [names[k] for k in order], lines[order].tolist()


# Pillow's raw mode names the stored pixel layout ("I;16B", "RGB;16B", "LA;16B"); its
# mode alone does not (16-bit RGB and greyscale+alpha PNGs are reduced to 8 bits).
_LAYOUTS = {"1": "greyscale", "L": "greyscale", "I": "greyscale", "LA": "greyscale+alpha", "RGB": "RGB",
            "RGBA": "RGBA", "P": "palette", "PA": "palette+alpha"}


def _open_image(path: PathLike, what: str):
    """The image opened by Pillow (header only) and checked: a 16-bit greyscale PNG for
    ``what="depth"``, 8 bits per channel for ``"colour"``."""
    try:
        im = Image.open(path)
    except (OSError, Image.DecompressionBombError) as e:  # UnidentifiedImageError included
        kind = "a PNG file" if what == "depth" else "an image file"
        raise TumFormatError(f"{what} image is not {kind}, or one truncated before its header ends "
                             f"({type(e).__name__}: {e})", path) from None
    tile = getattr(im, "tile", None)  # absent once decoded
    raw = tile[0][3] if tile and isinstance(tile[0][3], str) else im.mode
    base, _, bits = raw.partition(";")
    bit_depth = int(re.match(r"\d*", bits).group() or (1 if base == "1" else 8))
    found = f"{bit_depth}-bit {_LAYOUTS.get(base, f'mode {im.mode}')} {im.format}"
    if what == "depth" and (im.format != "PNG" or bit_depth != 16 or _LAYOUTS.get(base) != "greyscale"):
        message = f"depth image must be a 16-bit single-channel greyscale PNG, this one is {found}"
    elif what == "colour" and bit_depth != 8 and im.mode != "1":
        message = f"colour image must have 8 bits per channel, this one is {found}"
    else:
        return im
    im.close()
    raise TumFormatError(message, path)


def load_image(path: PathLike, what: str, check: Callable[[Any], None] = lambda im: None) -> np.ndarray:
    """A depth PNG as (H, W) uint16, bit-exact, or a colour image as (H, W, 3) uint8
    (greyscale / palette / alpha converted); ``check(im)`` sees the header before decoding."""
    with _open_image(path, what) as im:
        check(im)  # e.g. the size: a header claiming a huge image is refused before it is decoded
        try:
            im.load()
            arr = np.array(im if what == "depth" or im.mode == "RGB" else im.convert("RGB"))
        except Exception as e:  # PIL raises OSError, SyntaxError, ValueError, zlib errors...
            raise TumFormatError(f"unreadable PNG ({type(e).__name__}: {e})", path) from e
    if what == "colour":
        return np.ascontiguousarray(arr, dtype=np.uint8)
    if arr.dtype != np.uint16 and arr.size and (arr.min() < 0 or arr.max() > 0xFFFF):  # Pillow's 32-bit "I"
        raise TumFormatError("depth PNG decoded to values outside 0..65535", path)
    return arr.astype(np.uint16)


def _read_camera(path: PathLike) -> Tuple[Intrinsics, Optional[float]]:
    """Intrinsics and optional depth_scale (m per unit) from a camera file."""
    try:
        d = read_camera_file(path)
    except OSError as e:
        raise TumFormatError(f"cannot read camera file ({e})", path) from e
    except ValueError as e:
        raise TumFormatError(f"malformed camera file ({e})", path) from e
    try:  # scanalign's flat keys, a ROS camera_info or an OpenCV calibration file
        intrinsics, scale = camera_from_dict(d)
        return intrinsics, None if scale is None else _depth_scale(scale)
    except (ValueError, TypeError) as e:
        raise TumFormatError(f"camera file: {e}", path) from e


class TumSequence:
    """An RGB-D sequence in the TUM RGB-D benchmark layout, read lazily.

    Frames are the depth images listed in ``depth.txt``, in increasing time.  When
    ``rgb.txt`` lists at least one image, every depth image is paired with a colour image
    within ``max_time_difference`` by :func:`scanalign.evaluation.trajectory.associate_timestamps`
    (the benchmark's greedy ``associate.py`` rule, each image used at most once); depth
    images without a partner are dropped (counted in :attr:`dropped_depth_frames`), so
    every frame has colour.  Without ``rgb.txt`` (or with an empty one) the sequence is
    depth-only and ``Frame.rgb`` is None.  Then ``start``, ``stride`` and ``limit`` select
    frames ``associated[start::stride][:limit]``.

    Ground truth (``groundtruth.txt``, ``T_world_camera`` of the motion-capture world, 4x4,
    metres) is interpolated to each frame's depth timestamp (:meth:`Trajectory.interpolate`:
    linear in position, spherical-linear in rotation).  A frame before the first or after
    the last ground-truth pose, or in a ground-truth gap wider than ``max_groundtruth_gap``
    seconds, gets ``T_base_camera=None``.

    Args:
        folder: the sequence folder.
        intrinsics: an :class:`Intrinsics`, a preset name from
            :data:`scanalign.reconstruction.camera.INTRINSICS_PRESETS` (e.g. ``"tum_fr1"``), a path to a
            camera file (JSON or YAML with width, height, fx, fy, cx, cy and optional
            depth_scale), or None for the folder's own camera file
            (:data:`CAMERA_FILE_NAMES`; more than one is an error).
        depth_scale: metres per depth unit.  Precedence: this argument, then the
            ``depth_scale`` of the camera file given as ``intrinsics``, then that of the
            folder's camera file (it describes the folder's data even when the intrinsics
            come from elsewhere), then 1/5000 (TUM).  The folder's camera file is read only
            when it matters.
        max_time_difference: largest |t_depth - t_rgb| (s) for a depth/colour pair
            (inclusive; the benchmark's default is 0.02 s).
        stride: keep every ``stride``-th associated frame (>= 1).
        start: index of the first associated frame to keep (>= 0).
        limit: at most this many frames (None: all).
        max_groundtruth_gap: largest time (s) between the two ground-truth poses that
            bracket a frame for the frame to get an interpolated pose.  The benchmark's
            motion capture runs at 100 Hz or more; the default 0.1 s tolerates a few
            dropped samples but not a tracking loss.

    Attributes:
        folder (Path), name (the folder's name, e.g. ``rgbd_dataset_freiburg1_xyz``),
        intrinsics (of the depth images, pixels), depth_scale (metres per depth unit),
        camera_file (the file the intrinsics came from; None for a preset or an
        :class:`Intrinsics`), has_rgb, dropped_depth_frames, groundtruth (the whole
        ground-truth :class:`Trajectory`, time-sorted, or None); per selected frame:
        timestamps ((N,) float64 depth timestamps, s), depth_files, and rgb_timestamps and
        rgb_files of the paired colour images (None when depth-only).

    Timestamps in the lists may be out of order (they are sorted); the same timestamp
    twice in one list is an error.  The lists and the existence of every selected image
    are checked on construction, together with the header (size and bit depth) of the
    first selected frame's images; every frame's images are checked again when loaded.

    Raises:
        FileNotFoundError: no such folder, no ``depth.txt``, or a listed image is missing.
        NotADirectoryError: ``folder`` is a file.
        TypeError: a non-integer ``stride``, ``start`` or ``limit``, an ``intrinsics`` of
            another type.
        ValueError: a bad ``stride``, ``start``, ``limit``, ``depth_scale``, time bound.
        TumFormatError (a ValueError): a malformed list or camera file, no intrinsics, an
            image that is unreadable, not 16-bit (depth), or of the wrong size, no depth
            image with a colour partner; the message names the file and, for lists, the line.
    """

    def __init__(self, folder: PathLike, intrinsics: Union[Intrinsics, str, "os.PathLike[str]", None] = None,
                 depth_scale: Optional[float] = None, max_time_difference: float = 0.02, stride: int = 1,
                 start: int = 0, limit: Optional[int] = None, max_groundtruth_gap: float = 0.1) -> None:
        self.folder = Path(folder)
        self.name = Path(os.path.abspath(self.folder)).name
        if not self.folder.exists():
            raise FileNotFoundError(f"{self.folder}: no such sequence folder")
        if not self.folder.is_dir():
            raise NotADirectoryError(f"{self.folder}: not a folder (expected a TUM sequence folder with depth.txt)")
        depth_list, rgb_list = self.folder / "depth.txt", self.folder / "rgb.txt"
        if not depth_list.is_file():
            raise FileNotFoundError(f"{depth_list}: missing; a TUM sequence folder lists its depth images in "
                                    "depth.txt ('timestamp filename' per line)")
        for name, v, low in (("stride", stride, 1), ("start", start, 0), ("limit", 0 if limit is None else limit, 0)):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
                raise TypeError(f"{name} must be an integer{' or None' * (name == 'limit')}, got {v!r}")
            _number(name, v, low, True, f">= {low}")
        max_dt = _number("max_time_difference", max_time_difference, 0.0, True, "a finite number >= 0 (s)")
        max_gap = _number("max_groundtruth_gap", max_groundtruth_gap, 0.0, False, "a finite number > 0 (s)")
        self.intrinsics, self.depth_scale, self.camera_file = self._resolve_camera(intrinsics, depth_scale)

        d_ts, d_names, d_lines = read_timestamp_list(depth_list)
        rgb_ts, rgb_names, rgb_lines = read_timestamp_list(rgb_list) if rgb_list.is_file() else (np.zeros(0), [], [])
        self.has_rgb = len(rgb_ts) > 0
        di, ri = np.arange(len(d_ts)), None
        if self.has_rgb:
            pairs = associate_timestamps(d_ts, rgb_ts, max_dt)
            if len(d_ts) and len(pairs) == 0:
                raise TumFormatError(f"no depth image has a colour image within max_time_difference="
                                     f"{max_dt} s (depth {d_ts[0]:.6f}..{d_ts[-1]:.6f}, rgb "
                                     f"{rgb_ts[0]:.6f}..{rgb_ts[-1]:.6f}); check the lists or raise "
                                     "max_time_difference", self.folder)
            di, ri = pairs[:, 0], pairs[:, 1]
        #: Depth images listed in depth.txt that have no colour partner (dropped).
        self.dropped_depth_frames = int(len(d_ts) - len(di))
        self._source_index = np.arange(len(di))[start::stride][:limit]
        di = di[self._source_index]
        self.timestamps = d_ts[di]
        self.depth_files = self._listed(depth_list, "depth", d_names, d_lines, di)
        self.rgb_timestamps = None if ri is None else rgb_ts[ri[self._source_index]]
        self.rgb_files = None if ri is None else self._listed(rgb_list, "colour", rgb_names, rgb_lines,
                                                               ri[self._source_index])
        if len(self) > 0:  # early, cheap check of the first frame's headers
            for path, what in ((self.depth_files[0], "depth"), (self.rgb_files and self.rgb_files[0], "colour")):
                if path:
                    with _open_image(path, what) as im:
                        self._check_size(path, im.size, what)

        self.groundtruth: Optional[Trajectory] = None
        self._poses: List[Optional[np.ndarray]] = [None] * len(self)
        gt_path = self.folder / "groundtruth.txt"
        if gt_path.is_file():
            rows, _, lines = read_tum_rows(gt_path, 8, "8 values (timestamp tx ty tz qx qy qz qw)")
            self.groundtruth = Trajectory.from_tum_rows(rows[time_order(rows[:, 0], gt_path, lines)])
            if len(self.groundtruth) > 0:
                self._poses = _interpolate_where_covered(self.groundtruth, self.timestamps, max_gap)

    def _listed(self, list_file: Path, what: str, names: List[str], lines: List[int], keep: np.ndarray) -> List[Path]:
        """The selected images of a list, each checked to exist."""
        for k in keep:
            if not (self.folder / names[k]).is_file():
                raise FileNotFoundError(f"{list_file}:{lines[k]}: listed {what} image {self.folder / names[k]} "
                                        "does not exist")
        return [self.folder / names[k] for k in keep]

    def _resolve_camera(self, intrinsics: Any, depth_scale: Optional[float]
                        ) -> Tuple[Intrinsics, float, Optional[Path]]:
        scale = None if depth_scale is None else _depth_scale(depth_scale)
        camera_file: Optional[Path] = None
        if isinstance(intrinsics, Intrinsics):
            intr = intrinsics
        elif isinstance(intrinsics, str) and intrinsics in INTRINSICS_PRESETS:
            intr = INTRINSICS_PRESETS[intrinsics]
        elif isinstance(intrinsics, (str, os.PathLike)):
            camera_file = Path(intrinsics)
            if not camera_file.is_file():
                raise ValueError(f"intrinsics {os.fspath(intrinsics)!r} is neither a preset "
                                 f"{sorted(INTRINSICS_PRESETS)} nor an existing camera file")
            intr, file_scale = _read_camera(camera_file)
            scale = file_scale if scale is None else scale
        elif intrinsics is not None:
            raise TypeError(f"intrinsics must be an Intrinsics, a preset name, a camera file path or None, "
                            f"got {type(intrinsics).__name__}")
        if intrinsics is None or scale is None:
            # The folder's camera file is read only when it matters, so a stray file does
            # not block explicit settings.
            found = [self.folder / n for n in CAMERA_FILE_NAMES if (self.folder / n).is_file()]
            if len(found) > 1:
                raise TumFormatError(f"more than one camera file: {[p.name for p in found]}; keep one", self.folder)
            folder_intr, folder_scale = _read_camera(found[0]) if found else (None, None)
            if intrinsics is None:
                if folder_intr is None:
                    m = re.search(r"(?:freiburg|fr)([123])", self.folder.name.lower())
                    hint = f" (the folder name suggests freiburg{m[1]}: intrinsics='tum_fr{m[1]}')" if m else ""
                    raise TumFormatError(
                        "no intrinsics: the folder has no camera file (" + ", ".join(CAMERA_FILE_NAMES) +
                        f"); pass intrinsics (--intrinsics on the command line) as a preset name "
                        f"{sorted(INTRINSICS_PRESETS)} or a camera file" + hint, self.folder)
                intr, camera_file = folder_intr, found[0]
            if scale is None:
                scale = TUM_DEPTH_SCALE if folder_scale is None else folder_scale
        return intr, scale, camera_file

    def _check_size(self, path: Path, size: Tuple[int, int], what: str) -> None:
        w, h = size
        if (h, w) != self.intrinsics.shape:
            raise TumFormatError(f"{what} image is {w}x{h} pixels but the intrinsics are "
                                 f"{self.intrinsics.width}x{self.intrinsics.height}; pass matching intrinsics "
                                 "(Intrinsics.scaled for a resized sequence)", path)

    def __len__(self) -> int:
        return int(self.timestamps.shape[0])

    def __getitem__(self, i: int) -> Frame:
        """Frame ``i`` (negative indices count from the end), PNGs decoded now.

        ``depth`` is (H, W) uint16 in units of :attr:`depth_scale` metres (0 = no
        measurement), ``rgb`` (H, W, 3) uint8 or None, ``timestamp`` the depth timestamp
        (s), ``T_base_camera`` the interpolated ground-truth pose or None, ``index`` = i.
        ``meta`` holds ``depth_file``, ``rgb_file``, ``rgb_timestamp``, ``source_index``
        (position among all associated frames, before start/stride/limit), ``sequence``.
        """
        k = sequence_index(i, len(self), "TumSequence")
        meta: Dict[str, Any] = {"depth_file": str(self.depth_files[k]), "source_index": int(self._source_index[k]),
                                "sequence": self.name, "rgb_file": None, "rgb_timestamp": None}
        depth = self._load(self.depth_files[k], "depth")
        rgb = None
        if self.rgb_files is not None:
            rgb = self._load(self.rgb_files[k], "colour")
            meta.update(rgb_file=str(self.rgb_files[k]), rgb_timestamp=float(self.rgb_timestamps[k]))
        pose = self._poses[k]
        return Frame(depth=depth, intrinsics=self.intrinsics, rgb=rgb, depth_scale=self.depth_scale,
                     timestamp=float(self.timestamps[k]), T_base_camera=None if pose is None else pose.copy(),
                     index=k, meta=meta)

    def _load(self, path: Path, what: str) -> np.ndarray:
        return load_image(path, what, lambda im: self._check_size(path, im.size, what))

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
        return Trajectory(self.timestamps[idx], np.stack([self._poses[k] for k in idx])) if idx else None

    def __repr__(self) -> str:
        n_gt = sum(p is not None for p in self._poses)
        return (f"TumSequence({os.fspath(self.folder)!r}, frames={len(self)}, rgb={self.has_rgb}, "
                f"groundtruth={n_gt}/{len(self)}, intrinsics={self.intrinsics}, depth_scale={self.depth_scale})")


def _interpolate_where_covered(gt: Trajectory, t: np.ndarray, max_gap: float) -> List[Optional[np.ndarray]]:
    """Ground-truth poses at times ``t`` where the trajectory covers them (inside its span,
    bracketing poses at most ``max_gap`` s + 1 us apart), else None."""
    ts = gt.timestamps
    hi = np.clip(np.searchsorted(ts, t, side="left"), 0, len(ts) - 1)
    gap = np.where(np.abs(ts[hi] - t) <= 1e-9, 0.0, ts[hi] - ts[np.maximum(hi - 1, 0)])  # exact hits: no gap
    # Timestamps are microsecond-precision decimals: a gap that equals max_gap in the text
    # may exceed it by a rounding error in binary, hence the 1 us slack.
    ok = np.flatnonzero((t >= ts[0]) & (t <= ts[-1]) & (gap <= max_gap + 1e-6))
    out: List[Optional[np.ndarray]] = [None] * len(t)
    for k, T in zip(ok, gt.interpolate(t[ok], max_gap=max_gap + 1e-6).poses if ok.size else ()):
        out[int(k)] = T
    return out


def is_tum_folder(path: Any) -> bool:
    """True when ``path`` is a folder containing ``depth.txt`` (a TUM RGB-D sequence)."""
    try:
        return Path(path).is_dir() and (Path(path) / "depth.txt").is_file()
    except (TypeError, ValueError, OSError):
        return False


def _depth_units(frame: Frame, depth_scale: float, where: str) -> np.ndarray:
    """A frame's depth as uint16 in units of ``depth_scale`` m (nearest, ties to even;
    0 where there is no measurement)."""
    d = np.asarray(frame.depth)
    if d.ndim != 2:
        raise ValueError(f"{where}: depth must be a 2-D (H, W) image, got shape {d.shape}")
    if d.dtype.kind in "iu":
        if d.dtype == np.uint16 and float(frame.depth_scale) == depth_scale:
            return d.copy()
        metres = np.where(d > 0, d * float(frame.depth_scale), 0.0)
    elif d.dtype.kind == "f":
        metres = np.where(np.isfinite(d) & (d > 0), d, 0.0).astype(np.float64)
    else:
        raise TypeError(f"{where}: depth must be an integer or floating-point image, got dtype {d.dtype}")
    units = np.rint(metres / depth_scale)
    if units.size and units.max() > 0xFFFF:
        raise ValueError(f"{where}: depth {metres.max():.4f} m exceeds the largest value a 16-bit PNG holds "
                         f"at depth_scale {depth_scale:g} m ({0xFFFF * depth_scale:.4f} m); use a larger depth_scale")
    return units.astype(np.uint16)


def _write_list(path: Path, title: str, lines: List[str]) -> None:
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(title + "# timestamp filename\n")
        fh.writelines(lines)


def write_tum_sequence(folder: PathLike, frames: Iterable[Frame], intrinsics: Optional[Intrinsics] = None,
                       depth_scale: float = TUM_DEPTH_SCALE, write_groundtruth: bool = True) -> str:
    """Writes RGB-D frames into the TUM RGB-D layout, readable by :class:`TumSequence`:
    ``depth/<timestamp>.png`` (16-bit, units of ``depth_scale`` m; integer images converted
    from ``Frame.depth_scale``, float images in metres; rounded, with 0/negative/NaN/Inf
    written as 0) and ``depth.txt``; with colour, ``rgb/<timestamp>.png`` and ``rgb.txt``;
    ``camera.json`` (``intrinsics``, default the frames' own, which must then agree, and
    ``depth_scale``); and, unless ``write_groundtruth`` is False, ``groundtruth.txt`` with
    each frame's ``T_base_camera`` (as ``T_world_camera``, metres) when it has one.
    Timestamps get 6 decimals; frames are written in time order; PNGs use zlib level 1.

    Returns the folder path. Raises TypeError (not a :class:`Frame`, bad ``intrinsics``),
    ValueError (no frames, mixed intrinsics or colour, size mismatch, malformed colour or
    pose, timestamps equal at 6 decimals or non-finite, depth beyond ``65535 * depth_scale``),
    FileExistsError (``folder`` already holds a sequence) or NotADirectoryError.
    """
    depth_scale = _depth_scale(depth_scale)
    frames = list(frames)
    if not frames:
        raise ValueError("write_tum_sequence: no frames to write")
    for k, f in enumerate(frames):
        if not isinstance(f, Frame):
            raise TypeError(f"frame {k}: expected scanalign.reconstruction.camera.Frame, got {type(f).__name__}")
        if intrinsics is None and f.intrinsics != frames[0].intrinsics:
            raise ValueError(f"frame {k}: intrinsics {f.intrinsics} differ from frame 0's {frames[0].intrinsics}; "
                             "one TUM folder has one camera (pass intrinsics explicitly to override)")
    intrinsics = frames[0].intrinsics if intrinsics is None else intrinsics
    if not isinstance(intrinsics, Intrinsics):
        raise TypeError(f"intrinsics must be an Intrinsics or None, got {type(intrinsics).__name__}")
    no_rgb = [k for k, f in enumerate(frames) if f.rgb is None]
    if 0 < len(no_rgb) < len(frames):
        raise ValueError(f"frames {no_rgb[:10]} have no colour image while others do; a TUM folder pairs every "
                         "depth image with a colour image or none")
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
    if not no_rgb:
        (out / "rgb").mkdir(exist_ok=True)

    depth_lines, rgb_lines, gt_t, gt_T = [], [], [], []
    for k, label in zip(order, labels):
        f, where = frames[k], f"frame {k} (t={label})"
        units = _depth_units(f, depth_scale, where)
        if units.shape != intrinsics.shape:
            raise ValueError(f"{where}: depth image {units.shape[1]}x{units.shape[0]} does not match the "
                             f"intrinsics {intrinsics.width}x{intrinsics.height}")
        # Little-endian uint16 -> Pillow mode "I;16" -> 16-bit greyscale PNG.
        Image.fromarray(units.astype("<u2")).save(out / f"depth/{label}.png", format="PNG", compress_level=1)
        depth_lines.append(f"{label} depth/{label}.png\n")
        if f.rgb is not None:
            rgb = np.asarray(f.rgb)
            if rgb.dtype != np.uint8 or rgb.shape != units.shape + (3,):
                raise ValueError(f"{where}: rgb must be a ({units.shape[0]}, {units.shape[1]}, 3) uint8 image, got "
                                 f"{rgb.dtype} {rgb.shape}")
            Image.fromarray(np.ascontiguousarray(rgb)).save(out / f"rgb/{label}.png", format="PNG", compress_level=1)
            rgb_lines.append(f"{label} rgb/{label}.png\n")
        if f.T_base_camera is not None:
            T = np.asarray(f.T_base_camera, dtype=np.float64)
            if T.shape != (4, 4) or not np.all(np.isfinite(T)):
                raise ValueError(f"{where}: T_base_camera must be a finite 4x4 matrix")
            gt_t.append(float(label))
            gt_T.append(T)

    title = out.resolve().name
    _write_list(out / "depth.txt", f"# depth maps\n# file: '{title}' (scanalign, depth_scale {depth_scale!r} m per "
                "unit)\n", depth_lines)
    if rgb_lines:
        _write_list(out / "rgb.txt", f"# color images\n# file: '{title}' (scanalign)\n", rgb_lines)
    (out / "camera.json").write_text(json.dumps({**intrinsics.to_dict(), "depth_scale": depth_scale}, indent=2) + "\n",
                                     encoding="utf-8")
    if write_groundtruth and gt_T:
        write_tum_trajectory(out / "groundtruth.txt", Trajectory(np.array(gt_t), np.stack(gt_T)),
                             header=f"ground truth trajectory\nfile: '{title}' (scanalign, T_world_camera)")
    return os.fspath(out)

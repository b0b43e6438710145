"""Real RGB-D sequences in the TUM RGB-D benchmark folder layout, and the checks every reader
of :mod:`scanalign.datasets` shares (frame selection, camera files, images, time pairing).

A sequence folder (e.g. ``rgbd_dataset_freiburg1_xyz``) holds::

    depth.txt          # lines "timestamp filename" (s, path relative to the folder)
    depth/*.png        # 16-bit single-channel PNG, depth (z) in units of depth_scale m
    rgb.txt            # optional; same line format
    rgb/*.png          # 8-bit colour images registered to the depth images
    groundtruth.txt    # optional; TUM trajectory "timestamp tx ty tz qx qy qz qw"
    camera.json        # optional camera file (or camera.yaml / intrinsics.json|yaml)

The lists follow :func:`scanalign.evaluation.trajectory.read_tum_rows`; depth images store 5000
units per metre. Ground truth poses are ``T_world_camera`` (4x4, metres) handed out as
``Frame.T_base_camera``: the motion-capture world plays the part of the robot's base frame.
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path
from typing import Any, Dict, Iterable, Iterator, List, Optional, Tuple, Union

import numpy as np
from PIL import Image

from scanalign import _core
from scanalign.evaluation.trajectory import (PathLike, Trajectory, TumFormatError, associate_timestamps, read_tum_rows,
                                             time_order, write_tum_trajectory)
from scanalign.reconstruction.camera import (INTRINSICS_PRESETS, Frame, Intrinsics, camera_from_dict, read_camera_file,
                                             sequence_index)

__all__ = ["TumSequence", "TumFormatError", "write_tum_sequence", "is_tum_folder", "read_timestamp_list",
           "TUM_DEPTH_SCALE", "CAMERA_FILE_NAMES"]

#: Metres per unit of a TUM depth PNG (the benchmark stores 5000 units per metre).
TUM_DEPTH_SCALE = 1.0 / 5000.0

#: Camera files looked for in a sequence folder, in this order.  At most one may exist.
CAMERA_FILE_NAMES = ("camera.json", "camera.yaml", "camera.yml", "intrinsics.json", "intrinsics.yaml", "intrinsics.yml")


def check_number(name: str, value: Any, what: str, low: float = 0.0, strict: bool = False,
                 high: float = math.inf) -> float:
    """``value`` as a float: a finite real number (not a bool) ``>= low`` (``> low`` when
    ``strict``) and ``<= high``; else ValueError "``name`` must be ``what``, got ..."."""
    ok = (not isinstance(value, (bool, np.bool_)) and isinstance(value, (int, float, np.integer, np.floating))
          and math.isfinite(float(value)) and (value > low if strict else value >= low) and value <= high)
    if not ok:
        raise ValueError(f"{name} must be {what}, got {value!r}")
    return float(value)


def check_selection(start: Any, stride: Any, limit: Any) -> None:
    """Checks the frame selection ``frames[start::stride][:limit]`` (TypeError for a
    non-integer, ValueError for stride < 1, start < 0, limit < 0; limit may be None)."""
    for name, v, low in (("stride", stride, 1), ("start", start, 0), ("limit", 0 if limit is None else limit, 0)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise TypeError(f"{name} must be an integer{' or None' * (name == 'limit')}, got {v!r}")
        check_number(name, v, f">= {low}", low)


def _read_camera(path: PathLike) -> Tuple[Intrinsics, Optional[float]]:
    """Intrinsics and optional depth_scale from a camera file (any layout of
    :func:`scanalign.reconstruction.camera.camera_from_dict`)."""
    try:
        return camera_from_dict(read_camera_file(path))
    except OSError as e:
        raise TumFormatError(f"cannot read camera file ({e})", path) from e
    except (ValueError, TypeError) as e:
        raise TumFormatError(f"malformed camera file ({e})", path) from e


def camera_argument(intrinsics: Any) -> Tuple[Optional[Intrinsics], Optional[float], Optional[Path]]:
    """An ``intrinsics=`` argument (an :class:`Intrinsics`, a preset name of
    :data:`~scanalign.reconstruction.camera.INTRINSICS_PRESETS`, a camera file path or None) as
    ``(intrinsics, depth_scale, file)``, the last two from a camera file only. ValueError for a string that is neither a
    preset nor a file (TumFormatError: a malformed camera file), TypeError for another type."""
    if intrinsics is None or isinstance(intrinsics, Intrinsics):
        return intrinsics, None, None
    if isinstance(intrinsics, str) and intrinsics in INTRINSICS_PRESETS:
        return INTRINSICS_PRESETS[intrinsics], None, None
    if not isinstance(intrinsics, (str, os.PathLike)):
        raise TypeError(f"intrinsics must be an Intrinsics, a preset name, a camera file path or None, "
                        f"got {type(intrinsics).__name__}")
    path = Path(intrinsics)
    if not path.is_file():
        raise ValueError(f"intrinsics {os.fspath(intrinsics)!r} is neither a preset {sorted(INTRINSICS_PRESETS)} "
                         "nor an existing camera file")
    return (*_read_camera(path), path)


def resolve_camera(folder: Path, intrinsics: Any, depth_scale: Any, default_scale: float,
                   max_scale: float = math.inf) -> Tuple[Intrinsics, float, Optional[Path]]:
    """A recording folder's ``(intrinsics, depth_scale, camera file)``. ``intrinsics``: as :func:`camera_argument`;
    None: the folder's camera file (one of :data:`CAMERA_FILE_NAMES`; more than one is an error). ``depth_scale`` (m per
    unit, in ``(0, max_scale]``): this argument, else the camera file given as ``intrinsics``, else the folder's camera
    file (read only when it matters, so a stray file does not block explicit settings), else ``default_scale``."""
    rule = "a positive number of metres per unit" if max_scale == math.inf else f"in (0, {max_scale:g}] metres per unit"
    if depth_scale is not None:
        check_number("depth_scale", depth_scale, rule, strict=True, high=max_scale)
    intr, scale, camera_file = camera_argument(intrinsics)
    scale = scale if depth_scale is None else depth_scale
    if intr is None or scale is None:
        found = [folder / n for n in CAMERA_FILE_NAMES if (folder / n).is_file()]
        if len(found) > 1:
            raise TumFormatError(f"more than one camera file: {[p.name for p in found]}; keep one", folder)
        if found:
            folder_intr, folder_scale = _read_camera(found[0])
            if intr is None:
                intr, camera_file = folder_intr, found[0]
            scale = folder_scale if scale is None else scale
        elif intr is None:
            m = re.search(r"(?:freiburg|fr)([123])", folder.name.lower())
            hint = f" (the folder name suggests freiburg{m[1]}: intrinsics='tum_fr{m[1]}')" if m else ""
            raise TumFormatError(f"no intrinsics: the folder has no camera file ({', '.join(CAMERA_FILE_NAMES)}); "
                                 "pass intrinsics (--intrinsics on the command line) as a preset name "
                                 f"{sorted(INTRINSICS_PRESETS)} or a camera file" + hint, folder)
    scale = default_scale if scale is None else scale
    return intr, check_number("depth_scale", scale, rule, strict=True, high=max_scale), camera_file


# Pillow's raw mode names the stored pixel layout ("I;16B", "RGB;16B", "LA;16B"); its
# mode alone does not (16-bit RGB and greyscale+alpha PNGs are reduced to 8 bits).
_LAYOUTS = {"1": "greyscale", "L": "greyscale", "I": "greyscale", "LA": "greyscale+alpha", "RGB": "RGB",
            "RGBA": "RGBA", "P": "palette", "PA": "palette+alpha"}


def open_image(path: PathLike, what: str, intrinsics: Intrinsics):
    """The image opened by Pillow (header only) and checked: a 16-bit greyscale PNG for
    ``what="depth"``, 8 bits per channel for ``"colour"``, the size of ``intrinsics``
    (a header claiming a huge image is refused before it is decoded)."""
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
    w, h = im.size
    if what == "depth" and (im.format != "PNG" or bit_depth != 16 or _LAYOUTS.get(base) != "greyscale"):
        message = f"depth image must be a 16-bit single-channel greyscale PNG, this one is {found}"
    elif what == "colour" and bit_depth != 8 and im.mode != "1":
        message = f"colour image must have 8 bits per channel, this one is {found}"
    elif (h, w) != intrinsics.shape:
        message = (f"{what} image is {w}x{h} pixels but the intrinsics are {intrinsics.width}x{intrinsics.height}; "
                   "pass matching intrinsics (Intrinsics.scaled for a resized sequence)")
    else:
        return im
    im.close()
    raise TumFormatError(message, path)


def load_image(path: PathLike, what: str, intrinsics: Intrinsics) -> np.ndarray:
    """A depth PNG as (H, W) uint16, bit-exact, or a colour image as (H, W, 3) uint8
    (greyscale / palette / alpha converted), checked by :func:`open_image`."""
    with open_image(path, what, intrinsics) as im:
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


def pair_frames(depth_t: np.ndarray, color_t: np.ndarray, max_dt: float, where: PathLike,
                streams: str = "") -> np.ndarray:
    """(K, 2) (depth, colour) index pairs by :func:`~scanalign.evaluation.trajectory.associate_timestamps`
    (the benchmark's ``associate.py`` rule, each image used once); TumFormatError naming
    ``where`` when there are depth images but none has a colour partner."""
    pairs = associate_timestamps(depth_t, color_t, max_dt)
    if len(depth_t) and len(pairs) == 0:
        raise TumFormatError(f"no depth image{streams} has a colour image within max_time_difference={max_dt} s "
                             f"(depth {depth_t[0]:.6f}..{depth_t[-1]:.6f} s, colour {color_t[0]:.6f}.."
                             f"{color_t[-1]:.6f} s); check the timestamps or raise max_time_difference", where)
    return pairs


def interpolate(ts: np.ndarray, values: np.ndarray, t: np.ndarray, max_gap: float) -> List[Optional[np.ndarray]]:
    """Per query time ``t``, the ``values`` sampled at sorted times ``ts`` (same unit) interpolated, or None where the
    samples do not cover it (covered: an exact hit within 1e-9, or inside their span between two samples at most
    ``max_gap`` apart). Poses (N, 4, 4) are linear in position and spherical-linear in rotation, rows (N, n) linear."""
    t, out = np.asarray(t), [None] * len(t)
    if len(ts) == 0:
        return out
    hi = np.clip(np.searchsorted(ts, t, side="left"), 0, len(ts) - 1)
    lo = np.where(np.abs(ts[hi] - t) <= 1e-9, hi, np.maximum(hi - 1, 0))
    gap = ts[hi] - ts[lo]
    ok = np.flatnonzero((t >= ts[0]) & (t <= ts[-1]) & (gap <= max_gap))
    lo, hi, gap = lo[ok], hi[ok], gap[ok]
    w = np.where(gap > 0, (t[ok] - ts[lo]) / np.where(gap > 0, gap, 1), 0.0)
    a, b = values[lo], values[hi]
    for k, v in zip(ok, _core.evaluation.interpolate_poses(a, b, w) if values.ndim == 3
                    else (1 - w)[:, None] * a + w[:, None] * b):
        out[k] = v
    return out


class ImageFileSequence:
    """Frames from image files: ``depth_files``, ``rgb_files`` (or None) and ``timestamps``
    (s) per frame, decoded and checked (:func:`load_image`) when a frame is requested."""

    depth_files: List[Path]
    rgb_files: Optional[List[Path]]
    timestamps: np.ndarray
    intrinsics: Intrinsics
    depth_scale: float

    def _meta(self, k: int) -> Dict[str, Any]:
        return {}

    def _pose(self, k: int) -> Optional[np.ndarray]:
        return None

    def __len__(self) -> int:
        return len(self.depth_files)

    def __getitem__(self, i: int) -> Frame:
        k = sequence_index(i, len(self), type(self).__name__)
        depth = load_image(self.depth_files[k], "depth", self.intrinsics)
        rgb_file = None if self.rgb_files is None else self.rgb_files[k]
        rgb = None if rgb_file is None else load_image(rgb_file, "colour", self.intrinsics)
        meta = {"depth_file": str(self.depth_files[k]), "rgb_file": None if rgb_file is None else str(rgb_file),
                **self._meta(k)}
        return Frame(depth=depth, intrinsics=self.intrinsics, rgb=rgb, depth_scale=self.depth_scale,
                     timestamp=float(self.timestamps[k]), T_base_camera=self._pose(k), index=k, meta=meta)

    def __iter__(self) -> Iterator[Frame]:
        for k in range(len(self)):
            yield self[k]


def read_timestamp_list(path: PathLike) -> Tuple[np.ndarray, List[str], List[int]]:
    """Reads a TUM image list (``rgb.txt`` / ``depth.txt``) of ``timestamp filename`` lines,
    sorted by timestamp (recorders sometimes flush out of order): ``(timestamps (N,) float64
    seconds, filenames as written, 1-based line numbers)``. TumFormatError (naming the file and
    line) for a line without exactly two fields, a timestamp that is not a finite number, or
    the same timestamp twice."""
    values, names, lines = read_tum_rows(path, 2, "'timestamp filename'")
    order = time_order(values[:, 0], path, lines)
    return values[order, 0], [names[k] for k in order], lines[order].tolist()


class TumSequence(ImageFileSequence):
    """An RGB-D sequence in the TUM RGB-D benchmark layout; PNGs are decoded when a frame is requested.

    Frames are the depth images of ``depth.txt`` in increasing time. When ``rgb.txt`` lists images, each is paired with
    a colour image within ``max_time_difference`` by :func:`~scanalign.evaluation.trajectory.associate_timestamps`
    (depth images without a partner are dropped, counted in :attr:`dropped_depth_frames`); then ``start``, ``stride``,
    ``limit`` select ``paired[start::stride][:limit]``. Ground truth (``groundtruth.txt``) is interpolated to each depth
    timestamp (linear in position, spherical-linear in rotation); a frame outside it, or in a gap wider than
    ``max_groundtruth_gap`` s, gets ``T_base_camera=None``.

    Args:
        folder: the sequence folder.
        intrinsics: an :class:`Intrinsics`, a preset name from
            :data:`~scanalign.reconstruction.camera.INTRINSICS_PRESETS` (e.g. ``"tum_fr1"``), a
            camera file, or None for the folder's own camera file (:data:`CAMERA_FILE_NAMES`).
        depth_scale: metres per depth unit: this argument, else the ``depth_scale`` of the camera
            file given as ``intrinsics``, else that of the folder's camera file, else 1/5000.
        max_time_difference: largest |t_depth - t_rgb| (s) of a pair (inclusive).
        stride, start, limit: frame selection (stride >= 1, start >= 0, limit None: all).
        max_groundtruth_gap: largest time (s) between the two ground-truth poses around a frame
            (the default 0.1 s tolerates a few dropped 100 Hz samples, not a tracking loss).

    Attributes:
        folder (Path), name (the folder's name), intrinsics, depth_scale, camera_file (None for
        a preset or an :class:`Intrinsics`), has_rgb, dropped_depth_frames, groundtruth (the
        whole time-sorted ground-truth :class:`Trajectory`, or None); per selected frame:
        timestamps ((N,) float64 s), depth_files, rgb_timestamps and rgb_files (None: depth only).

    Frames: ``depth`` (H, W) uint16 in units of :attr:`depth_scale` m (0 = no measurement), ``rgb`` (H, W, 3) uint8 or
    None, ``timestamp`` the depth timestamp, ``T_base_camera`` the interpolated ground truth or None; ``meta``:
    ``depth_file``, ``rgb_file``, ``rgb_timestamp``, ``source_index`` (position among all paired frames), ``sequence``.

    Raises (the lists, every selected image's existence and the first frame's image headers
    are checked on construction, every frame's images when loaded):
        FileNotFoundError: no such folder, no ``depth.txt``, or a listed image is missing.
        NotADirectoryError: ``folder`` is a file. TypeError: a non-integer ``stride``, ``start``
            or ``limit``, an ``intrinsics`` of another type.
        ValueError: a bad ``stride``, ``start``, ``limit``, ``depth_scale``, time bound;
            TumFormatError (a ValueError, naming the file and line): a malformed list or camera file, no intrinsics, an
            unreadable, non-16-bit (depth) or wrongly sized image, no depth image with a colour partner.
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
        check_selection(start, stride, limit)
        max_dt = check_number("max_time_difference", max_time_difference, "a finite number >= 0 (s)")
        max_gap = check_number("max_groundtruth_gap", max_groundtruth_gap, "a finite number > 0 (s)", strict=True)
        self.intrinsics, self.depth_scale, self.camera_file = resolve_camera(self.folder, intrinsics, depth_scale,
                                                                             TUM_DEPTH_SCALE)

        d_ts, d_names, d_lines = read_timestamp_list(depth_list)
        rgb_ts, rgb_names, rgb_lines = read_timestamp_list(rgb_list) if rgb_list.is_file() else (np.zeros(0), [], [])
        self.has_rgb = len(rgb_ts) > 0
        di, ri = np.arange(len(d_ts)), None
        if self.has_rgb:
            di, ri = pair_frames(d_ts, rgb_ts, max_dt, self.folder).T
        self.dropped_depth_frames = int(len(d_ts) - len(di))
        self._source_index = np.arange(len(di))[start::stride][:limit]
        di, ri = di[self._source_index], None if ri is None else ri[self._source_index]
        self.timestamps = d_ts[di]
        self.depth_files = self._listed(depth_list, "depth", d_names, d_lines, di)
        self.rgb_timestamps = None if ri is None else rgb_ts[ri]
        self.rgb_files = None if ri is None else self._listed(rgb_list, "colour", rgb_names, rgb_lines, ri)
        for files, what in ((self.depth_files, "depth"), (self.rgb_files, "colour")):
            if files:  # an early, cheap check of the first frame's headers
                open_image(files[0], what, self.intrinsics).close()

        self.groundtruth: Optional[Trajectory] = None
        self._poses: List[Optional[np.ndarray]] = [None] * len(self)
        gt_path = self.folder / "groundtruth.txt"
        if gt_path.is_file():
            rows, _, lines = read_tum_rows(gt_path, 8, "8 values (timestamp tx ty tz qx qy qz qw)")
            gt = self.groundtruth = Trajectory.from_tum_rows(rows[time_order(rows[:, 0], gt_path, lines)])
            # Timestamps are microsecond decimals: a gap equal to max_gap in the text may exceed
            # it by a rounding error in binary, hence the 1 us slack.
            self._poses = interpolate(gt.timestamps, gt.poses, self.timestamps, max_gap + 1e-6)

    def _listed(self, list_file: Path, what: str, names: List[str], lines: List[int], keep: np.ndarray) -> List[Path]:
        """The selected images of a list, each checked to exist."""
        for k in keep:
            if not (self.folder / names[k]).is_file():
                raise FileNotFoundError(f"{list_file}:{lines[k]}: listed {what} image {self.folder / names[k]} "
                                        "does not exist")
        return [self.folder / names[k] for k in keep]

    def _meta(self, k: int) -> Dict[str, Any]:
        return {"source_index": int(self._source_index[k]), "sequence": self.name,
                "rgb_timestamp": None if self.rgb_timestamps is None else float(self.rgb_timestamps[k])}

    def _pose(self, k: int) -> Optional[np.ndarray]:
        return None if self._poses[k] is None else self._poses[k].copy()

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


def is_tum_folder(path: Any) -> bool:
    """True when ``path`` is a folder containing ``depth.txt`` (a TUM RGB-D sequence)."""
    try:
        return Path(path).is_dir() and (Path(path) / "depth.txt").is_file()
    except (TypeError, ValueError, OSError):
        return False


def depth_units(frame: Frame, depth_scale: float, where: str) -> np.ndarray:
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


def write_tum_sequence(folder: PathLike, frames: Iterable[Frame], intrinsics: Optional[Intrinsics] = None,
                       depth_scale: float = TUM_DEPTH_SCALE, write_groundtruth: bool = True, lists: bool = True) -> str:
    """Writes RGB-D frames into the TUM RGB-D layout, readable by :class:`TumSequence`: ``depth/<timestamp>.png``
    (16-bit, units of ``depth_scale`` m; integer images converted from ``Frame.depth_scale``, float images in metres;
    rounded, with 0/negative/NaN/Inf written as 0) and ``depth.txt``; with colour, ``rgb/<timestamp>.png`` and
    ``rgb.txt``; ``camera.json`` (``intrinsics``, default the frames' own, which must then agree, and ``depth_scale``);
    and, unless ``write_groundtruth`` is False, ``groundtruth.txt`` with each frame's ``T_base_camera`` (as
    ``T_world_camera``, metres) when it has one; ``lists=False``: no ``depth.txt`` / ``rgb.txt`` (the image folder of
    :class:`~scanalign.datasets.ImageFolderSequence`). Timestamps get 6 decimals; frames are written in time order; PNGs
    use zlib level 1. Returns the folder path. Raises TypeError (not a :class:`Frame`, bad ``intrinsics``), ValueError
    (no frames, mixed intrinsics or colour, size mismatch, malformed colour or pose, timestamps equal at 6 decimals or
    non-finite, depth beyond ``65535 * depth_scale``), FileExistsError (``folder`` already holds a sequence) or
    NotADirectoryError.
    """
    depth_scale = check_number("depth_scale", depth_scale, "a positive number of metres per unit", strict=True)
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
        units = depth_units(f, depth_scale, where)
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
    depth_header = f"# depth maps\n# file: '{title}' (scanalign, depth_scale {depth_scale!r} m per unit)\n"
    for name, header, lines in (("depth.txt", depth_header, depth_lines),
                                ("rgb.txt", f"# color images\n# file: '{title}' (scanalign)\n", rgb_lines)):
        if lines and lists:
            (out / name).write_text(header + "# timestamp filename\n" + "".join(lines), encoding="utf-8")
    (out / "camera.json").write_text(json.dumps({**intrinsics.to_dict(), "depth_scale": depth_scale}, indent=2) + "\n",
                                     encoding="utf-8")
    if write_groundtruth and gt_T:
        write_tum_trajectory(out / "groundtruth.txt", Trajectory(np.array(gt_t), np.stack(gt_T)),
                             header=f"ground truth trajectory\nfile: '{title}' (scanalign, T_world_camera)")
    return os.fspath(out)

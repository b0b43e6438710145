"""Pinhole cameras and RGB-D frames: what a depth sensor hands to the reconstruction.

Conventions (OpenCV / TUM): the camera frame has x to the right, y down and z along the
optical axis towards the scene; pixel ``(u, v)`` is column ``u``, row ``v``, and the
centre of pixel ``(0, 0)`` is at image coordinates ``(0, 0)``.  A point ``(x, y, z)``
in the camera frame projects to ``u = fx * x / z + cx``, ``v = fy * y / z + cy``.
Depth is the z coordinate (not the ray length), in metres.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Dict, Mapping, Optional, Union

import numpy as np
import yaml

from . import _core

__all__ = ["Intrinsics", "Frame", "INTRINSICS_PRESETS"]


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics of a depth image (no distortion: rectified images).

    Attributes:
        width, height: image size, pixels.
        fx, fy: focal lengths along x and y, pixels.
        cx, cy: principal point (column and row of the optical axis), pixels.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    def __post_init__(self) -> None:
        for name in ("width", "height", "fx", "fy", "cx", "cy"):
            v = getattr(self, name)
            if name in ("width", "height") and int(v) != v:
                raise ValueError(f"Intrinsics.{name} must be a positive integer, got {v!r}")
            object.__setattr__(self, name, int(v) if name in ("width", "height") else float(v))
        # The C++ checks (positive size and focal lengths, finite values): ValueError naming them.
        _core.reconstruction.PinholeIntrinsics(self.width, self.height, self.fx, self.fy, self.cx, self.cy)

    @property
    def K(self) -> np.ndarray:
        """The 3x3 camera matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def shape(self) -> tuple:
        """(height, width): the shape a depth image for these intrinsics must have."""
        return (self.height, self.width)

    def scaled(self, factor: float) -> "Intrinsics":
        """The intrinsics of the image resized by ``factor`` (e.g. 0.5 for half resolution)."""
        if not (factor > 0 and math.isfinite(factor)):
            raise ValueError("factor must be positive")
        w, h = int(round(self.width * factor)), int(round(self.height * factor))
        # Pixel centres sit at integer coordinates, so the principal point maps as
        # (c + 0.5) * s - 0.5.
        return Intrinsics(w, h, self.fx * factor, self.fy * factor, (self.cx + 0.5) * factor - 0.5,
                          (self.cy + 0.5) * factor - 0.5)

    def to_dict(self) -> Dict[str, Any]:
        """The fields as a dict (the keys :meth:`from_dict` reads)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Intrinsics":
        """From a mapping with keys width, height, fx, fy, cx, cy (other keys are ignored)."""
        missing = [k for k in ("width", "height", "fx", "fy", "cx", "cy") if k not in d]
        if missing:
            raise ValueError(f"intrinsics: missing keys {missing}")
        return cls(int(d["width"]), int(d["height"]), float(d["fx"]), float(d["fy"]), float(d["cx"]),
                   float(d["cy"]))

    @classmethod
    def preset(cls, name: str) -> "Intrinsics":
        """A named preset from :data:`INTRINSICS_PRESETS` (e.g. ``"tum_fr1"``, ``"sr300"``)."""
        try:
            return INTRINSICS_PRESETS[name]
        except KeyError:
            raise ValueError(f"unknown intrinsics preset {name!r}; known: {sorted(INTRINSICS_PRESETS)}") from None

    @classmethod
    def from_file(cls, path: Union[str, os.PathLike]) -> "Intrinsics":
        """Reads a JSON or YAML file (:func:`read_camera_file`) with keys width, height, fx,
        fy, cx, cy. Other keys (e.g. ``depth_scale``) are ignored here; see
        :func:`read_camera_file` for them."""
        return cls.from_dict(read_camera_file(path))


#: A number in exponent notation, which YAML 1.1 (PyYAML) reads as a string unless it has a dot.
_EXPONENT_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")


def read_camera_file(path: Union[str, os.PathLike]) -> Dict[str, Any]:
    """Reads a small camera description, JSON or YAML (a leading OpenCV ``%YAML:1.0`` line,
    which YAML parsers reject as a directive, is skipped), as a mapping; strings that are
    numbers in exponent notation (``1e-3``, which YAML 1.1 reads as text) become floats.

    Raises:
        OSError: the file cannot be read.
        ValueError: not valid JSON/YAML, or not a mapping (naming the file).
    """
    text = Path(path).read_text(encoding="utf-8")
    as_json = str(path).lower().endswith(".json") or text.lstrip().startswith("{")
    try:  # JSON is nearly YAML, but not quite (tabs, escapes): a JSON file is read as JSON
        d = json.loads(text) if as_json else yaml.safe_load(re.sub(r"\A%YAML:1\.0[^\n]*", "", text))
    except (json.JSONDecodeError, yaml.YAMLError) as e:
        raise ValueError(f"{path}: not valid JSON or YAML: {e}") from None
    if not isinstance(d, dict):
        raise ValueError(f"{path}: expected 'key: value' entries, got {type(d).__name__}")
    return {k: float(v) if isinstance(v, str) and _EXPONENT_NUMBER.fullmatch(v) else v for k, v in d.items()}


#: Named intrinsics. TUM values are from the TUM RGB-D benchmark's published calibration
#: (depth images are registered to the colour camera); the sensor presets are typical
#: factory values of the depth stream at 640x480.
INTRINSICS_PRESETS: Dict[str, Intrinsics] = {
    "tum_default": Intrinsics(640, 480, 525.0, 525.0, 319.5, 239.5),
    "tum_fr1": Intrinsics(640, 480, 517.3, 516.5, 318.6, 255.3),
    "tum_fr2": Intrinsics(640, 480, 520.9, 521.0, 325.1, 249.7),
    "tum_fr3": Intrinsics(640, 480, 535.4, 539.2, 320.1, 247.6),
    "sr300": Intrinsics(640, 480, 475.0, 475.0, 319.5, 239.5),
    "d435": Intrinsics(640, 480, 385.0, 385.0, 319.5, 239.5),
}


@dataclass
class Frame:
    """One RGB-D capture.

    Attributes:
        depth: (H, W) depth image: uint16 in units of ``depth_scale`` metres (0 = no
            measurement), or float32/float64 in metres (0 or NaN = no measurement).
        intrinsics: the pinhole intrinsics of ``depth`` (its shape must be (H, W)).
        rgb: optional (H, W, 3) uint8 colour image registered to the depth image.
        depth_scale: metres per unit of an integer depth image (1e-3 for millimetres,
            1/5000 for the TUM RGB-D benchmark). Ignored for float depth.
        timestamp: capture time, seconds.
        T_base_camera: optional 4x4 reference pose of the camera in the robot's base frame
            (maps camera coordinates into base coordinates), e.g. from forward kinematics
            and the hand-eye calibration, or a motion-capture ground truth.
        index: position of the frame in its sequence.
    """

    depth: np.ndarray
    intrinsics: Intrinsics
    rgb: Optional[np.ndarray] = None
    depth_scale: float = 0.001
    timestamp: float = 0.0
    T_base_camera: Optional[np.ndarray] = None
    index: int = 0
    meta: Dict[str, Any] = field(default_factory=dict)

    def depth_metres(self) -> np.ndarray:
        """The depth image as float32 metres, with NaN where there is no measurement."""
        d = np.asarray(self.depth)
        if np.issubdtype(d.dtype, np.integer) and not 0 < self.depth_scale <= 1:  # as depth_to_cloud
            raise ValueError(f"depth_scale must be in (0, 1] metres per unit, got {self.depth_scale!r}")
        out = d.astype(np.float32) * np.float32(self.depth_scale if np.issubdtype(d.dtype, np.integer) else 1.0)
        out[~(out > 0)] = np.nan  # 0 (also NaN, negative) = no measurement
        return out


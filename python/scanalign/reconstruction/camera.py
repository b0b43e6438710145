"""Pinhole cameras and RGB-D frames: what a depth sensor hands to the reconstruction.

Conventions (OpenCV / TUM): the camera frame has x to the right, y down and z along the optical axis towards the scene;
pixel ``(u, v)`` is column ``u``, row ``v``, and the centre of pixel ``(0, 0)`` is at image coordinates ``(0, 0)``. A
point ``(x, y, z)`` in the camera frame projects to ``u = fx * x / z + cx``, ``v = fy * y / z + cy``. Depth is the z
coordinate (not the ray length), in metres.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Mapping, Optional, Tuple, Union

import numpy as np
import yaml

from scanalign import _core

__all__ = ["Intrinsics", "Frame", "INTRINSICS_PRESETS", "read_camera_file", "read_camera", "camera_from_dict",
           "intrinsics_from_dict", "intrinsics_preset", "NO_DISTORTION", "sequence_index"]

#: The distortion of a pinhole camera (rectified images): k1 k2 p1 p2 k3 all zero.
NO_DISTORTION: Tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)


#: Intrinsics of a depth image: the C++ ``PinholeIntrinsics``, the library's one intrinsics type,
#: bound as it is (its fields, units and methods documented there: ``help(Intrinsics)``).
#: ``Intrinsics(width, height, fx, fy, cx, cy, distortion=(0,)*5)`` validates (ValueError naming
#: the field); ``distortion`` is Brown-Conrady ``(k1, k2, p1, p2, k3)``, OpenCV's order, which
#: back-projection undoes. Presets: :func:`intrinsics_preset`; camera files: :func:`read_camera`.
Intrinsics = _core.reconstruction.PinholeIntrinsics


def intrinsics_from_dict(d: Mapping[str, Any]) -> Intrinsics:
    """Intrinsics from a mapping with keys width, height, fx, fy, cx, cy and optional distortion (k1, k2, p1, p2, k3);
    other keys are ignored. :func:`camera_from_dict` also reads ROS ``camera_info`` and OpenCV calibration layouts."""
    if missing := [k for k in ("width", "height", "fx", "fy", "cx", "cy") if k not in d]:
        raise ValueError(f"intrinsics: missing keys {missing}")
    dist = d.get("distortion")
    # No int() / float() here: the constructor checks each value and names it (a string or an
    # infinite size is an error, not parsed or an OverflowError).
    return Intrinsics(d["width"], d["height"], d["fx"], d["fy"], d["cx"], d["cy"],
                      NO_DISTORTION if dist is None else _distortion5(dist, d.get("distortion_model")))


def intrinsics_preset(name: str) -> Intrinsics:
    """A named preset from :data:`INTRINSICS_PRESETS` (e.g. ``"tum_fr1"``, ``"sr300"``)."""
    try:
        return INTRINSICS_PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown intrinsics preset {name!r}; known: {sorted(INTRINSICS_PRESETS)}") from None


class _CameraYamlLoader(yaml.SafeLoader):
    """PyYAML's safe loader plus what camera files need (:func:`read_camera_file`): OpenCV's ``!!opencv-matrix`` and
    exponent notation without a dot or sign (``1e-3``: a float in YAML 1.2 and JSON, text in YAML 1.1)."""


_CameraYamlLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."))


def _opencv_matrix(loader: yaml.SafeLoader, node: yaml.Node) -> np.ndarray:
    m = loader.construct_mapping(node, deep=True)
    try:
        rows, cols, data = int(m["rows"]), int(m["cols"]), m["data"]
        return np.asarray(data, dtype=np.float64).reshape(rows, cols)
    except (KeyError, TypeError, ValueError) as e:
        raise yaml.constructor.ConstructorError(None, None, f"malformed !!opencv-matrix ({type(e).__name__}: {e}): "
                                                "expected rows, cols and rows x cols numbers in data",
                                                node.start_mark) from None


_CameraYamlLoader.add_constructor("tag:yaml.org,2002:opencv-matrix", _opencv_matrix)


def read_camera_file(path: Union[str, os.PathLike]) -> Dict[str, Any]:
    """Reads a small camera description, JSON or YAML, as a mapping, with PyYAML: a leading OpenCV ``%YAML:1.0`` line (a
    directive YAML parsers reject) is skipped, OpenCV's ``!!opencv-matrix`` entries become float64 arrays of their
    shape, and numbers in exponent notation (``1e-3``, which YAML 1.1 reads as text) are floats. The keys are as
    written; :func:`read_camera` / :func:`camera_from_dict` interpret them. OSError: the file cannot be read;
    ValueError: not valid JSON/YAML, or not a mapping (naming the file)."""
    text = Path(path).read_text(encoding="utf-8")
    as_json = str(path).lower().endswith(".json") or text.lstrip().startswith("{")
    try:  # JSON is nearly YAML, but not quite (tabs, escapes): a JSON file is read as JSON
        d = json.loads(text) if as_json else yaml.load(re.sub(r"\A%YAML:1\.0[^\n]*", "", text),
                                                       Loader=_CameraYamlLoader)
    except (json.JSONDecodeError, yaml.YAMLError) as e:
        raise ValueError(f"{path}: not valid JSON or YAML: {e}") from None
    if not isinstance(d, dict):
        raise ValueError(f"{path}: expected 'key: value' entries, got {type(d).__name__}")
    return d


#: Distortion models whose coefficients are Brown-Conrady's k1 k2 p1 p2 k3 (ROS names,
#: RealSense's, OpenCV's); "rational_polynomial" (8 coefficients) is accepted when its
#: k4 k5 k6 are zero. Any model is accepted when all its coefficients are zero.
_BROWN_CONRADY = ("plumb_bob", "brown_conrady", "modified_brown_conrady", "rational_polynomial", "opencv", "radtan")


def _distortion5(values: Any, model: Any = None) -> Tuple[float, ...]:
    """(k1, k2, p1, p2, k3) from a coefficient list (4, 5, 8, 12 or 14 numbers, OpenCV's
    order; beyond the fifth they must be zero) of a Brown-Conrady model."""
    v = _numbers(values, None, "distortion coefficients")
    if v.size == 0 or not np.any(v != 0):
        return NO_DISTORTION
    name = None if model is None else str(model).strip().lower().replace(" ", "_").replace("-", "_")
    if name is not None and name not in _BROWN_CONRADY:
        raise ValueError(f"distortion model {model!r} is not supported: back-projection undistorts the Brown-Conrady "
                         f"('plumb_bob') model k1 k2 p1 p2 k3 only (models read: {', '.join(_BROWN_CONRADY)})")
    if v.size not in (4, 5, 8, 12, 14):
        raise ValueError(f"distortion: expected 4, 5, 8, 12 or 14 coefficients (OpenCV's order k1 k2 p1 p2 [k3 ...]), "
                         f"got {v.size}")
    if np.any(v[5:] != 0):
        raise ValueError(f"distortion coefficients beyond k1 k2 p1 p2 k3 are not supported (rational / thin-prism / "
                         f"tilt terms {v[5:].tolist()} must be zero)")
    return tuple(float(x) for x in np.r_[v, 0.0][:5])  # k3 = 0 when 4 are given


def _first(d: Mapping[str, Any], *keys: str) -> Any:
    return next((d[k] for k in keys if k in d and d[k] is not None), None)


def _numbers(value: Any, n: Optional[int], what: str) -> np.ndarray:
    """A matrix entry as a flat float64 array: a list, an array (OpenCV), or a ROS ``{rows, cols, data}`` mapping."""
    if isinstance(value, Mapping):
        value = value.get("data")
    try:
        a = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise ValueError(f"{what}: expected numbers, got {value!r}") from None
    if n is not None and a.size != n:
        raise ValueError(f"{what}: expected {n} numbers, got {a.size}")
    return a


def camera_from_dict(d: Mapping[str, Any]) -> Tuple[Intrinsics, Optional[float]]:
    """Intrinsics (with distortion) and the optional ``depth_scale`` (m per unit) from a camera description in any of
    the layouts :func:`read_camera` reads:

    - scanalign's flat keys: ``width height fx fy cx cy`` (+ optional ``distortion``: k1 k2 p1 p2 k3, ``depth_scale``);
    - a ROS ``camera_info`` YAML (``camera_calibration_parsers``): ``image_width``, ``image_height``,
      ``camera_matrix: {rows, cols, data}``, ``distortion_model``, ``distortion_coefficients: {rows, cols, data}``; or a
      CameraInfo message as YAML (``width``, ``height``, ``K``/``k`` 9 numbers, ``D``/``d``, ``distortion_model``);
    - an OpenCV calibration file (``%YAML:1.0``; ``camera_matrix`` / ``cameraMatrix`` / ``K`` and
      ``distortion_coefficients`` / ``distCoeffs`` / ``D`` as ``!!opencv-matrix``, ``image_width`` / ``image_height``).

    Distortion: Brown-Conrady coefficients in OpenCV's order (4, 5, 8, 12 or 14 numbers, those after k3 zero); another
    non-zero model is a ValueError, as are missing keys, malformed numbers and invalid intrinsics (the message says
    which).
    """
    if not isinstance(d, Mapping):
        raise ValueError(f"camera: expected a mapping, got {type(d).__name__}")
    scale = d.get("depth_scale")
    if scale is not None and (isinstance(scale, bool) or not isinstance(scale, (int, float, np.number))
                              or not (math.isfinite(float(scale)) and 0 < float(scale))):
        raise ValueError(f"depth_scale must be a positive number of metres per unit, got {scale!r}")
    scale = None if scale is None else float(scale)
    K = _first(d, "camera_matrix", "cameraMatrix", "K", "k", "intrinsic_matrix")
    flat = any(k in d for k in ("fx", "fy", "cx", "cy")) or K is None
    model = _first(d, "distortion_model", "distortionModel")
    dist = _first(d, "distortion", "distortion_coefficients", "distCoeffs", "dist_coeffs", "D", "d")
    if flat:
        return intrinsics_from_dict({**d, "distortion": dist, "distortion_model": model}), scale
    K = _numbers(K, 9, "camera_matrix")
    if K[1] != 0 or K[3] != 0 or K[6] != 0 or K[7] != 0 or K[8] != 1:
        raise ValueError(f"camera_matrix must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), got {K.tolist()}")
    width, height = _first(d, "image_width", "width", "imageWidth"), _first(d, "image_height", "height", "imageHeight")
    if width is None or height is None:
        raise ValueError("camera: missing the image size (image_width and image_height, or width and height)")
    distortion = NO_DISTORTION if dist is None else _distortion5(dist, model)
    return Intrinsics(width, height, K[0], K[4], K[2], K[5], distortion), scale


def read_camera(path: Union[str, os.PathLike]) -> Tuple[Intrinsics, Optional[float]]:
    """Intrinsics (with distortion) and the optional ``depth_scale`` (m per unit) of a camera file: JSON or YAML in any
    layout of :func:`camera_from_dict` (scanalign's flat keys, ROS ``camera_info`` YAML, OpenCV calibration YAML), read
    by :func:`read_camera_file`. OSError: the file cannot be read. ValueError: malformed file or camera, naming the
    file."""
    d = read_camera_file(path)
    try:
        return camera_from_dict(d)
    except (ValueError, TypeError) as e:
        raise ValueError(f"{path}: {e}") from None


#: Named intrinsics. TUM values are from the TUM RGB-D benchmark's published calibration (depth images are registered to
#: the colour camera); the sensor presets are typical factory values of the depth stream at 640x480 (the Kinect One's
#: at its native 512x424, about 70 x 60 deg).
INTRINSICS_PRESETS: Dict[str, Intrinsics] = {
    "tum_default": Intrinsics(640, 480, 525.0, 525.0, 319.5, 239.5),
    "tum_fr1": Intrinsics(640, 480, 517.3, 516.5, 318.6, 255.3),
    "tum_fr2": Intrinsics(640, 480, 520.9, 521.0, 325.1, 249.7),
    "tum_fr3": Intrinsics(640, 480, 535.4, 539.2, 320.1, 247.6),
    "sr300": Intrinsics(640, 480, 475.0, 475.0, 319.5, 239.5),
    "d435": Intrinsics(640, 480, 385.0, 385.0, 319.5, 239.5),
    "kinect_one": Intrinsics(512, 424, 365.0, 365.0, 255.5, 211.5),
}


@dataclass
class Frame:
    """One RGB-D capture: ``depth``, an (H, W) image, uint16 in units of ``depth_scale`` metres (0 = no measurement) or
    float32/float64 in metres (0 or NaN = no measurement), and its pinhole ``intrinsics`` (their shape must be (H, W));
    an optional (H, W, 3) uint8 ``rgb`` image registered to the depth image; ``depth_scale``, metres per unit of an
    integer depth image (1e-3 for millimetres, 1/5000 for the TUM RGB-D benchmark; ignored for float depth);
    ``timestamp``, the capture time in seconds; ``T_base_camera``, an optional 4x4 reference pose of the camera in the
    robot's base frame (maps camera coordinates into base coordinates), e.g. from forward kinematics and the hand-eye
    calibration, or a motion-capture ground truth; ``index``, the frame's position in its sequence."""

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


def sequence_index(i: Any, n: int, what: str) -> int:
    """Frame ``i`` of a sequence of ``n`` frames (negative counts from the end) as a
    non-negative index; TypeError naming ``what`` for a non-integer, IndexError out of range."""
    if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
        raise TypeError(f"{what} indices must be integers, got {type(i).__name__}")
    k = int(i) + n if i < 0 else int(i)
    if not 0 <= k < n:
        raise IndexError(f"frame index {i} out of range for a sequence of {n} frames")
    return k

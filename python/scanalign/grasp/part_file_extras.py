"""What a part file adds for the two-step pose and assembly (Kleppe et al., "Automated assembly using 3D and 2D
cameras", Robotics 6 (2017) 14, the thesis's Paper 3): the part's top-face reference image, which the hand camera's
2D step matches, and where the part goes when it is assembled onto another part.

Part-file fields (schema in docs/api/grasp.md)::

    reference_image:               # an orthographic top view: pixel u along model +x, pixel v along model -y
      image: top.png               # a grey or colour image file (relative to the part file), or builtin:label-<seed>
                                   # / builtin:plain (scanalign.data.labels; then give size)
      pixels_per_metre: 5000       # px/m
      top_height: 0.015            # m, the labelled face's height above the model origin (model z)
      origin_pixel: [199.5, 124.5] # px, the pixel above the model origin (default the image centre)
      size: [0.08, 0.05]           # m (x, y), only for a built-in label: its size in pixels is size x pixels_per_metre
    assembly:
      onto: bracket                # the part it is placed on (its name)
      onto_file: bracket.json      # that part's file, relative to this one (default: the built-in part of that name)
      T_onto_part: [[...]]         # 4x4 rigid: this part's model frame in the other part's, when assembled (m)
      tolerance_translation: 0.001 # m, how far the placed part may lie from T_onto_part (at its symmetry point)
      tolerance_angle: 0.0175      # rad, how far it may turn from it (up to its symmetry)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Optional, Tuple

import numpy as np

from scanalign.common.rigid import require_rigid
from scanalign.pose.image_matching import ReferenceImageGeometry

__all__ = ["ReferenceImage", "AssemblyTarget", "parse_reference_image", "parse_assembly", "dump_reference_image",
           "dump_assembly"]

_REFERENCE_KEYS = {"image", "pixels_per_metre", "top_height", "origin_pixel", "size"}
_ASSEMBLY_KEYS = {"onto", "onto_file", "T_onto_part", "tolerance_translation", "tolerance_angle"}


@dataclass
class ReferenceImage:
    """A part's top-face reference image. ``image``: a file path (relative to the part file), a built-in label name, or
    (once loaded by :func:`scanalign.grasp.parts.load_part`) the (H, W) uint8 grey array."""

    image: Any
    pixels_per_metre: float
    top_height: float  #: m above the model origin
    origin_pixel: Optional[Tuple[float, float]] = None  #: px; None: the image centre
    size: Optional[Tuple[float, float]] = None  #: m, a built-in label's (x, y) size

    def geometry(self) -> Any:
        """The :class:`scanalign.pose.image_matching.ReferenceImageGeometry` of a loaded image."""
        if not isinstance(self.image, np.ndarray):
            raise ValueError("reference_image: load the part first (scanalign.grasp.parts.load_part): the image is "
                             f"still the name {self.image!r}")
        h, w = self.image.shape[:2]
        origin = self.origin_pixel if self.origin_pixel is not None else ((w - 1) / 2.0, (h - 1) / 2.0)
        g = ReferenceImageGeometry(width=w, height=h, pixels_per_metre=self.pixels_per_metre,
                                   origin_pixel=tuple(origin), top_height=self.top_height)
        g.validate()
        return g


@dataclass
class AssemblyTarget:
    """Where a part goes when assembled: onto the part named ``onto``, its model frame at ``T_onto_part`` (4x4, m) in
    that part's model frame, within ``tolerance_translation`` (m) and ``tolerance_angle`` (rad)."""

    onto: str
    T_onto_part: np.ndarray
    tolerance_translation: float = 0.001
    tolerance_angle: float = math.radians(1.0)
    #: the other part's file (as read: resolved against this part file's folder); None: the built-in part ``onto``
    onto_file: Optional[str] = None

    def onto_source(self) -> str:
        """What :func:`scanalign.grasp.parts.load_part` takes for the other part."""
        return self.onto_file or self.onto


def _number(where: str, key: str, value: Any, positive: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or (positive and value <= 0):
        raise ValueError(f"{where}: field {key!r} must be a {'positive ' if positive else ''}finite number, "
                         f"got {value!r}")
    return float(value)


def _pair(where: str, key: str, value: Any) -> Tuple[float, float]:
    a = np.asarray(value, dtype=object)
    if a.shape != (2,) or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                                  for v in a):
        raise ValueError(f"{where}: field {key!r} must be two finite numbers, got {value!r}")
    return float(a[0]), float(a[1])


def _fields(where: str, data: Any, allowed: set, required: set) -> Dict[str, Any]:
    if not isinstance(data, dict):
        raise ValueError(f"{where}: expected a mapping, got {type(data).__name__}")
    if unknown := sorted(set(data) - allowed):
        raise ValueError(f"{where}: unknown field(s) {unknown} (expected {sorted(allowed)})")
    if missing := sorted(required - set(data)):
        raise ValueError(f"{where}: missing field(s) {missing}")
    return data


def parse_reference_image(where: str, data: Any) -> ReferenceImage:
    """A part file's ``reference_image`` mapping; ValueError naming ``where`` and the field."""
    d = _fields(where, data, _REFERENCE_KEYS, {"image", "pixels_per_metre", "top_height"})
    if not isinstance(d["image"], str) or not d["image"]:
        raise ValueError(f"{where}: field 'image' must be a file name or builtin:label-<seed> / builtin:plain")
    builtin = d["image"].startswith("builtin:")
    if builtin != ("size" in d):
        raise ValueError(f"{where}: field 'size' (m) is needed for a built-in label and only for one")
    size = _pair(where, "size", d["size"]) if builtin else None
    if size is not None and min(size) <= 0:
        raise ValueError(f"{where}: field 'size' must be positive, got {d['size']!r}")
    return ReferenceImage(image=d["image"], pixels_per_metre=_number(where, "pixels_per_metre", d["pixels_per_metre"]),
                          top_height=_number(where, "top_height", d["top_height"], positive=False),
                          origin_pixel=_pair(where, "origin_pixel", d["origin_pixel"]) if "origin_pixel" in d else None,
                          size=size)


def parse_assembly(where: str, data: Any, folder: Path = Path(".")) -> AssemblyTarget:
    """A part file's ``assembly`` mapping (``onto_file`` resolved against ``folder``); ValueError naming ``where`` and
    the field."""
    d = _fields(where, data, _ASSEMBLY_KEYS, {"onto", "T_onto_part"})
    for key in ("onto", "onto_file"):
        if key in d and (not isinstance(d[key], str) or not d[key]):
            raise ValueError(f"{where}: field {key!r} must be a {'part name' if key == 'onto' else 'file name'}, "
                             f"got {d[key]!r}")
    try:
        T = require_rigid(d["T_onto_part"], "field 'T_onto_part'")
    except (TypeError, ValueError) as e:
        raise ValueError(f"{where}: {e}") from None
    default = AssemblyTarget("", np.eye(4))
    return AssemblyTarget(d["onto"], np.asarray(T, dtype=np.float64),
                          _number(where, "tolerance_translation",
                                  d.get("tolerance_translation", default.tolerance_translation)),
                          _number(where, "tolerance_angle", d.get("tolerance_angle", default.tolerance_angle)),
                          str(folder / d["onto_file"]) if "onto_file" in d else None)


def dump_reference_image(r: ReferenceImage) -> Dict[str, Any]:
    """The part-file mapping of ``r`` (its image must still be a name)."""
    if not isinstance(r.image, (str, Path)):
        raise ValueError("reference_image: only an image file name or a built-in label can be written, got an array")
    out: Dict[str, Any] = {"image": str(r.image), "pixels_per_metre": float(r.pixels_per_metre),
                           "top_height": float(r.top_height)}
    if r.origin_pixel is not None:
        out["origin_pixel"] = [float(v) for v in r.origin_pixel]
    if r.size is not None:
        out["size"] = [float(v) for v in r.size]
    return out


def dump_assembly(a: AssemblyTarget, folder: Path = Path(".")) -> Dict[str, Any]:
    """The part-file mapping of ``a`` (``onto_file`` relative to ``folder`` when it lies below it)."""
    out: Dict[str, Any] = {"onto": a.onto, "T_onto_part": np.asarray(a.T_onto_part, dtype=np.float64).tolist(),
                           "tolerance_translation": float(a.tolerance_translation),
                           "tolerance_angle": float(a.tolerance_angle)}
    if a.onto_file is not None:
        f = Path(a.onto_file)
        out["onto_file"] = str(f.relative_to(folder)) if f.is_relative_to(folder) else str(f)
    return out

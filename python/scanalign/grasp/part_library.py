"""A part library: each known part's CAD views and CBD descriptors computed once, saved to disk.

Rendering a part's 42 views takes milliseconds; describing them (CBD keypoints and
descriptors, thesis ch. 6) takes about a second per part, and :func:`scanalign.pose.find_parts`
would otherwise repeat it for every object cluster of every scene. A library describes each
view once (C++ ``describeModelViews``, cached in ``ModelView.cbd``); ``find_parts`` and
``estimate_pose`` reuse those descriptors whenever they run with the same pose settings
(:attr:`PartLibrary.pose_settings`), else they recompute and the result is unchanged.

The file is a NumPy ``.npz`` read with ``allow_pickle=False`` (no code runs on load): a
``format`` entry (:data:`FORMAT_VERSION`), the settings as JSON, and per part its model (a
mesh's vertices and faces, or a scanned model cloud's points and normals), symmetry and views, each view as the flat state dict its C++ class pickles to
(``ModelView.__getstate__``). A file of another format version is refused with a
ValueError saying so; rebuild it with :func:`build_part_library`.
"""

from __future__ import annotations

import json
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Union

import numpy as np
from tqdm.auto import tqdm

from scanalign import __version__, io, pose
from scanalign._core import pose as _P
from scanalign.grasp import PartSymmetry
from scanalign.grasp.parts import load_part
from scanalign.io.interop import Cloud
from scanalign.pose import model_views as cad

__all__ = ["FORMAT_VERSION", "LibraryPart", "PartLibrary", "build_part_library", "load_part_library"]

#: Version of the on-disk layout; bumped whenever a state field changes meaning.
FORMAT_VERSION = 1

PathLike = Union[str, "os.PathLike[str]"]


@dataclass
class LibraryPart:
    """One part: its mesh (model frame, metres), symmetry and described views."""

    name: str
    mesh: io.Mesh
    symmetry: Any                                   #: scanalign.grasp.PartSymmetry
    views: List[Any] = field(default_factory=list)  #: scanalign.pose.model_views.ModelView, ``cbd`` filled in


@dataclass
class PartLibrary:
    """Parts by name with the settings their views were rendered and described with.

    Attributes:
        parts: name -> :class:`LibraryPart`, in the order they were added.
        resolution: view image size, pixels (``find_parts``'s default 100).
        pose_settings: the keywords of :func:`scanalign.pose.find_parts` the descriptors were
            computed for (``inlier_threshold``, ``radius``, ``cbd_radius_fraction``...); calls
            with other CBD settings recompute them.
    """

    parts: Dict[str, LibraryPart]
    resolution: int = 100
    pose_settings: Dict[str, Any] = field(default_factory=dict)

    def models(self, names: Sequence[str]) -> List[List[Any]]:
        """The described views of each named part, as ``find_parts(models=...)`` takes them."""
        return [self[n].views for n in names]

    def __getitem__(self, name: str) -> LibraryPart:
        if name not in self.parts:
            raise KeyError(f"part {name!r} is not in the library ({', '.join(self.parts)})")
        return self.parts[name]

    def __contains__(self, name: object) -> bool:
        return name in self.parts

    def save(self, path: PathLike) -> Path:
        """Writes the library as an ``.npz`` (see the module docstring); returns the path."""
        arrays: Dict[str, Any] = {"format": np.array(FORMAT_VERSION), "meta": np.array(json.dumps(
            {"scanalign": __version__, "resolution": self.resolution, "pose_settings": self.pose_settings,
             "parts": list(self.parts)}))}
        for i, part in enumerate(self.parts.values()):
            p = f"part{i}/"
            s = part.symmetry
            arrays.update(_model_arrays(p, part.mesh))
            arrays.update({p + "symmetry": np.r_[s.axis, s.point, s.order].astype(np.float64),
                           p + "views": np.array(len(part.views))})
            arrays.update({f"{p}view{k}/{key}": np.asarray(value) for k, view in enumerate(part.views)
                           for key, value in view.__getstate__().items()})
        path = Path(path)
        with io.atomic_open(path, "wb") as f:
            np.savez(f, **arrays)
        return path


def _model_arrays(prefix: str, model: Any) -> Dict[str, np.ndarray]:
    """A part's model as library arrays: a mesh's vertices and faces, or a model cloud's points (and normals)."""
    if isinstance(model, Cloud):
        out = {prefix + "points": np.asarray(model.points, dtype=np.float64)}
        if model.normals is not None:
            out[prefix + "normals"] = np.asarray(model.normals, dtype=np.float64)
        return out
    return {prefix + "vertices": np.asarray(model.vertices), prefix + "faces": np.asarray(model.faces)}


def build_part_library(parts: Sequence[Any], *, resolution: Optional[int] = None, progress: bool = False,
                       **pose_settings: Any) -> PartLibrary:
    """Renders and describes each part once.

    Args:
        parts: what :func:`scanalign.grasp.parts.load_part` takes: part files (JSON / YAML), built-in
            part names (``"block"``, ``"bracket"``, ``"standoff"``) or ``PartGrasps``.
        resolution: view size, pixels (None: ``FindPartsSettings.pose.views.resolution``, as
            ``find_parts`` renders).
        progress: a progress bar over the parts on stderr.
        pose_settings: keywords of :func:`scanalign.pose.find_parts` (``inlier_threshold``,
            ``radius``, ``cbd_radius_fraction``...), the ones the pose jobs will use; default
            its defaults. With ``cbd_radius_fraction`` each part is described at its own radius.

    Raises:
        ValueError: an unknown part, a malformed mesh, or bad settings.
    """
    # validates the keywords before any work
    settings = pose.pose_task_settings(pose.FindPartsSettings, **pose_settings)
    resolution = settings.pose.views.resolution if resolution is None else resolution
    out: Dict[str, LibraryPart] = {}
    for source in tqdm(list(parts), desc="part library", unit="part", disable=not progress):
        part = load_part(source)
        view_settings = settings.pose.views  # the cameras (and a model cloud's settings) find_parts will use
        view_settings.resolution = int(resolution)
        views = cad.model_views(part.mesh, view_settings)  # a mesh rendered, or a scanned cloud's visible subsets
        described = _P.describe_model_views(views, _P.part_pose_settings(views, settings))
        out[part.name] = LibraryPart(part.name, part.mesh, part.symmetry, described)
    return PartLibrary(out, int(resolution), dict(pose_settings))


def _view(data: Dict[str, np.ndarray], prefix: str) -> Any:
    """The ModelView saved under ``prefix``: its state dict, one entry per key."""
    view = _P.ModelView.__new__(_P.ModelView)
    view.__setstate__({k[len(prefix):]: v.item() if v.ndim == 0 else v for k, v in data.items()
                       if k.startswith(prefix)})
    return view


def load_part_library(path: PathLike) -> PartLibrary:
    """Reads a library written by :meth:`PartLibrary.save`, without recomputing anything.

    Raises:
        ValueError: not a part library, another :data:`FORMAT_VERSION`, or a corrupt file
            (the message starts with the path).
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as e:
        raise ValueError(f"{path}: not a readable part library ({e})") from None
    if "format" not in data or "meta" not in data:
        raise ValueError(f"{path}: not a scanalign part library (no 'format' entry)")
    if int(data["format"]) != FORMAT_VERSION:
        raise ValueError(f"{path}: part library format {int(data['format'])}, this scanalign reads "
                         f"{FORMAT_VERSION}: rebuild it with build_part_library")
    try:
        meta = json.loads(str(data["meta"]))
        parts: Dict[str, LibraryPart] = {}
        for i, name in enumerate(meta["parts"]):
            p = f"part{i}/"
            views = [_view(data, f"{p}view{k}/") for k in range(int(data[p + "views"]))]
            s = data[p + "symmetry"]
            model = (io.Mesh(data[p + "vertices"], data[p + "faces"]) if p + "faces" in data
                     else Cloud(data[p + "points"], data.get(p + "normals")))
            parts[name] = LibraryPart(name, model, PartSymmetry(axis=s[:3], point=s[3:6], order=int(s[6])), views)
    except (KeyError, TypeError, ValueError) as e:
        raise ValueError(f"{path}: corrupt part library ({type(e).__name__}: {e})") from None
    return PartLibrary(parts, int(meta["resolution"]), dict(meta["pose_settings"]))

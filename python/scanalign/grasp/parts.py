"""A part ready to be found and picked: its model in metres (a CAD mesh, or a scanned model cloud), grasps, symmetry
and gripper,
from a part file (JSON / YAML, :func:`scanalign.grasp.read_part_grasps`), a built-in part
name or a :class:`scanalign.grasp.PartGrasps`."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Dict, Optional

import numpy as np

from scanalign import io
from scanalign.common.rigid import require_rigid, transform_points
from scanalign.data.labels import builtin_label
from scanalign.data.parts import builtin_mesh, sample_mesh
from scanalign.evaluation import MeshDistanceIndex
from scanalign.grasp import Gripper, PartGrasps, PartSymmetry, ReferenceImage, read_part_grasps
from scanalign.io.interop import Cloud
from scanalign.pose.model_views import read_model, surface_points

__all__ = ["BUILTIN_PART_FILES", "SYMMETRY_TOLERANCE", "check_symmetry", "load_part"]

#: Built-in part name -> its part file (mesh, grasps, symmetry): the parts of
#: :data:`scanalign.data.parts.BUILTIN_PARTS` with grasps for a parallel-jaw gripper.
BUILTIN_PART_FILES: Dict[str, Path] = {p.stem: p for p in sorted((Path(__file__).parents[1] / "data" / "parts").glob("*.json"))}
#: How far a declared symmetry may move the surface off itself, as a fraction of the part's size
#: (:func:`check_symmetry`): 0.5 mm on a 50 mm part. A 6-fold symmetry on a regular octagonal
#: prism as tall as wide is off by 3.4 %; a cylinder of 16 or more segments is a body of revolution.
SYMMETRY_TOLERANCE = 0.01


def load_part(source: Any) -> Any:
    """A part ready for :func:`pick`: a part file (JSON / YAML, :func:`scanalign.grasp.read_part_grasps`),
    a built-in part name (:data:`BUILTIN_PART_FILES`) or a :class:`scanalign.grasp.PartGrasps`,
    with its mesh loaded into the model frame in metres (``"builtin:<name>"``, or a mesh file
    relative to the part file, times ``scale``, then moved by ``T_model_mesh``), its symmetry
    (default none, checked against the mesh: :func:`check_symmetry`) and gripper (default
    :meth:`scanalign.grasp.Gripper.parallel_jaw`) filled in."""
    where, what = Path("."), None
    if isinstance(source, PartGrasps):
        part = source
    else:
        path = BUILTIN_PART_FILES.get(str(source), Path(source))
        if not path.is_file():
            raise ValueError(f"part {str(source)!r}: no such part file, and not a built-in part "
                             f"({', '.join(BUILTIN_PART_FILES)})")
        part, where, what = read_part_grasps(path), path.parent, str(path)
    mesh = part.mesh
    if isinstance(mesh, str):
        mesh = (builtin_mesh(name=mesh[len("builtin:"):]) if mesh.startswith("builtin:")
                else read_model(where / mesh))
        mesh = _scaled(mesh, part.scale)
    if not isinstance(mesh, (io.Mesh, Cloud)):
        raise ValueError(f"part {part.name!r}: no model (give 'mesh' in the part file: a mesh file, a scanned model "
                         "cloud (.pcd, .ply without faces) or builtin:<name>)")
    if part.T_model_mesh is not None:
        mesh = _moved(mesh, require_rigid(part.T_model_mesh, "T_model_mesh"))
    symmetry = part.symmetry or PartSymmetry()
    check_symmetry(mesh, symmetry, what or f"part {part.name!r}")
    return dataclasses.replace(part, mesh=mesh, scale=1.0, T_model_mesh=None, symmetry=symmetry,
                               gripper=part.gripper or Gripper.parallel_jaw(),
                               reference_image=_loaded_reference(part.reference_image, where, what or part.name))


def _scaled(model: Any, scale: float) -> Any:
    """A mesh or model cloud with its coordinates times ``scale`` (normals unchanged)."""
    if isinstance(model, Cloud):
        return model._replace(points=np.asarray(model.points, dtype=np.float64) * scale)
    return io.Mesh(np.asarray(model.vertices, dtype=np.float64) * scale, model.faces)


def _moved(model: Any, T: np.ndarray) -> Any:
    """A mesh or model cloud moved by the rigid T (a cloud's normals turned with it)."""
    if isinstance(model, Cloud):
        normals = None if model.normals is None else np.asarray(model.normals, dtype=np.float64) @ T[:3, :3].T
        return model._replace(points=transform_points(T, model.points), normals=normals)
    return io.Mesh(transform_points(T, model.vertices), model.faces)


def _read_grey(path: Path, what: str) -> np.ndarray:
    """An image file as (H, W) uint8 grey (Pillow's ITU-R 601 luma); ValueError naming ``what`` and the file."""
    from PIL import Image

    try:
        with Image.open(path) as im:
            return np.asarray(im.convert("L"))
    except (OSError, Image.DecompressionBombError, ValueError) as e:
        raise ValueError(f"{what}: cannot read the image {str(path)!r} ({type(e).__name__}: {e})") from None


def _loaded_reference(r: Optional[ReferenceImage], where: Path, what: str) -> Optional[ReferenceImage]:
    """``r`` with its image read (a file relative to ``where``, grey) or drawn (a built-in label), its geometry
    checked."""
    if r is None or isinstance(r.image, np.ndarray):
        return r
    name = str(r.image)
    if name.startswith("builtin:"):
        w, h = (int(round(v * r.pixels_per_metre)) for v in r.size)
        image = builtin_label(name, w, h)
    else:
        image = _read_grey(where / name, f"{what}: reference_image")
    out = dataclasses.replace(r, image=np.asarray(image))
    out.geometry()  # ValueError naming the field: an origin or scale that cannot be
    return out


def _check_cloud_symmetry(cloud: Cloud, symmetry: Any, transforms: list, what: str) -> None:
    """check_symmetry for a scanned model: 98 % of 2000 of its points, turned, must lie within the tolerance of its
    points (a scan is noisy, and the edges of what it saw need not map onto points it has)."""
    from scanalign.pose import alignment_fitness

    points = surface_points(cloud, 2000)
    size = float(np.ptp(points, axis=0).max())
    target = np.asarray(cloud.points, dtype=np.float64)
    for k, S in enumerate(transforms, start=1):
        share = alignment_fitness(transform_points(np.asarray(S), points), target, np.eye(4), SYMMETRY_TOLERANCE * size)[0]
        if share < 0.98:
            axis, point = (np.round(v, 6).tolist() for v in (symmetry.axis, symmetry.point))
            raise ValueError(
                f"{what}: symmetry (order {symmetry.order} about axis {axis} through {point} m) does not map the model "
                f"cloud onto itself: turned by {360 * k / (symmetry.order or len(transforms) + 1):.1f} deg, only "
                f"{100 * share:.1f} % of its points lie within {1000 * SYMMETRY_TOLERANCE * size:.2f} mm of it (98 % "
                "needed): check the axis, point and order (model frame, after scale and T_model_mesh)")


def check_symmetry(mesh: Any, symmetry: Any, what: str = "part") -> None:
    """Raises ValueError naming ``what`` and ``symmetry`` unless each rotation of ``symmetry``
    (a :class:`scanalign.grasp.PartSymmetry`; order 0 checked every 5 degrees) maps the surface of
    ``mesh`` (model frame) onto itself: every one of 2000 points sampled on the surface (seed 0),
    rotated, must lie within :data:`SYMMETRY_TOLERANCE` times the part's size (its largest
    bounding-box extent) of the surface."""
    transforms = symmetry.transforms()[1:]
    if not transforms:
        return
    if isinstance(mesh, Cloud):
        _check_cloud_symmetry(mesh, symmetry, transforms, what)
        return
    size = float(np.ptp(np.asarray(mesh.vertices)[np.unique(mesh.faces)], axis=0).max())
    points, index = sample_mesh(mesh, 2000, seed=0)[0], MeshDistanceIndex(mesh.vertices, mesh.faces)
    for k, S in enumerate(transforms, start=1):
        if (worst := float(index.distance(transform_points(np.asarray(S), points)).max())) > SYMMETRY_TOLERANCE * size:
            axis, point = (np.round(v, 6).tolist() for v in (symmetry.axis, symmetry.point))
            raise ValueError(
                f"{what}: symmetry (order {symmetry.order} about axis {axis} through {point} m) does not map the mesh "
                f"onto itself: turned by {360 * k / (symmetry.order or len(transforms) + 1):.1f} deg, its surface lies "
                f"up to {1000 * worst:.2f} mm off the mesh (tolerance {1000 * SYMMETRY_TOLERANCE * size:.2f} mm, "
                f"{SYMMETRY_TOLERANCE:.0%} of the part's size {1000 * size:.1f} mm): check the axis, point and order "
                "(model frame, after scale and T_model_mesh)")

"""A part ready to be found and picked: its mesh in metres, grasps, symmetry and gripper,
from a part file (JSON / YAML, :func:`scanalign.grasp.read_part_grasps`), a built-in part
name or a :class:`scanalign.grasp.PartGrasps`."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Dict

import numpy as np

from scanalign import io
from scanalign.data.parts import builtin_mesh
from scanalign.grasp import Gripper, PartGrasps, PartSymmetry, read_part_grasps

__all__ = ["BUILTIN_PART_FILES", "load_part"]

#: Built-in part name -> its part file (mesh, grasps, symmetry): the parts of
#: :data:`scanalign.data.parts.BUILTIN_PARTS` with grasps for a parallel-jaw gripper.
BUILTIN_PART_FILES: Dict[str, Path] = {p.stem: p for p in sorted((Path(__file__).parents[1] / "data" / "parts").glob("*.json"))}


def load_part(source: Any) -> Any:
    """A part ready for :func:`pick`: a part file (JSON / YAML, :func:`scanalign.grasp.read_part_grasps`),
    a built-in part name (:data:`BUILTIN_PART_FILES`) or a :class:`scanalign.grasp.PartGrasps`,
    with its mesh loaded in metres (``"builtin:<name>"``, or a mesh file relative to the part
    file, times ``scale``), its symmetry (default none) and gripper (default
    :meth:`scanalign.grasp.Gripper.parallel_jaw`) filled in."""
    where = Path(".")
    if isinstance(source, PartGrasps):
        part = source
    else:
        path = BUILTIN_PART_FILES.get(str(source), Path(source))
        if not path.is_file():
            raise ValueError(f"part {str(source)!r}: no such part file, and not a built-in part "
                             f"({', '.join(BUILTIN_PART_FILES)})")
        part, where = read_part_grasps(path), path.parent
    mesh = part.mesh
    if isinstance(mesh, str):
        mesh = (builtin_mesh(name=mesh[len("builtin:"):]) if mesh.startswith("builtin:")
                else io.read_mesh(where / mesh))
        mesh = io.Mesh(np.asarray(mesh.vertices, dtype=np.float64) * part.scale, mesh.faces)
    if not isinstance(mesh, io.Mesh):
        raise ValueError(f"part {part.name!r}: no mesh (give 'mesh' in the part file: a mesh file or builtin:<name>)")
    return dataclasses.replace(part, mesh=mesh, scale=1.0, symmetry=part.symmetry or PartSymmetry(),
                               gripper=part.gripper or Gripper.parallel_jaw())

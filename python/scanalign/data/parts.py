"""The built-in parts (need no download), and meshes turned into oriented clouds.

Each part is defined once, as a closed triangle mesh generated in C++ from its analytic
surfaces (:func:`builtin_mesh`; :data:`BUILTIN_PARTS` names them with their symmetry), in
metres in its own frame, z up:

``"block"``, the machined block (origin at the box centre; :func:`builtin_object` samples it
with the points of the curved faces on the exact cylinder and sphere): a box ``[-0.040, 0.040]
x [-0.025, 0.025] x [-0.015, 0.015]`` (80 x 50 x 30 mm); a cylindrical boss of radius 0.012 on
the top face, axis along z through ``(x, y) = (-0.015, 0)``, 0.015 high (top at ``z = 0.030``);
a spherical cap, the part of the sphere of radius 0.015 centred at ``(0.020, 0.006, 0.006)``
above the top face (cap height 0.006, base radius 0.012). Flat faces, a cylinder and a sphere
without symmetry constrain point-to-plane ICP in all six degrees of freedom.

``"bracket"``, an L-shaped angle bracket (origin at the base plate's centre on its bottom face):
a 70 x 40 x 6 mm base plate ``[-0.035, 0.035] x [-0.020, 0.020] x [0, 0.006]``, a 40 x 40 x 6 mm
upright plate at the +x end (x in ``[0.029, 0.035]``, top at ``z = 0.040``) and a triangular
gusset (legs 20 mm, 6 mm thick, y in ``[0.014, 0.020]``) in the inner corner on the +y side,
which breaks the mirror symmetry: no rotation or reflection maps it onto itself.

``"standoff"``, a hexagonal standoff (origin at the bottom face centre): a hexagonal prism 30
mm across flats (corners at angles ``k 60°``), 20 mm high, and a coaxial cylindrical stud of
radius 6 mm, 15 mm high (top at ``z = 0.035``). It looks the same after a rotation by 60°
about z: order 6.
"""

from __future__ import annotations

import functools
import math
from typing import Any, Dict, Tuple, Union

import numpy as np
import numpy.typing as npt

from scanalign import _core, io
from scanalign.common.arrays import mesh_arrays

__all__ = ["builtin_mesh", "builtin_object", "sample_mesh", "normalize_mesh", "BUILTIN_PARTS"]

MeshLike = Union[io.Mesh, Tuple[npt.ArrayLike, npt.ArrayLike]]


def sample_mesh(mesh_or_vertices_faces: MeshLike, n_points: int, seed: int = 0) -> Tuple[np.ndarray, np.ndarray]:
    """Samples points uniformly per unit area on a triangle mesh's surface, in C++
    (``_core.common.sample_mesh``): triangles drawn with probability proportional to their area
    (zero-area ones never), points uniform inside them (``p = a + sqrt(u) (1 - v) (b - a) +
    sqrt(u) v (c - a)``, ``u, v`` uniform in [0, 1)), with the random numbers of
    ``numpy.random.default_rng(seed)`` drawn as NumPy draws them.

    Args:
        mesh_or_vertices_faces: a :class:`scanalign.io.Mesh`, ``(vertices (V, 3), faces (F, 3))`` or an
            Open3D / trimesh triangle mesh.
        n_points: number of points (>= 0). seed: equal seeds give equal samples.

    Returns:
        ``points (n_points, 3)`` float64 in the mesh's unit, and ``normals (n_points, 3)``
        float64 unit face normals (right-hand rule on the winding: outward for a
        counter-clockwise, outward-facing mesh).

    Raises:
        ValueError: bad shapes, negative or memory-exceeding ``n_points``, a mesh of zero area.
    """
    m = mesh_or_vertices_faces
    mesh = m if isinstance(m, io.Mesh) else io.Mesh(*(mesh_arrays(m) or m))  # or an Open3D / trimesh mesh
    points, normals, _ = _core.common.sample_mesh(mesh.vertices, mesh.faces, n_points, seed)
    return points, normals


def normalize_mesh(mesh: io.Mesh, size: float) -> io.Mesh:
    """A copy of ``mesh`` scaled uniformly so that its largest bounding-box extent is ``size``
    metres, its bounding box centred on x = y = 0 and its lowest point at z = 0 (ready to
    stand on a table). For meshes in arbitrary units (CGAL's demo meshes are about one unit
    across; CAD files are often in millimetres). ValueError for a non-positive size or a mesh
    without extent."""
    if not (math.isfinite(size) and size > 0):
        raise ValueError(f"size must be a finite positive length in metres, got {size}")
    v = mesh.vertices
    used = v[np.unique(mesh.faces)] if mesh.faces.size else v
    if used.size == 0 or not np.all(np.isfinite(used)):
        raise ValueError("mesh has no finite vertices in use")
    lo, hi = used.min(axis=0), used.max(axis=0)
    extent = float((hi - lo).max())
    if extent <= 0:
        raise ValueError("mesh has zero extent")
    offset = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    return io.Mesh((v - offset) * (size / extent), mesh.faces.copy())


#: Each built-in part's name and rotational symmetry in its model frame (``PartSymmetry``:
#: ``axis``, ``point`` m, ``order``): block 1, bracket 1, standoff 6 about z through the origin.
BUILTIN_PARTS: Dict[str, Any] = {name: _core.pose.PartSymmetry(*_core.synthetic.builtin_part_symmetry(name))
                                 for name in _core.synthetic.BUILTIN_PART_NAMES}


@functools.lru_cache(maxsize=8)
def _builtin(segments: int, name: str) -> io.Mesh:
    vertices, faces, _ = _core.synthetic.builtin_part_mesh(segments, name)  # _: each face's surface kind
    return io.Mesh(vertices, faces)


def builtin_mesh(segments: int = 96, name: str = "block") -> io.Mesh:
    """The built-in part ``name`` (``"block"``, ``"bracket"`` or ``"standoff"``; see the module
    docstring and :data:`BUILTIN_PARTS`) as a watertight triangle mesh (every edge shared by two
    faces, wound counter-clockwise seen from outside) in metres in the part's own frame (z up).

    Curved surfaces (the bracket has none) are inscribed polygons of ``segments`` vertices
    (integer in [8, 4096]; the standoff's stud rounds it up to a multiple of 6, keeping the
    6-fold symmetry) on the exact surfaces: about 3000 triangles and a chord error of 6 um for
    the block at 96 segments."""
    if int(segments) != segments:
        raise ValueError(f"segments must be an integer >= 8, got {segments}")
    if name not in BUILTIN_PARTS:
        raise ValueError(f"name: expected one of {sorted(BUILTIN_PARTS)}, got {name!r}")
    m = _builtin(int(segments), name)  # C++ raises ValueError for segments < 8
    return io.Mesh(m.vertices.copy(), m.faces.copy())


def builtin_object(n_points: int = 20000, seed: int = 0) -> Tuple[np.ndarray, np.ndarray]:
    """Samples the block's exposed surface as :func:`sample_mesh` samples the mesh of
    :func:`builtin_mesh`, with the points and normals of the curved faces projected onto the
    exact cylinder and sphere: ``points, normals (n_points, 3)``, float64, metres, outward
    unit normals, in random order; equal seeds give identical output."""
    points, normals, _ = _core.synthetic.sample_builtin_block(n_points, seed, 96)
    return points, normals

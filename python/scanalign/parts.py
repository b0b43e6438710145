"""The built-in machined part (needs no download), and meshes turned into oriented clouds.

The part is defined once, as a closed triangle mesh (:func:`builtin_mesh`) generated from
the analytic surfaces below; :func:`builtin_object` samples its cloud from that mesh and
puts the points of the curved faces back on the exact cylinder and sphere. In metres, in
its own frame (origin at the box centre, z up):

- a box ``[-0.040, 0.040] x [-0.025, 0.025] x [-0.015, 0.015]`` (80 x 50 x 30 mm);
- a cylindrical boss of radius 0.012 standing on the top face, axis along z through
  ``(x, y) = (-0.015, 0)``, 0.015 high (top at ``z = 0.030``);
- a spherical cap: the part of the sphere of radius 0.015 centred at ``(0.020, 0.006,
  0.006)`` above the top face (cap height 0.006, base radius 0.012).

Flat faces, a cylinder and a sphere without symmetry constrain point-to-plane ICP in all
six degrees of freedom.
"""

from __future__ import annotations

import functools
import math
from typing import Dict, List, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import io

__all__ = ["builtin_mesh", "builtin_object", "sample_mesh", "normalize_mesh"]

MeshLike = Union[io.Mesh, Tuple[npt.ArrayLike, npt.ArrayLike]]

_BOX_HALF = np.array([0.040, 0.025, 0.015])  # box centred at the origin
_TOP = float(_BOX_HALF[2])
_BOSS_CENTER = np.array([-0.015, 0.0])
_BOSS_RADIUS = 0.012
_BOSS_HEIGHT = 0.015
_CAP_CENTER = np.array([0.020, 0.006, _TOP - 0.009])
_CAP_RADIUS = 0.015
_CAP_BASE_RADIUS = math.sqrt(_CAP_RADIUS**2 - (_TOP - _CAP_CENTER[2]) ** 2)
_PLANE, _BOSS, _CAP = 0, 1, 2  # the analytic surface each mesh face lies on


# --------------------------------------------------------------------------- sampling


def _sample_faces(mesh: io.Mesh, n_points: int, rng: np.random.Generator):
    """Area-uniform points, unit face normals and face indices (zero-area faces never drawn)."""
    corners = mesh.vertices[mesh.faces]  # (F, 3 corners, 3)
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    double_area = np.linalg.norm(cross, axis=1)
    if not np.any(double_area > 0):
        raise ValueError("mesh has zero total area; cannot sample its surface")
    face = rng.choice(len(double_area), size=n_points, p=double_area / double_area.sum())
    s = np.sqrt(rng.random(n_points))[:, None]
    t = rng.random(n_points)[:, None]
    a, b, c = corners[face, 0], corners[face, 1], corners[face, 2]
    # Relative to `a`, so points on axis-aligned faces keep the exact coordinate.
    points = a + s * (1.0 - t) * (b - a) + s * t * (c - a)
    return points, cross[face] / double_area[face, None], face


def sample_mesh(mesh_or_vertices_faces: MeshLike, n_points: int, seed: int = 0) -> Tuple[np.ndarray, np.ndarray]:
    """Samples points uniformly per unit area on a triangle mesh's surface.

    Triangles are drawn with probability proportional to their area, points uniformly
    inside them (``p = a + sqrt(u) (1 - v) (b - a) + sqrt(u) v (c - a)``, ``u, v`` uniform
    in [0, 1)); zero-area triangles are never drawn.

    Args:
        mesh_or_vertices_faces: a :class:`scanalign.io.Mesh` or ``(vertices (V, 3), faces (F, 3))``.
        n_points: number of points (>= 0).
        seed: random seed; equal seeds give equal samples.

    Returns:
        ``points (n_points, 3)`` float64 in the mesh's unit, and ``normals (n_points, 3)``
        float64 unit face normals (right-hand rule on the winding: outward for a
        counter-clockwise, outward-facing mesh).

    Raises:
        ValueError: bad shapes, negative ``n_points``, or a mesh of zero total area.
    """
    m = mesh_or_vertices_faces
    mesh = m if isinstance(m, io.Mesh) else io.Mesh(*m)
    if n_points < 0:
        raise ValueError(f"n_points must be non-negative, got {n_points}")
    points, normals, _ = _sample_faces(mesh, int(n_points), np.random.default_rng(seed))
    return points, normals


def normalize_mesh(mesh: io.Mesh, size: float) -> io.Mesh:
    """A copy of ``mesh`` scaled uniformly so that its largest bounding-box extent is ``size``
    metres, its bounding box centred on x = y = 0 and its lowest point at z = 0 (ready to
    stand on a table). For meshes in arbitrary units (CGAL's demo meshes are about one unit
    across; CAD files are often in millimetres).

    Raises:
        ValueError: a non-positive size or a mesh without extent.
    """
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


# --------------------------------------------------------------------------- mesh generation


class _MeshBuilder:
    """Collects triangles, each labelled with the analytic surface it lies on; vertices with
    bit-identical coordinates are shared, which keeps the surfaces watertight without a tolerance."""

    def __init__(self) -> None:
        self._index: Dict[Tuple[float, float, float], int] = {}
        self.vertices: List[Tuple[float, float, float]] = []
        self.faces: List[Tuple[int, int, int]] = []
        self.labels: List[int] = []
        self.surface = _PLANE

    def vertex(self, p: Sequence[float]) -> int:
        key = (float(p[0]), float(p[1]), float(p[2]))
        i = self._index.get(key)
        if i is None:
            i = self._index[key] = len(self.vertices)
            self.vertices.append(key)
        return i

    def vertices_of(self, points: np.ndarray) -> List[int]:
        return [self.vertex(p) for p in points]

    def triangle(self, a: int, b: int, c: int) -> None:
        self.faces.append((a, b, c))
        self.labels.append(self.surface)

    def strip(self, lower: Sequence[int], upper: Sequence[int]) -> None:
        """Closed band between two rings of equal size, both counter-clockwise seen from
        outside-above; normals point away from the ring axis."""
        n = len(lower)
        for j in range(n):
            k = (j + 1) % n
            self.triangle(lower[j], lower[k], upper[k])
            self.triangle(lower[j], upper[k], upper[j])


def _annulus(b: _MeshBuilder, centre: np.ndarray, hole: List[int], hole_xy: np.ndarray, outer: List[int],
             outer_xy: np.ndarray) -> None:
    """Triangulates a planar region z = const between a circular hole and a convex outer
    boundary around it (normal +z) by merging both boundaries in angle around the hole centre."""

    def by_angle(idx: List[int], xy: np.ndarray) -> Tuple[List[int], np.ndarray]:
        ang = np.mod(np.arctan2(xy[:, 1] - centre[1], xy[:, 0] - centre[0]), 2 * np.pi)
        order = np.argsort(ang, kind="stable")
        return [idx[i] for i in order], ang[order]

    inner, ia = by_angle(hole, hole_xy)
    outer, oa = by_angle(outer, outer_xy)
    # Both walks start at their first point past angle 0 and close the loop by repeating it
    # at + 2 pi; each step advances the walk whose next point comes first in angle.
    inner, ia = inner + [inner[0]], np.append(ia, ia[0] + 2 * np.pi)
    outer, oa = outer + [outer[0]], np.append(oa, oa[0] + 2 * np.pi)
    i = j = 0
    n_i, n_o = len(inner) - 1, len(outer) - 1
    while i < n_i or j < n_o:
        if j >= n_o or (i < n_i and ia[i + 1] <= oa[j + 1]):
            b.triangle(inner[i], outer[j], inner[i + 1])
            i += 1
        else:
            b.triangle(inner[i], outer[j], outer[j + 1])
            j += 1


def _rectangle_side(b: _MeshBuilder, top: List[int], bottom: Tuple[int, int]) -> None:
    """A vertical rectangle whose top edge carries the points ``top`` (from the corner above
    bottom[0] to the one above bottom[1]) and whose bottom edge is the two corners ``bottom``.
    Its normal is (direction of ``top``) x (up): walk the top edge with the outside on your
    left, seen from above."""
    b0, b1 = bottom
    half = (len(top) - 1) // 2
    for j in range(half):
        b.triangle(b0, top[j + 1], top[j])
    b.triangle(b0, b1, top[half])
    for j in range(half, len(top) - 1):
        b.triangle(b1, top[j + 1], top[j])


@functools.lru_cache(maxsize=4)
def _builtin(segments: int) -> Tuple[io.Mesh, np.ndarray]:
    """The part's mesh and, per face, the surface it lies on (_PLANE, _BOSS or _CAP)."""
    hx, hy, hz = (float(x) for x in _BOX_HALF)
    b = _MeshBuilder()
    phi = 2 * np.pi * np.arange(segments) / segments
    ring = np.column_stack([np.cos(phi), np.sin(phi)])

    # Boss: a cylinder on the top face, its bottom ring shared with the face's hole.
    boss_xy = _BOSS_CENTER + _BOSS_RADIUS * ring
    boss_bottom = b.vertices_of(np.column_stack([boss_xy, np.full(segments, hz)]))
    boss_top = b.vertices_of(np.column_stack([boss_xy, np.full(segments, hz + _BOSS_HEIGHT)]))
    b.surface = _BOSS
    b.strip(boss_bottom, boss_top)
    b.surface = _PLANE
    lid = b.vertex((_BOSS_CENTER[0], _BOSS_CENTER[1], hz + _BOSS_HEIGHT))
    for j in range(segments):
        b.triangle(lid, boss_top[j], boss_top[(j + 1) % segments])

    # Cap: the sphere above the top face, in rings from the base circle to the pole.
    theta_max = math.acos((hz - _CAP_CENTER[2]) / _CAP_RADIUS)  # polar angle of the base circle
    n_rings = max(4, segments // 8)
    rings = []
    for k in range(n_rings):
        th = theta_max * (n_rings - k) / n_rings
        if k == 0:  # exactly on the top face, so the face's hole matches bit for bit
            pts = np.column_stack([_CAP_CENTER[:2] + _CAP_RADIUS * math.sin(th) * ring, np.full(segments, hz)])
        else:
            pts = _CAP_CENTER + _CAP_RADIUS * np.column_stack([math.sin(th) * ring, np.full(segments, math.cos(th))])
        rings.append(b.vertices_of(pts))
    b.surface = _CAP
    for lower, upper in zip(rings[:-1], rings[1:]):
        b.strip(lower, upper)
    pole = b.vertex(_CAP_CENTER + np.array([0.0, 0.0, _CAP_RADIUS]))
    for j in range(segments):
        b.triangle(pole, rings[-1][j], rings[-1][(j + 1) % segments])
    b.surface = _PLANE
    cap_xy = _CAP_CENTER[:2] + _CAP_RADIUS * math.sin(theta_max) * ring

    # Top face: split at x = xs between the two holes into two rectangles with one hole each.
    xs = 0.5 * ((_BOSS_CENTER[0] + _BOSS_RADIUS) + (_CAP_CENTER[0] - _CAP_RADIUS * math.sin(theta_max)))

    def line(a: float, c: float) -> np.ndarray:  # boundary points 4 mm apart: dense enough for the merge
        return np.linspace(a, c, max(2, int(math.ceil(abs(c - a) / 0.004)) + 1))

    x_left, x_right, y_all = line(-hx, xs), line(xs, hx), line(-hy, hy)
    # Boundary points, each edge generated once so that faces sharing it share the vertices.
    x_all = np.concatenate([x_left, x_right[1:]])
    south = [b.vertex((x, -hy, hz)) for x in x_all]  # y = -hy, x ascending
    north = [b.vertex((x, hy, hz)) for x in x_all]   # y = +hy, x ascending
    west = [b.vertex((-hx, y, hz)) for y in y_all]   # x = -hx, y ascending
    east = [b.vertex((hx, y, hz)) for y in y_all]    # x = +hx, y ascending
    split = [b.vertex((xs, y, hz)) for y in y_all]
    n_left = len(x_left)
    left_outer = south[:n_left] + split[1:-1] + north[:n_left] + west[1:-1]
    right_outer = south[n_left - 1:] + east[1:-1] + north[n_left - 1:] + split[1:-1]
    for centre, hole, hole_xy, outer in ((_BOSS_CENTER, boss_bottom, boss_xy, left_outer),
                                         (_CAP_CENTER[:2], rings[0], cap_xy, right_outer)):
        _annulus(b, centre, hole, hole_xy, outer, np.array([b.vertices[i][:2] for i in outer]))

    # Side walls (outward normals) and the bottom face.
    c000, c100 = b.vertex((-hx, -hy, -hz)), b.vertex((hx, -hy, -hz))
    c010, c110 = b.vertex((-hx, hy, -hz)), b.vertex((hx, hy, -hz))
    _rectangle_side(b, south, (c000, c100))          # y = -hy
    _rectangle_side(b, north[::-1], (c110, c010))    # y = +hy
    _rectangle_side(b, west[::-1], (c010, c000))     # x = -hx
    _rectangle_side(b, east, (c100, c110))           # x = +hx
    b.triangle(c000, c110, c100)
    b.triangle(c000, c010, c110)
    mesh = io.Mesh(np.array(b.vertices, dtype=np.float64), np.array(b.faces, dtype=np.int64))
    return mesh, np.array(b.labels)


def builtin_mesh(segments: int = 96) -> io.Mesh:
    """The built-in part (see the module docstring) as a closed triangle mesh, in metres in
    the part's own frame (origin at the box centre, z up).

    Watertight (every edge shared by exactly two faces), wound counter-clockwise seen from
    outside, about 3000 triangles for ``segments=96``; the curved surfaces are inscribed
    polygons (chord error 6 um at 96 segments) whose vertices lie on the exact surfaces.

    Args:
        segments: vertices around the boss and the cap (integer >= 8).
    """
    if int(segments) != segments or segments < 8:
        raise ValueError(f"segments must be an integer >= 8, got {segments}")
    m, _ = _builtin(int(segments))
    return io.Mesh(m.vertices.copy(), m.faces.copy())


def builtin_object(n_points: int = 20000, seed: int = 0) -> Tuple[np.ndarray, np.ndarray]:
    """Samples the built-in part's surface: the mesh of :func:`builtin_mesh`, its curved
    faces projected onto the exact cylinder and sphere.

    Only the exposed surface is sampled: the six box faces (the top one minus the footprints
    of the boss and the cap), the boss side and top disc, and the cap. The density is
    uniform per unit area, normals are outward unit vectors (exact ones on the curved
    surfaces), and the points come in random order.

    Args:
        n_points: number of points (>= 0).
        seed: random seed; equal seeds give identical output.

    Returns:
        ``points (n_points, 3)`` and ``normals (n_points, 3)``, float64, metres, in the frame
        of :func:`builtin_mesh`.
    """
    if n_points < 0:
        raise ValueError(f"n_points must be non-negative, got {n_points}")
    mesh, surface = _builtin(96)
    rng = np.random.default_rng(seed)
    points, normals = np.zeros((0, 3)), np.zeros((0, 3))
    while len(points) < n_points:
        missing = n_points - len(points)
        p, n, face = _sample_faces(mesh, missing + missing // 100 + 16, rng)
        boss, cap = surface[face] == _BOSS, surface[face] == _CAP
        radial = p[boss, :2] - _BOSS_CENTER
        radial /= np.linalg.norm(radial, axis=1, keepdims=True)
        p[boss, :2] = _BOSS_CENTER + _BOSS_RADIUS * radial
        n[boss] = np.column_stack([radial, np.zeros(len(radial))])
        n[cap] = p[cap] - _CAP_CENTER
        n[cap] /= np.linalg.norm(n[cap], axis=1, keepdims=True)
        p[cap] = _CAP_CENTER + _CAP_RADIUS * n[cap]
        # The top face's holes are inscribed polygons: drop the slivers between them and the
        # true circles, which belong to the boss and the cap.
        in_hole = ((np.linalg.norm(p[:, :2] - _BOSS_CENTER, axis=1) < _BOSS_RADIUS)
                   | (np.linalg.norm(p[:, :2] - _CAP_CENTER[:2], axis=1) < _CAP_BASE_RADIUS))
        keep = ~((surface[face] == _PLANE) & (p[:, 2] == _TOP) & in_hole)
        points, normals = np.vstack([points, p[keep]]), np.vstack([normals, n[keep]])
    return points[:n_points], normals[:n_points]

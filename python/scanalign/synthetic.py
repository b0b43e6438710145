"""Synthetic eye-in-hand RGB-D scans with exact ground truth.

A camera on a robot's hand moves around objects on a table; a z-buffer renderer (C++,
``scanalign._core.synthetic``) computes what it sees, and a sensor model adds RealSense- or
Zivid-like noise.  Every pose, surface and pixel is known exactly, so reconstructions can be
scored against the truth.

Frames (all transforms ``T_a_b`` map b-coordinates into a, metres, 4x4 float64):

- ``base``: the scene (world) frame; z up, the table top is the plane ``z = table_height``
  (0 by default), the objects stand on it. Every pose and the reconstruction's model are
  given in this frame.
- ``robot``: the base frame of the robot arm that moves the camera (a UR5 by default,
  :mod:`scanalign.kinematics`), mounted at ``T_base_robot`` in the scene (default
  :func:`robot_mount`: hanging 0.9 m above the table centre).
- ``flange``: the robot's tool flange; ``T_base_flange = T_base_robot @ fk(q)`` comes from
  forward kinematics of the joints ``q``.
- ``camera``: the depth camera, OpenCV convention (x right, y down, z along the optical
  axis); ``T_flange_camera`` is the hand-eye calibration, so
  ``T_base_camera = T_base_flange @ T_flange_camera``.
- ``object``: a mesh's own frame; ``T_base_object`` places it in the scene.

Pipeline::

    scene = Scene(table_size=(0.6, 0.6))
    scene.add_object(builtin_mesh(), position=(0.5, 0.0), yaw=0.3)
    traj = loop_trajectory(36, center=scene.center, height=0.40, radius=0.20, robot="ur5")
    scan = render_scan(scene, traj, "sr300", noise="sr300", seed=1)
    scan.joints[0]                     # UR5 joints of frame 0 (rad), from inverse kinematics
    scan.frames[0].depth_metres()      # (480, 640) float32, NaN = no measurement
    scan.reference.poses[0]            # exact T_base_camera of frame 0
    scan.mesh                          # the whole scene in the base frame (for cloud-to-mesh)

or, for the demo, ``builtin_scan(n_frames=36, noise="sr300", seed=0)``, or from a JSON /
flat YAML file with :class:`SyntheticConfig`.

With a robot (``robot="ur5"``, the default of :class:`SyntheticConfig` and
:func:`builtin_scan`), the planned camera poses become flange poses
``T_base_camera @ inv(T_flange_camera)``, mapped into the robot base frame; the arm's
analytic inverse kinematics gives the joints, each step taking the solution closest to the
previous one (:meth:`scanalign.kinematics.Robot.ik_trajectory`), and forward kinematics of
those joints gives the reference flange and camera poses: the reconstruction is scored
against the robot's own pose, as in seed 000. A pose the arm cannot reach raises
ValueError naming the frame and the IK status.
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import functools
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _core
from . import io as _io
from . import se3
from ._arrays import as_points, as_transform
from .camera import INTRINSICS_PRESETS, Frame, Intrinsics, read_camera_file
from .trajectory import Trajectory

__all__ = [
    "RenderResult",
    "render_depth",
    "builtin_mesh",
    "normalize_mesh",
    "SceneObject",
    "Scene",
    "DEFAULT_T_FLANGE_CAMERA",
    "look_at",
    "ScanTrajectory",
    "DEFAULT_ROBOT_HEIGHT",
    "robot_mount",
    "attach_robot",
    "loop_trajectory",
    "hemisphere_trajectory",
    "SensorNoise",
    "NOISE_PRESETS",
    "SyntheticScan",
    "render_scan",
    "SyntheticConfig",
    "builtin_scan",
]

PathLike = Union[str, "os.PathLike[str]"]


# --------------------------------------------------------------------------- rendering


@dataclass(frozen=True)
class RenderResult:
    """What a pinhole camera sees of a triangle mesh, per pixel (row-major, (H, W)).

    Attributes:
        depth: float32 depth z along the optical axis, metres; NaN where nothing is hit.
        face_id: int32 index (row of ``faces``) of the visible triangle; -1 where nothing is hit.
        cos_incidence: float32 cosine between the visible face's normal (right-hand rule on
            its winding) and the direction from the surface point to the camera: 1 head on,
            about 0 at grazing angles, negative when the back of a face is seen; 0 where
            nothing is hit.
    """

    depth: np.ndarray
    face_id: np.ndarray
    cos_incidence: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """(H, W) bool: pixels that see a surface."""
        return self.face_id >= 0


def _as_faces(faces: object, n_vertices: int) -> np.ndarray:
    """(M, 3) int32 C-contiguous faces, validated against the vertex count."""
    f = np.asarray(faces)
    if f.size == 0 and f.ndim <= 2:
        return np.zeros((0, 3), np.int32)
    if not np.issubdtype(f.dtype, np.integer):
        raise TypeError(f"faces: expected an integer array, got dtype {f.dtype}")
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces: expected shape (M, 3), got {f.shape}")
    lo, hi = int(f.min()), int(f.max())
    if lo < 0 or hi >= n_vertices:
        raise ValueError(f"faces: vertex indices must lie in [0, {n_vertices}), got [{lo}, {hi}]")
    return np.ascontiguousarray(f, dtype=np.int32)


def _check_intrinsics(intrinsics: object) -> Intrinsics:
    if isinstance(intrinsics, str):
        return Intrinsics.preset(intrinsics)
    if not isinstance(intrinsics, Intrinsics):
        raise TypeError(
            f"intrinsics: expected scanalign.camera.Intrinsics or a preset name, got {type(intrinsics)!r}")
    return intrinsics


def render_depth(
    vertices: np.ndarray,
    faces: np.ndarray,
    intrinsics: Union[Intrinsics, str],
    T_camera_world: np.ndarray,
    *,
    near: float = 0.01,
    far: float = math.inf,
    cull_backfaces: bool = False,
    num_threads: int = 0,
) -> RenderResult:
    """Renders a triangle mesh with a z-buffer: depth, visible face and incidence per pixel.

    Pixel ``(u, v)`` samples the ray through its centre (OpenCV convention). Depth is the
    exact intersection of that ray with the visible triangle's plane (perspective-correct:
    a rendered plane back-projects onto the plane to ~1e-8 m, the float32 rounding). Pixel
    centres on an edge shared by two triangles belong to exactly one of them (top-left
    rule), so closed meshes show no holes. Triangles crossing the near plane are clipped
    (the part beyond ``near`` is drawn); surfaces beyond ``far`` are not drawn. Both sides
    of every face are drawn unless ``cull_backfaces``.

    Args:
        vertices: (V, 3) float32/float64 vertex positions in the world frame, metres. Faces
            using a non-finite vertex are skipped.
        faces: (F, 3) integer vertex indices (any integer dtype; copied to int32).
        intrinsics: image size and pinhole parameters (or a preset name, e.g. ``"sr300"``).
        T_camera_world: 4x4 rigid transform mapping world coordinates into the camera frame.
        near: near clipping distance along the optical axis, metres (> 0).
        far: far limit, metres (> near).
        cull_backfaces: drop faces whose winding is clockwise as seen by the camera.
        num_threads: OpenMP threads, 0 for the default.

    Returns:
        A :class:`RenderResult` of (H, W) arrays.

    Raises:
        TypeError: vertices not float32/float64, faces not integer, intrinsics of another type.
        ValueError: bad shapes, a face index out of range, a non-finite or non-rigid
            transform, or bad clip distances.
    """
    K = _check_intrinsics(intrinsics)
    v = as_points(vertices, "vertices")
    f = _as_faces(faces, v.shape[0])
    T = se3.require_rigid(T_camera_world, "T_camera_world")
    near, far = float(near), float(far)
    if not (math.isfinite(near) and near > 0):
        raise ValueError(f"near must be a finite positive distance in metres, got {near}")
    if not far > near:
        raise ValueError(f"far ({far}) must exceed near ({near})")
    if int(num_threads) != num_threads or num_threads < 0:
        raise ValueError(f"num_threads must be a non-negative integer, got {num_threads}")
    depth, face_id, cos = _core.synthetic.render_depth(
        v, f, K.width, K.height, K.fx, K.fy, K.cx, K.cy, T, near, far, bool(cull_backfaces), int(num_threads)
    )
    return RenderResult(depth, face_id, cos)


# --------------------------------------------------------------------------- meshes


class _MeshBuilder:
    """Collects triangles; vertices with bit-identical coordinates are shared, which keeps
    the generated surfaces watertight without any tolerance."""

    def __init__(self) -> None:
        self._index: Dict[Tuple[float, float, float], int] = {}
        self.vertices: List[Tuple[float, float, float]] = []
        self.faces: List[Tuple[int, int, int]] = []

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

    def strip(self, lower: Sequence[int], upper: Sequence[int]) -> None:
        """Closed band between two rings of equal size, both counter-clockwise seen from
        outside-above; normals point away from the ring axis."""
        n = len(lower)
        for j in range(n):
            k = (j + 1) % n
            self.triangle(lower[j], lower[k], upper[k])
            self.triangle(lower[j], upper[k], upper[j])

    def mesh(self) -> _io.Mesh:
        return _io.Mesh(np.array(self.vertices, dtype=np.float64), np.array(self.faces, dtype=np.int64))


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
    bottom[0] to the one above bottom[1]) and whose bottom edge is the two corners
    ``bottom``. Its normal is (direction of ``top``) x (up): walk the top edge with the
    outside on your left, seen from above."""
    b0, b1 = bottom
    half = (len(top) - 1) // 2
    for j in range(half):
        b.triangle(b0, top[j + 1], top[j])
    b.triangle(b0, b1, top[half])
    for j in range(half, len(top) - 1):
        b.triangle(b1, top[j + 1], top[j])


@functools.lru_cache(maxsize=4)
def _builtin_mesh_cached(segments: int) -> _io.Mesh:
    from .datasets import _BOSS_CENTER, _BOSS_HEIGHT, _BOSS_RADIUS, _BOX_HALF, _CAP_CENTER, _CAP_RADIUS

    hx, hy, hz = (float(x) for x in _BOX_HALF)
    b = _MeshBuilder()
    phi = 2 * np.pi * np.arange(segments) / segments
    ring = np.column_stack([np.cos(phi), np.sin(phi)])

    # Boss: a cylinder standing on the top face, its bottom ring shared with the face's hole.
    boss_c = np.asarray(_BOSS_CENTER, dtype=float)
    boss_xy = boss_c + _BOSS_RADIUS * ring
    boss_bottom = b.vertices_of(np.column_stack([boss_xy, np.full(segments, hz)]))
    boss_top = b.vertices_of(np.column_stack([boss_xy, np.full(segments, hz + _BOSS_HEIGHT)]))
    b.strip(boss_bottom, boss_top)
    lid = b.vertex((boss_c[0], boss_c[1], hz + _BOSS_HEIGHT))
    for j in range(segments):
        b.triangle(lid, boss_top[j], boss_top[(j + 1) % segments])

    # Cap: the part of a sphere above the top face, in rings from the base circle to the pole.
    cap_c = np.asarray(_CAP_CENTER, dtype=float)
    theta_max = math.acos((hz - cap_c[2]) / _CAP_RADIUS)  # polar angle of the base circle
    n_rings = max(4, segments // 8)
    rings = []
    for k in range(n_rings):
        th = theta_max * (n_rings - k) / n_rings
        if k == 0:  # exactly on the top face, so the face's hole matches bit for bit
            xy = cap_c[:2] + _CAP_RADIUS * math.sin(th) * ring
            pts = np.column_stack([xy, np.full(segments, hz)])
        else:
            pts = cap_c + _CAP_RADIUS * np.column_stack(
                [math.sin(th) * ring, np.full(segments, math.cos(th))]
            )
        rings.append(b.vertices_of(pts))
    for lower, upper in zip(rings[:-1], rings[1:]):
        b.strip(lower, upper)
    pole = b.vertex(cap_c + np.array([0.0, 0.0, _CAP_RADIUS]))
    for j in range(segments):
        b.triangle(pole, rings[-1][j], rings[-1][(j + 1) % segments])
    cap_xy = cap_c[:2] + _CAP_RADIUS * math.sin(theta_max) * ring

    # Top face: split at x = xs between the two holes into two rectangles with one hole each.
    xs = 0.5 * ((boss_c[0] + _BOSS_RADIUS) + (cap_c[0] - _CAP_RADIUS * math.sin(theta_max)))
    spacing = 0.004  # boundary sampling (m): dense enough for the angular merge
    def line(a: float, c: float) -> np.ndarray:
        return np.linspace(a, c, max(2, int(math.ceil(abs(c - a) / spacing)) + 1))

    x_left, x_right, y_all = line(-hx, xs), line(xs, hx), line(-hy, hy)
    # Boundary points, each edge generated once so that faces sharing it share the vertices.
    south = [b.vertex((x, -hy, hz)) for x in np.concatenate([x_left, x_right[1:]])]  # y = -hy, x ascending
    north = [b.vertex((x, hy, hz)) for x in np.concatenate([x_left, x_right[1:]])]   # y = +hy, x ascending
    west = [b.vertex((-hx, y, hz)) for y in y_all]                                    # x = -hx, y ascending
    east = [b.vertex((hx, y, hz)) for y in y_all]                                     # x = +hx, y ascending
    split = [b.vertex((xs, y, hz)) for y in y_all]
    n_left = len(x_left)

    def coords(idx: List[int]) -> np.ndarray:
        return np.array([b.vertices[i][:2] for i in idx])

    left_outer = south[:n_left] + split[1:-1] + north[:n_left] + west[1:-1]
    right_outer = south[n_left - 1:] + east[1:-1] + north[n_left - 1:] + split[1:-1]
    _annulus(b, boss_c, boss_bottom, boss_xy, left_outer, coords(left_outer))
    _annulus(b, cap_c[:2], rings[0], cap_xy, right_outer, coords(right_outer))

    # Side walls (outward normals) and the bottom face.
    c000, c100 = b.vertex((-hx, -hy, -hz)), b.vertex((hx, -hy, -hz))
    c010, c110 = b.vertex((-hx, hy, -hz)), b.vertex((hx, hy, -hz))
    _rectangle_side(b, south, (c000, c100))          # y = -hy
    _rectangle_side(b, north[::-1], (c110, c010))    # y = +hy
    _rectangle_side(b, west[::-1], (c010, c000))     # x = -hx
    _rectangle_side(b, east, (c100, c110))           # x = +hx
    b.triangle(c000, c110, c100)
    b.triangle(c000, c010, c110)
    return b.mesh()


def builtin_mesh(segments: int = 96) -> _io.Mesh:
    """The built-in machined part as a closed triangle mesh (no download needed).

    The same part as :func:`scanalign.datasets.builtin_object` samples, in the same frame
    (metres, origin at the box centre, z up): an 80 x 50 x 30 mm block, a cylindrical boss
    (radius 12 mm, 15 mm high) on its top face at (x, y) = (-15, 0) mm, and a spherical cap
    (radius 15 mm, 6 mm high) at (20, 6) mm. Flat faces, a cylinder and a sphere with no
    symmetry, so point-to-plane ICP is constrained in all six degrees of freedom. The mesh
    is watertight (every edge shared by exactly two faces), wound counter-clockwise seen
    from outside, and has about 3000 triangles for ``segments=96``; the curved surfaces are
    inscribed polygons (chord error 6 um at 96 segments).

    Args:
        segments: vertices around the boss and the cap (>= 8).
    """
    if int(segments) != segments or segments < 8:
        raise ValueError(f"segments must be an integer >= 8, got {segments}")
    m = _builtin_mesh_cached(int(segments))
    return _io.Mesh(m.vertices.copy(), m.faces.copy())


def normalize_mesh(mesh: _io.Mesh, size: float) -> _io.Mesh:
    """A copy of ``mesh`` scaled uniformly so that its largest bounding-box extent is
    ``size`` metres, with its bounding box centred on x = y = 0 and its lowest point at z = 0
    (ready to stand on a table). Use it for meshes in arbitrary units (CGAL's demo meshes are
    about one unit across; CAD files are often in millimetres).

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
    s = size / extent
    offset = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    return _io.Mesh((v - offset) * s, mesh.faces.copy())


def _morton_order(points: np.ndarray, bits: int = 10) -> np.ndarray:
    """Permutation sorting points along a Morton (Z-order) curve of their bounding box."""
    if len(points) == 0:
        return np.zeros(0, np.int64)
    lo = points.min(axis=0)
    ext = float(np.ptp(points, axis=0).max()) or 1.0
    q = np.clip(((points - lo) / ext * (2**bits - 1)).astype(np.uint64), 0, 2**bits - 1)
    code = np.zeros(len(points), dtype=np.uint64)
    for bit in range(bits):
        for axis in range(3):
            code |= ((q[:, axis] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + axis)
    return np.argsort(code, kind="stable")


# --------------------------------------------------------------------------- scene


def _rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _as_color(color: Sequence[float], name: str = "color") -> np.ndarray:
    c = np.asarray(color, dtype=np.float64)
    if c.shape != (3,) or not np.all(np.isfinite(c)) or c.min() < 0 or c.max() > 1:
        raise ValueError(f"{name}: expected three values in [0, 1] (linear RGB), got {color!r}")
    return c


@dataclass
class SceneObject:
    """A mesh placed in the scene.

    Attributes:
        name: label (e.g. the mesh name).
        mesh: the mesh in its own (object) frame, metres.
        T_base_object: 4x4 pose: maps object coordinates into the base frame.
        color: RGB albedo in [0, 1] used for the shaded colour image.
    """

    name: str
    mesh: _io.Mesh
    T_base_object: np.ndarray
    color: Tuple[float, float, float]


class Scene:
    """Objects on a table, in the robot base frame (z up, table top at ``table_height``).

    The table is a finite rectangle (two triangles, normal +z) with a checker pattern in the
    colour image. Rendering uses one combined mesh in the base frame, whose faces are
    reordered along a Morton curve for cache locality; :attr:`face_object` and
    :attr:`face_source` map its faces back to the objects.

    Args:
        table_size: (x, y) size of the table top, metres; None for no table.
        table_center: (x, y) of the table's centre in the base frame, metres.
        table_height: z of the table top in the base frame, metres.
        checker_size: side of a checker square, metres.
        checker_colors: the two RGB albedos of the checker, in [0, 1].
        light_direction: direction towards a distant light in the base frame (normalised
            here); shading is two-sided Lambertian plus ``ambient``.
        ambient: ambient fraction of the light in [0, 1].
    """

    def __init__(
        self,
        table_size: Optional[Tuple[float, float]] = (0.6, 0.6),
        table_center: Tuple[float, float] = (0.5, 0.0),
        table_height: float = 0.0,
        checker_size: float = 0.05,
        checker_colors: Tuple[Sequence[float], Sequence[float]] = ((0.80, 0.78, 0.72), (0.45, 0.43, 0.40)),
        light_direction: Sequence[float] = (0.3, -0.2, 1.0),
        ambient: float = 0.3,
    ) -> None:
        if table_size is not None:
            ts = np.asarray(table_size, dtype=np.float64)
            if ts.shape != (2,) or not np.all(np.isfinite(ts)) or ts.min() <= 0:
                raise ValueError(f"table_size: expected two positive lengths in metres, got {table_size!r}")
            table_size = (float(ts[0]), float(ts[1]))
        tc = np.asarray(table_center, dtype=np.float64)
        if tc.shape != (2,) or not np.all(np.isfinite(tc)):
            raise ValueError(f"table_center: expected (x, y) in metres, got {table_center!r}")
        if not math.isfinite(table_height):
            raise ValueError("table_height must be finite")
        if not (math.isfinite(checker_size) and checker_size > 0):
            raise ValueError("checker_size must be a positive length in metres")
        light = np.asarray(light_direction, dtype=np.float64)
        if light.shape != (3,) or not np.all(np.isfinite(light)) or np.linalg.norm(light) == 0:
            raise ValueError("light_direction must be a non-zero 3-vector")
        if not 0 <= ambient <= 1:
            raise ValueError("ambient must lie in [0, 1]")
        self.table_size = table_size
        self.table_center = (float(tc[0]), float(tc[1]))
        self.table_height = float(table_height)
        self.checker_size = float(checker_size)
        self.checker_colors = (_as_color(checker_colors[0], "checker_colors"),
                               _as_color(checker_colors[1], "checker_colors"))
        self.light_direction = light / np.linalg.norm(light)
        self.ambient = float(ambient)
        self.objects: List[SceneObject] = []
        self._combined: Optional[Dict[str, np.ndarray]] = None

    # ---------------------------------------------------------------- content

    def add_object(
        self,
        mesh: _io.Mesh,
        T_base_object: Optional[np.ndarray] = None,
        *,
        position: Optional[Tuple[float, float]] = None,
        yaw: float = 0.0,
        color: Sequence[float] = (0.75, 0.45, 0.20),
        name: Optional[str] = None,
    ) -> SceneObject:
        """Places a mesh (metres, its own frame) in the scene.

        Either give ``T_base_object`` explicitly, or let the object stand on the table: rotated
        by ``yaw`` (rad) about the vertical, its lowest vertex on the table top, and the centre
        of its bounding box at ``position`` (x, y) in the base frame (default: the table centre).

        Returns:
            The :class:`SceneObject` (its ``T_base_object`` is the pose used).
        """
        if not isinstance(mesh, _io.Mesh):
            raise TypeError(f"mesh: expected scanalign.io.Mesh, got {type(mesh)!r}")
        if mesh.faces.shape[0] == 0:
            raise ValueError("mesh has no faces")
        if T_base_object is not None:
            if position is not None or yaw != 0.0:
                raise ValueError("give either T_base_object or position/yaw, not both")
            T = se3.require_rigid(T_base_object, "T_base_object")
        else:
            if not math.isfinite(yaw):
                raise ValueError("yaw must be finite (radians)")
            xy = np.asarray(self.table_center if position is None else position, dtype=np.float64)
            if xy.shape != (2,) or not np.all(np.isfinite(xy)):
                raise ValueError(f"position: expected (x, y) in metres, got {position!r}")
            R = _rot_z(yaw)
            used = mesh.vertices[np.unique(mesh.faces)]
            if not np.all(np.isfinite(used)):
                raise ValueError("mesh has non-finite vertices")
            rotated = used @ R.T
            lo, hi = rotated.min(axis=0), rotated.max(axis=0)
            T = np.eye(4)
            T[:3, :3] = R
            T[:3, 3] = [xy[0] - (lo[0] + hi[0]) / 2, xy[1] - (lo[1] + hi[1]) / 2, self.table_height - lo[2]]
        obj = SceneObject(
            name=name or f"object{len(self.objects)}",
            mesh=mesh,
            T_base_object=T,
            color=tuple(float(c) for c in _as_color(color)),  # type: ignore[arg-type]
        )
        self.objects.append(obj)
        self._combined = None
        return obj

    @property
    def center(self) -> np.ndarray:
        """(3,) centre of the objects' bounding box in the base frame, at table height (the
        default target of trajectories); the table centre when there are no objects."""
        if not self.objects:
            return np.array([*self.table_center, self.table_height])
        v = self.object_mesh.vertices
        lo, hi = v.min(axis=0), v.max(axis=0)
        return np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, self.table_height])

    def _build(self) -> Dict[str, np.ndarray]:
        if self._combined is not None:
            return self._combined
        verts, faces, owner, source, albedo = [], [], [], [], []
        offset = 0
        for k, obj in enumerate(self.objects):
            v = obj.mesh.vertices @ obj.T_base_object[:3, :3].T + obj.T_base_object[:3, 3]
            f = obj.mesh.faces
            # Faces in Morton order of their centroids and vertices in order of first use:
            # neighbouring faces end up close in memory, which cuts the renderer's cache misses
            # on meshes stored in random order. Unused vertices are dropped.
            order = _morton_order(v[f].mean(axis=1)) if len(f) > 1 else np.arange(len(f))
            f = f[order]
            used, first = np.unique(f.ravel(), return_index=True)
            by_first_use = used[np.argsort(first, kind="stable")]
            remap = np.empty(len(v), dtype=np.int64)
            remap[by_first_use] = np.arange(len(by_first_use))
            v = v[by_first_use]
            verts.append(v)
            faces.append(remap[f] + offset)
            owner.append(np.full(len(f), k, dtype=np.int32))
            source.append(order.astype(np.int64))
            albedo.append(np.tile(obj.color, (len(f), 1)))
            offset += len(v)
        n_object_faces = sum(len(f) for f in faces)
        if self.table_size is not None:
            sx, sy = self.table_size
            cx, cy = self.table_center
            z = self.table_height
            tv = np.array([[cx - sx / 2, cy - sy / 2, z], [cx + sx / 2, cy - sy / 2, z],
                           [cx + sx / 2, cy + sy / 2, z], [cx - sx / 2, cy + sy / 2, z]])
            verts.append(tv)
            faces.append(np.array([[0, 1, 2], [0, 2, 3]]) + offset)
            owner.append(np.full(2, -1, dtype=np.int32))
            source.append(np.arange(2))
            albedo.append(np.tile(self.checker_colors[0], (2, 1)))
        V = np.concatenate(verts) if verts else np.zeros((0, 3))
        F = np.concatenate(faces).astype(np.int32) if faces else np.zeros((0, 3), np.int32)
        corners = V[F]
        n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        norm = np.linalg.norm(n, axis=1, keepdims=True)
        normals = np.divide(n, norm, out=np.zeros_like(n), where=norm > 0)
        self._combined = {
            "vertices": np.ascontiguousarray(V),
            "faces": np.ascontiguousarray(F),
            "owner": np.concatenate(owner) if owner else np.zeros(0, np.int32),
            "source": np.concatenate(source) if source else np.zeros(0, np.int64),
            "albedo": np.concatenate(albedo) if albedo else np.zeros((0, 3)),
            "normals": normals,
            "n_object_faces": np.array(n_object_faces),
        }
        return self._combined

    @property
    def mesh(self) -> _io.Mesh:
        """The whole scene (objects and table) as one mesh in the base frame, metres. Its
        face order is the renderer's: ``RenderResult.face_id`` indexes these faces."""
        c = self._build()
        return _io.Mesh(c["vertices"].copy(), c["faces"].astype(np.int64))

    @property
    def object_mesh(self) -> _io.Mesh:
        """The objects only (no table) as one mesh in the base frame, metres; its faces are
        the first ``len(object_mesh.faces)`` faces of :attr:`mesh`."""
        c = self._build()
        n = int(c["n_object_faces"])
        F = c["faces"][:n].astype(np.int64)
        used = np.unique(F)
        remap = np.full(len(c["vertices"]), -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        return _io.Mesh(c["vertices"][used].copy(), remap[F])

    @property
    def face_object(self) -> np.ndarray:
        """(F,) int32: for each face of :attr:`mesh`, the index of its object in
        :attr:`objects`, or -1 for the table."""
        return self._build()["owner"].copy()

    @property
    def face_source(self) -> np.ndarray:
        """(F,) int64: for each face of :attr:`mesh`, its row in its object's own mesh (or
        in the table's two triangles)."""
        return self._build()["source"].copy()

    # ---------------------------------------------------------------- images

    def render(
        self,
        T_base_camera: np.ndarray,
        intrinsics: Union[Intrinsics, str],
        *,
        near: float = 0.01,
        far: float = math.inf,
        num_threads: int = 0,
    ) -> RenderResult:
        """Noise-free depth, face ids and incidence for a camera at ``T_base_camera``
        (camera -> base). Face ids index :attr:`mesh`."""
        c = self._build()
        T = se3.require_rigid(T_base_camera, "T_base_camera")
        return render_depth(c["vertices"], c["faces"], intrinsics, se3.inverse(T), near=near, far=far,
                            num_threads=num_threads)

    def _prepare_shading(self) -> None:
        """Colour of every face under the fixed light, for both checker albedos (they differ
        on table faces only); the last row is the background (black). Built once."""
        c = self._build()
        if "lut" in c:
            return
        lambert = np.abs(c["normals"] @ self.light_direction)
        intensity = (self.ambient + (1.0 - self.ambient) * lambert)[:, None]
        alt = c["albedo"].copy()
        alt[c["owner"] < 0] = self.checker_colors[1]

        def to8(a: np.ndarray) -> np.ndarray:
            return np.vstack([np.clip(a * 255.0 + 0.5, 0, 255).astype(np.uint8), np.zeros((1, 3), np.uint8)])

        c["lut_alt"] = to8(alt * intensity)
        c["lut"] = to8(c["albedo"] * intensity)

    def shade(self, result: RenderResult, T_base_camera: np.ndarray,
              intrinsics: Union[Intrinsics, str]) -> np.ndarray:
        """(H, W, 3) uint8 colour image registered to ``result`` (same pixels): two-sided
        Lambertian shading of each face's albedo (the object's colour, or the table's checker
        at the point hit) under :attr:`light_direction`; black where nothing is hit."""
        c = self._build()
        K = _check_intrinsics(intrinsics)
        T = as_transform(T_base_camera, "T_base_camera")
        fid = np.asarray(result.face_id)
        if fid.shape != K.shape:
            raise ValueError(f"result has shape {fid.shape}, intrinsics expect {K.shape}")
        n_faces = len(c["faces"])
        self._prepare_shading()
        idx = np.where(fid >= 0, fid, n_faces)
        rgb = c["lut"][idx]
        n_obj = int(c["n_object_faces"])
        table = (idx >= n_obj) & (idx < n_faces)  # the table's faces come last
        if np.any(table):
            # Checker parity from the base-frame point hit on the table: back-project.
            v, u = np.nonzero(table)
            z = result.depth[v, u].astype(np.float64)
            xc = (u - K.cx) * (z / K.fx)
            yc = (v - K.cy) * (z / K.fy)
            px = T[0, 0] * xc + T[0, 1] * yc + T[0, 2] * z + T[0, 3]
            py = T[1, 0] * xc + T[1, 1] * yc + T[1, 2] * z + T[1, 3]
            cell = np.floor((px - self.table_center[0]) / self.checker_size) + np.floor(
                (py - self.table_center[1]) / self.checker_size)
            odd = np.mod(cell, 2.0) == 1.0
            rgb[v[odd], u[odd]] = c["lut_alt"][idx[v[odd], u[odd]]]
        return rgb


# --------------------------------------------------------------------------- trajectories


def _default_hand_eye() -> np.ndarray:
    T = np.eye(4)
    # Camera mounted beside the gripper: 3.5 cm off the tool axis along flange x, 5 cm in
    # front of the flange along its z, looking along the tool axis, with the few-degree
    # misalignment a real bracket has (so the hand-eye transform is not a pure offset).
    T[:3, :3] = se3.rotation_about([1.0, 0.0, 0.0], math.radians(3.0)) @ se3.rotation_about([0.0, 1.0, 0.0], math.radians(-2.0)) @ se3.rotation_about(
        [0.0, 0.0, 1.0], math.radians(1.0))
    T[:3, 3] = [0.035, 0.0, 0.05]
    return T


#: Default hand-eye calibration ``T_flange_camera`` (camera -> flange): camera 5 cm in front
#: of the flange along its z axis and 3.5 cm off-axis along its x axis, optical axis along
#: the tool axis rotated by 3 deg about x, -2 deg about y and 1 deg about z.
DEFAULT_T_FLANGE_CAMERA: np.ndarray = _default_hand_eye()
DEFAULT_T_FLANGE_CAMERA.setflags(write=False)


def look_at(eye: Sequence[float], target: Sequence[float], up: Sequence[float] = (0.0, 0.0, 1.0)) -> np.ndarray:
    """The camera pose ``T_base_camera`` at ``eye`` whose optical axis (camera z) points at
    ``target``, with the image's up direction (camera -y) as close as possible to ``up``
    (base frame, metres).

    Raises:
        ValueError: eye == target, or the viewing direction parallel to ``up``.
    """
    eye, target, up = (np.asarray(x, dtype=np.float64) for x in (eye, target, up))
    z = target - eye
    if not np.linalg.norm(z) > 0:
        raise ValueError("look_at: eye and target coincide")
    z /= np.linalg.norm(z)
    up_perp = up - (up @ z) * z
    if np.linalg.norm(up_perp) < 1e-9 * max(1.0, np.linalg.norm(up)):
        raise ValueError("look_at: viewing direction parallel to up; give another up vector")
    y = -up_perp / np.linalg.norm(up_perp)
    x = np.cross(y, z)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, y, z])
    T[:3, 3] = eye
    return T


@dataclass
class ScanTrajectory:
    """Robot poses of a scan and the camera poses they give.

    Attributes:
        T_base_flange: (N, 4, 4) flange poses (flange -> base), metres. With a robot, forward
            kinematics of :attr:`joints`: ``robot.fk(joints)``.
        T_flange_camera: (4, 4) hand-eye transform (camera -> flange).
        timestamps: (N,) seconds.
        joints: (N, 6) joint values of the robot (rad, as its controller reports them), or
            None when the poses were planned without a robot.
        robot: the :class:`scanalign.kinematics.Robot` that moves the camera, placed in the
            scene (its base transform is ``T_base_robot``, its tool the flange), so that
            ``robot.fk(joints)`` is :attr:`T_base_flange`; None without a robot.
        T_base_robot: (4, 4) where the robot's own base frame is mounted in the scene
            (robot base -> scene base), or None.
    """

    T_base_flange: np.ndarray
    T_flange_camera: np.ndarray
    timestamps: np.ndarray
    joints: Optional[np.ndarray] = None
    robot: Optional[Any] = None
    T_base_robot: Optional[np.ndarray] = None

    def __post_init__(self) -> None:
        self.T_base_flange = np.asarray(self.T_base_flange, dtype=np.float64)
        if self.T_base_flange.ndim != 3 or self.T_base_flange.shape[1:] != (4, 4):
            raise ValueError(f"T_base_flange: expected shape (N, 4, 4), got {self.T_base_flange.shape}")
        self.T_flange_camera = se3.require_rigid(self.T_flange_camera, "T_flange_camera")
        self.timestamps = np.asarray(self.timestamps, dtype=np.float64).reshape(-1)
        if len(self.timestamps) != len(self.T_base_flange):
            raise ValueError("one timestamp per pose expected")
        if self.joints is not None:
            self.joints = np.asarray(self.joints, dtype=np.float64)
            if self.joints.shape != (len(self.T_base_flange), 6):
                raise ValueError(f"joints: expected shape ({len(self.T_base_flange)}, 6), got {self.joints.shape}")
        if self.T_base_robot is not None:
            self.T_base_robot = se3.require_rigid(self.T_base_robot, "T_base_robot")

    def __len__(self) -> int:
        return len(self.T_base_flange)

    @property
    def T_base_camera(self) -> np.ndarray:
        """(N, 4, 4) camera poses ``T_base_flange @ T_flange_camera``."""
        return self.T_base_flange @ self.T_flange_camera

    @property
    def reference(self) -> Trajectory:
        """The exact camera trajectory (``T_base_camera`` per frame) as a :class:`Trajectory`."""
        return Trajectory(self.timestamps.copy(), self.T_base_camera)


#: Default height (m) of the scan robot's base above the table top (:func:`robot_mount`).
DEFAULT_ROBOT_HEIGHT: float = 0.90


def robot_mount(x: float = 0.5, y: float = 0.0, z: float = DEFAULT_ROBOT_HEIGHT, roll: float = math.pi,
                pitch: float = 0.0, yaw: float = 0.0) -> np.ndarray:
    """``T_base_robot``: where a robot's own base frame sits in the scene (robot base ->
    scene base), from a position (m) and roll / pitch / yaw angles (rad, rotation
    ``Rz(yaw) @ Ry(pitch) @ Rx(roll)``, as URDF).

    The default mounts the arm upside down (roll = pi: its first joint axis points down)
    0.9 m above the table centre of the default scene, e.g. on a gantry or the ceiling. A
    camera that circles an object all the way round has to circle the arm's first axis
    too: from a base beside the table, a UR5 (reach 0.85 m) cannot reach the far side of
    the default hemisphere path, and the near side passes through the shoulder
    singularity (the wrist within d4 = 0.11 m of the first axis). From above, both default
    paths (the loop 40 cm above the table and the hemisphere at 35-75 deg elevation) lie
    0.15-0.47 m from the first axis and 0.3-0.7 m from the shoulder, well inside the
    workspace and away from every singularity.
    """
    vals = (x, y, z, roll, pitch, yaw)
    if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in vals):
        raise ValueError(f"robot_mount: expected finite numbers (m, rad), got {vals!r}")
    T = np.eye(4)
    T[:3, :3] = se3.rotation_about([0.0, 0.0, 1.0], yaw) @ se3.rotation_about([0.0, 1.0, 0.0], pitch) @ se3.rotation_about([1.0, 0.0, 0.0], roll)
    T[:3, 3] = [x, y, z]
    return T


def _as_robot(robot: Any) -> Any:
    from . import kinematics as kin

    if isinstance(robot, str):
        return kin.Robot.by_name(robot)
    if not isinstance(robot, kin.Robot):
        raise TypeError(f"robot: expected a scanalign.kinematics.Robot or a robot name, got {type(robot)!r}")
    return robot


def attach_robot(
    trajectory: ScanTrajectory,
    robot: Any = "ur5",
    *,
    T_base_robot: Optional[np.ndarray] = None,
    q_start: Optional[Sequence[float]] = None,
    elbow: str = "up",
) -> ScanTrajectory:
    """Moves a planned camera path with a robot arm: joints by inverse kinematics, poses
    by forward kinematics.

    The planned flange poses (``trajectory.T_base_flange``, i.e. the planned camera poses
    times ``inv(T_flange_camera)``) are mapped into the robot's base frame,
    ``inv(T_base_robot) @ T_base_flange``; :meth:`Robot.ik_trajectory` takes at each step
    the inverse-kinematics solution closest to the previous step's joints; and forward
    kinematics of those joints gives the returned flange poses, so the reference camera
    poses are the robot's own (equal to the planned ones up to rounding, ~1e-15 m, since
    the IK is exact).

    The start configuration, unless ``q_start`` is given, is chosen among the solutions of
    the first pose: those with the requested ``elbow`` ("up": the elbow on the side of the
    arm away from the table -- IK label elbow = +1 for an upright base, -1 for a hanging
    one; "down": the other; "any"), each with its first and last joint shifted by -2 pi, 0
    and +2 pi where the limits allow; the one whose trajectory reaches every pose with the
    smallest largest joint step wins (ties within 1e-9 rad: the lowest configuration index,
    then no shift before -2 pi before +2 pi). So a loop
    around the first axis starts where it can turn all the way without leaving the joint
    limits, and no step switches branch.

    Args:
        trajectory: the planned path (its ``T_base_flange`` and ``T_flange_camera``).
        robot: a :class:`scanalign.kinematics.Robot` or a name for
            :meth:`Robot.by_name` ("ur5", ...); its tool transform is replaced by the
            flange (the camera's hand-eye transform plays that role), its base transform
            by ``T_base_robot`` (composed with the model's own DH-frame-0 placement).
        T_base_robot: (4, 4) mounting of the robot base in the scene (robot base -> scene
            base, metres); default :func:`robot_mount` ``()``.
        q_start: (6,) joints (rad) to start from instead of the automatic choice: the first
            step is the solution closest to it.
        elbow: "up", "down" or "any" (see above; ignored with ``q_start``).

    Returns:
        A new :class:`ScanTrajectory` with ``joints``, ``robot`` (placed in the scene) and
        ``T_base_robot`` set.

    Raises:
        ValueError: a pose the robot cannot reach, or reaches only outside its joint limits
            (the message names the frame, its time and the IK status), a bad ``elbow`` or
            ``q_start``, or a malformed ``T_base_robot``.
        TypeError: ``robot`` of another type.
    """
    if not isinstance(trajectory, ScanTrajectory):
        raise TypeError(f"trajectory: expected ScanTrajectory, got {type(trajectory)!r}")
    if elbow not in ("up", "down", "any"):
        raise ValueError(f"elbow must be 'up', 'down' or 'any', got {elbow!r}")
    model = _as_robot(robot).with_tool(np.eye(4))
    Tbr = robot_mount() if T_base_robot is None else se3.require_rigid(T_base_robot, "T_base_robot")
    # Flange poses in the robot's own base frame, which is what its controller (and IK) sees.
    T_robot_flange = se3.inverse(Tbr) @ trajectory.T_base_flange
    n = len(T_robot_flange)
    stamps = trajectory.timestamps

    def where(k: int) -> str:
        p = T_robot_flange[k, :3, 3]
        return (f"frame {k} (t = {stamps[k]:.3f} s, flange at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) m in the "
                f"{model.name} base frame)")

    def run(q0: np.ndarray) -> Tuple[Any, float]:
        tr = model.ik_trajectory(T_robot_flange, q0)
        if not np.all(tr.ok):
            return tr, math.inf
        steps = np.abs(np.diff(np.vstack([q0[None], tr.q]), axis=0))
        return tr, float(steps.max())

    if q_start is not None:
        q0 = np.asarray(q_start, dtype=np.float64).reshape(-1)
        if q0.shape != (6,) or not np.all(np.isfinite(q0)):
            raise ValueError(f"q_start: expected 6 finite joint values (rad), got {q_start!r}")
        best, _ = run(q0)
    else:
        first = model.ik(T_robot_flange[0])
        ok = np.asarray(first.ok, dtype=bool)
        if not ok.any():
            status = sorted(set(first.status), key=("outside_limits", "unreachable", "invalid_input", "ok").index)
            raise ValueError(f"robot {model.name} mounted at T_base_robot cannot reach {where(0)}: IK status "
                             f"{status[0]!r} for every configuration; move the robot (T_base_robot) or the path")
        # Elbow label of "up" in the scene: +1 when the robot's z axis points upwards.
        z_up = (Tbr @ model.T_base_dh0)[2, 2] >= 0
        want = {"up": 1 if z_up else -1, "down": -1 if z_up else 1, "any": 0}[elbow]
        candidates = [k for k in range(8) if ok[k] and (want == 0 or int(first.config[k][1]) == want)]
        if not candidates:
            raise ValueError(f"robot {model.name}: no elbow-{elbow} solution within the joint limits for {where(0)}; "
                             f"use elbow='any' or another mount")
        lo, hi = model.limits[:, 0], model.limits[:, 1]
        best, best_step = None, math.inf
        for k in candidates:
            for d1 in (0.0, -2 * math.pi, 2 * math.pi):
                for d6 in (0.0, -2 * math.pi, 2 * math.pi):
                    q0 = np.array(first.q[k], dtype=np.float64)
                    q0[0] += d1
                    q0[5] += d6
                    if np.any(q0 < lo) or np.any(q0 > hi):
                        continue
                    tr, step = run(q0)
                    # Strictly smaller by more than rounding: equal steps keep the earlier
                    # candidate (lower configuration index, no shift first).
                    if best is None or step < best_step - 1e-9 or (
                            step == best_step == math.inf and np.count_nonzero(tr.ok) > np.count_nonzero(best.ok)):
                        best, best_step = tr, step
    if not np.all(best.ok):
        k = int(np.flatnonzero(~np.asarray(best.ok, dtype=bool))[0])
        raise ValueError(f"robot {model.name} mounted at T_base_robot cannot follow the camera path: {where(k)} "
                         f"has IK status {best.status[k]!r} ({int(np.count_nonzero(best.ok))} of {n} frames "
                         f"reachable); move the robot (T_base_robot) or the path")
    q = np.array(best.q, dtype=np.float64)
    placed = model.with_base(Tbr @ model.T_base_dh0)
    T_base_flange = placed.fk(q)
    return ScanTrajectory(T_base_flange, trajectory.T_flange_camera.copy(), stamps.copy(), joints=q, robot=placed,
                          T_base_robot=Tbr.copy())


def _scan_from_camera_poses(T_base_camera: np.ndarray, T_flange_camera: Optional[np.ndarray], frame_rate: float,
                            jitter_translation: float, jitter_rotation: float, seed: int) -> ScanTrajectory:
    Tfc = DEFAULT_T_FLANGE_CAMERA if T_flange_camera is None else se3.require_rigid(T_flange_camera, "T_flange_camera")
    if not (math.isfinite(frame_rate) and frame_rate > 0):
        raise ValueError("frame_rate must be positive (Hz)")
    if not (jitter_translation >= 0 and jitter_rotation >= 0):
        raise ValueError("jitter amplitudes must be non-negative")
    T_cam = np.array(T_base_camera, dtype=np.float64)
    if jitter_translation > 0 or jitter_rotation > 0:
        # Vibration-like perturbation of where the camera really is; the reference records
        # the perturbed pose, so it stays exact.
        rng = np.random.default_rng(seed)
        for T in T_cam:
            axis = rng.normal(size=3)
            T[:3, :3] = se3.rotation_about(axis, rng.normal() * jitter_rotation) @ T[:3, :3]
            T[:3, 3] += rng.normal(size=3) * jitter_translation
    T_base_flange = T_cam @ se3.inverse(np.asarray(Tfc))
    return ScanTrajectory(T_base_flange, np.array(Tfc), np.arange(len(T_cam)) / frame_rate)


def _with_robot(traj: ScanTrajectory, robot: Any, T_base_robot: Optional[np.ndarray],
                q_start: Optional[Sequence[float]], center: np.ndarray) -> ScanTrajectory:
    if robot is None or (isinstance(robot, str) and robot == "none"):
        if T_base_robot is not None or q_start is not None:
            raise ValueError("T_base_robot and q_start need a robot")
        return traj
    if T_base_robot is None:
        T_base_robot = robot_mount(float(center[0]), float(center[1]), float(center[2]) + DEFAULT_ROBOT_HEIGHT)
    return attach_robot(traj, robot, T_base_robot=T_base_robot, q_start=q_start)


def loop_trajectory(
    n_frames: int = 36,
    *,
    center: Sequence[float] = (0.5, 0.0, 0.0),
    height: float = 0.40,
    radius: float = 0.20,
    start_angle: float = 0.0,
    sweep: float = 2 * math.pi,
    target: Optional[Sequence[float]] = None,
    T_flange_camera: Optional[np.ndarray] = None,
    frame_rate: float = 10.0,
    jitter_translation: float = 0.0,
    jitter_rotation: float = 0.0,
    seed: int = 0,
    robot: Any = None,
    T_base_robot: Optional[np.ndarray] = None,
    q_start: Optional[Sequence[float]] = None,
) -> ScanTrajectory:
    """A loop around the object, like seed 000 Fig. 4: the camera circles at ``height``
    above the table, tilted to look at the target.

    Camera ``k`` sits at ``center + (radius cos a_k, radius sin a_k, height)`` with
    ``a_k = start_angle + sweep k / n_frames`` (a full loop by default, without repeating the
    first pose), its optical axis through ``target``, image up towards +z. Flange poses are
    ``T_base_camera @ inv(T_flange_camera)``, so composing them with the hand-eye transform
    gives the camera poses back. Timestamps are ``k / frame_rate`` (10 Hz like the seed).

    Args:
        n_frames: number of poses (>= 1).
        center: loop centre on the table, base frame (m).
        height: camera height above ``center`` (m, > 0).
        radius: loop radius (m, >= 0).
        start_angle, sweep: first azimuth and swept angle (rad).
        target: point looked at (m); default ``center``.
        T_flange_camera: hand-eye transform; default :data:`DEFAULT_T_FLANGE_CAMERA`.
        frame_rate: Hz.
        jitter_translation, jitter_rotation: standard deviations (m, rad) of an optional
            random perturbation of each camera pose (the reference includes it). 0: smooth.
        seed: seed of the jitter.
        robot: None (default): the flange poses are the planned ones, no arm. A robot name
            ("ur5") or :class:`scanalign.kinematics.Robot`: the arm follows the path
            (:func:`attach_robot`), the trajectory carries its joints, and its poses are
            forward kinematics of them.
        T_base_robot: with a robot, its mounting in the scene (robot base -> base, m);
            default :func:`robot_mount` hanging :data:`DEFAULT_ROBOT_HEIGHT` above ``center``.
        q_start: with a robot, joints (rad) to start from (default: chosen automatically,
            elbow up; see :func:`attach_robot`).
    """
    if int(n_frames) != n_frames or n_frames < 1:
        raise ValueError(f"n_frames must be a positive integer, got {n_frames}")
    c = np.asarray(center, dtype=np.float64)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ValueError(f"center: expected (x, y, z) in metres, got {center!r}")
    if not (math.isfinite(height) and height > 0):
        raise ValueError(f"height must be a positive distance in metres, got {height}")
    if not (math.isfinite(radius) and radius >= 0):
        raise ValueError(f"radius must be a non-negative distance in metres, got {radius}")
    if not (math.isfinite(start_angle) and math.isfinite(sweep)):
        raise ValueError("start_angle and sweep must be finite (radians)")
    tgt = c if target is None else np.asarray(target, dtype=np.float64)
    poses = []
    for k in range(int(n_frames)):
        a = start_angle + sweep * k / n_frames
        radial = np.array([math.cos(a), math.sin(a), 0.0])
        eye = c + radius * radial + np.array([0.0, 0.0, height])
        # Straight down (radius 0): keep the image up pointing outwards along the azimuth.
        up = np.array([0.0, 0.0, 1.0]) if radius > 1e-9 * height else radial
        poses.append(look_at(eye, tgt, up))
    traj = _scan_from_camera_poses(np.array(poses), T_flange_camera, frame_rate, jitter_translation,
                                   jitter_rotation, seed)
    return _with_robot(traj, robot, T_base_robot, q_start, c)


def hemisphere_trajectory(
    n_frames: int = 48,
    *,
    center: Sequence[float] = (0.5, 0.0, 0.0),
    distance: float = 0.45,
    elevations: Sequence[float] = (math.radians(35.0), math.radians(55.0), math.radians(75.0)),
    start_angle: float = 0.0,
    target: Optional[Sequence[float]] = None,
    T_flange_camera: Optional[np.ndarray] = None,
    frame_rate: float = 10.0,
    jitter_translation: float = 0.0,
    jitter_rotation: float = 0.0,
    seed: int = 0,
    robot: Any = None,
    T_base_robot: Optional[np.ndarray] = None,
    q_start: Optional[Sequence[float]] = None,
) -> ScanTrajectory:
    """Rings on a hemisphere of radius ``distance`` around the target, one per elevation.

    Frames are shared between rings in proportion to the rings' circumferences
    (``cos(elevation)``, at least one each); successive rings run in opposite directions and
    each starts where the previous ended, so the path is one continuous serpentine. Every
    camera looks at ``target`` (default ``center``) with image up towards +z (outwards for
    an elevation of 90 deg).

    Args:
        n_frames: total number of poses (>= number of rings).
        center: centre of the hemisphere's base on the table, base frame (m).
        distance: camera distance to the target (m).
        elevations: ring elevations above the table plane (rad, in (0, pi/2]).
        start_angle: azimuth of the first pose (rad).
        target, T_flange_camera, frame_rate, jitter_translation, jitter_rotation, seed,
            robot, T_base_robot, q_start: as for :func:`loop_trajectory`.
    """
    el = np.asarray(elevations, dtype=np.float64).reshape(-1)
    if el.size == 0 or not np.all((el > 0) & (el <= math.pi / 2 + 1e-12)):
        raise ValueError("elevations must be non-empty and in (0, pi/2] radians")
    if int(n_frames) != n_frames or n_frames < el.size:
        raise ValueError(f"n_frames must be an integer >= the number of rings ({el.size}), got {n_frames}")
    if not (math.isfinite(distance) and distance > 0):
        raise ValueError(f"distance must be a positive length in metres, got {distance}")
    c = np.asarray(center, dtype=np.float64)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ValueError(f"center: expected (x, y, z) in metres, got {center!r}")
    tgt = c if target is None else np.asarray(target, dtype=np.float64)
    # Largest-remainder apportionment of the frames to the rings.
    weight = np.maximum(np.cos(el), 1e-3)
    extra = n_frames - el.size
    share = weight / weight.sum() * extra
    counts = 1 + np.floor(share).astype(int)
    for i in np.argsort(-(share - np.floor(share)))[: n_frames - counts.sum()]:
        counts[i] += 1
    poses = []
    azimuth = start_angle
    for r, (e, n) in enumerate(zip(el, counts)):
        direction = 1.0 if r % 2 == 0 else -1.0
        step = 2 * math.pi / n
        for k in range(n):
            a = azimuth + direction * step * k
            radial = np.array([math.cos(a), math.sin(a), 0.0])
            eye = tgt + distance * (math.cos(e) * radial + np.array([0.0, 0.0, math.sin(e)]))
            up = np.array([0.0, 0.0, 1.0]) if math.cos(e) > 1e-6 else radial
            poses.append(look_at(eye, tgt, up))
        azimuth = azimuth + direction * step * (n - 1)
    traj = _scan_from_camera_poses(np.array(poses), T_flange_camera, frame_rate, jitter_translation,
                                   jitter_rotation, seed)
    return _with_robot(traj, robot, T_base_robot, q_start, c)


# --------------------------------------------------------------------------- sensor noise


@dataclass(frozen=True)
class SensorNoise:
    """A depth sensor's error model, applied to noise-free depth.

    In order: pixels are dropped at grazing incidence (``|cos| < grazing_cos``), on both
    sides of depth discontinuities (a 4-neighbour more than ``edge_threshold`` times the
    depth nearer or farther, or missing) dilated to ``edge_width`` pixels, and at random with
    probability ``dropout``; the rest get axial Gaussian noise of standard deviation
    ``sigma(z) = axial_sigma_ref * (z / z_ref)**2`` (triangulation sensors: the depth error
    grows with the square of the distance); values outside ``[min_range, max_range]`` are
    dropped; the result is rounded to multiples of ``depth_unit`` (the sensor's own
    quantisation; 0 = none).

    Attributes:
        name: label.
        axial_sigma_ref: standard deviation of the depth error at ``z_ref`` (m).
        z_ref: reference depth (m).
        depth_unit: quantisation step of the reported depth (m); 0 for none.
        min_range, max_range: measurable depth range (m).
        grazing_cos: minimum |cosine of incidence| for a measurement.
        edge_threshold: relative depth jump marking a discontinuity; 0 disables edge dropout.
        edge_width: pixels dropped on each side of a discontinuity (>= 1 when enabled).
        dropout: probability that any other pixel is missing.
    """

    name: str = "custom"
    axial_sigma_ref: float = 0.0
    z_ref: float = 1.0
    depth_unit: float = 0.0
    min_range: float = 0.0
    max_range: float = math.inf
    grazing_cos: float = 0.0
    edge_threshold: float = 0.0
    edge_width: int = 0
    dropout: float = 0.0

    def __post_init__(self) -> None:
        for n in ("axial_sigma_ref", "depth_unit", "min_range", "grazing_cos", "edge_threshold", "dropout"):
            v = getattr(self, n)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"SensorNoise.{n} must be finite and >= 0, got {v!r}")
        if not (math.isfinite(self.z_ref) and self.z_ref > 0):
            raise ValueError("SensorNoise.z_ref must be positive (m)")
        if not self.max_range > self.min_range:
            raise ValueError("SensorNoise.max_range must exceed min_range")
        if self.grazing_cos >= 1 or self.dropout >= 1:
            raise ValueError("SensorNoise.grazing_cos and dropout must be < 1")
        if int(self.edge_width) != self.edge_width or self.edge_width < 0:
            raise ValueError("SensorNoise.edge_width must be a non-negative integer")

    def sigma(self, z: Union[float, np.ndarray]) -> Union[float, np.ndarray]:
        """Axial standard deviation (m) at depth ``z`` (m)."""
        return self.axial_sigma_ref * (np.asarray(z) / self.z_ref) ** 2

    def apply(self, depth: np.ndarray, cos_incidence: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Noisy (H, W) float32 depth in metres (NaN = missing) from noise-free ``depth``
        (float, NaN = nothing hit) and the rendered ``cos_incidence``; all randomness from
        ``rng``."""
        z = np.asarray(depth, dtype=np.float32)
        valid = np.isfinite(z)
        if self.grazing_cos > 0:
            valid &= np.abs(cos_incidence) >= self.grazing_cos
        if self.edge_threshold > 0 and self.edge_width > 0:
            valid &= ~_depth_edges(z, self.edge_threshold, int(self.edge_width))
        if self.dropout > 0:
            valid &= rng.random(z.shape, dtype=np.float32) >= self.dropout
        out = np.full(z.shape, np.nan, dtype=np.float32)
        zv = z[valid].astype(np.float64)
        if self.axial_sigma_ref > 0:
            zv = zv + self.sigma(zv) * rng.standard_normal(zv.shape, dtype=np.float32)
        keep = (zv >= self.min_range) & (zv <= self.max_range)
        if self.depth_unit > 0:
            zv = np.round(zv / self.depth_unit) * self.depth_unit
        zv[~keep] = np.nan
        out[valid] = zv
        return out


def _depth_edges(z: np.ndarray, threshold: float, width: int) -> np.ndarray:
    """Pixels within ``width`` pixels of a depth discontinuity: a 4-neighbour pair whose
    depths differ by more than ``threshold`` times the nearer one, or where exactly one of
    the two sees a surface (a silhouette against the void). Both sides are marked."""
    valid = np.isfinite(z)
    zz = np.where(valid, z, 0.0)
    edge = np.zeros(z.shape, dtype=bool)
    for axis in (0, 1):
        a = [slice(None)] * 2
        b = [slice(None)] * 2
        a[axis], b[axis] = slice(None, -1), slice(1, None)
        za, zb = zz[tuple(a)], zz[tuple(b)]
        va, vb = valid[tuple(a)], valid[tuple(b)]
        jump = (va != vb) | (va & vb & (np.abs(za - zb) > threshold * np.minimum(za, zb)))
        edge[tuple(a)] |= jump
        edge[tuple(b)] |= jump
    for _ in range(width - 1):  # dilate by one pixel per step (4-neighbourhood)
        grown = edge.copy()
        grown[1:] |= edge[:-1]
        grown[:-1] |= edge[1:]
        grown[:, 1:] |= edge[:, :-1]
        grown[:, :-1] |= edge[:, 1:]
        edge = grown
    return edge & valid


#: Sensor presets. The axial noise follows the triangulation law sigma = z^2 * e / (f * b)
#: (disparity error e in pixels, focal length f in pixels, baseline b), hence sigma(z) =
#: sigma_ref (z / z_ref)^2:
#:
#: - ``"sr300"``: Intel RealSense SR300 (coded light, the seed's robot camera): about 1 mm at
#:   0.4 m; depth unit 1/8 mm (its default depth scale); range 0.2-1.5 m (datasheet); it loses
#:   pixels beyond ~78 deg incidence and one pixel around depth edges (projector shadow).
#: - ``"d435"``: Intel RealSense D435 (active stereo, the seed's free-hand camera) at 640x480:
#:   f = 385 px, b = 50 mm and a typical sub-pixel disparity error of 0.15 px give
#:   0.15 / (385 * 0.05) = 7.8e-3 /m, i.e. 1.95 mm at 0.5 m; depth unit 1 mm (its default);
#:   minimum depth about 0.175 m at this resolution, 3 m useful maximum; stereo matching
#:   fails at grazing angles (~75 deg) and fattens edges (2 pixels), plus 0.5 % random holes.
#: - ``"zivid"``: Zivid Two-like structured-light industrial camera: about 0.1 mm at 0.5 m,
#:   no quantisation of its float output, working range 0.3-1.2 m, few holes.
#: - ``"none"``: the exact rendered depth.
NOISE_PRESETS: Dict[str, SensorNoise] = {
    "none": SensorNoise(name="none"),
    "sr300": SensorNoise(name="sr300", axial_sigma_ref=0.0010, z_ref=0.4, depth_unit=0.000125, min_range=0.2,
                         max_range=1.5, grazing_cos=0.2, edge_threshold=0.02, edge_width=1, dropout=0.002),
    "d435": SensorNoise(name="d435", axial_sigma_ref=0.00195, z_ref=0.5, depth_unit=0.001, min_range=0.175,
                        max_range=3.0, grazing_cos=0.25, edge_threshold=0.02, edge_width=2, dropout=0.005),
    "zivid": SensorNoise(name="zivid", axial_sigma_ref=0.0001, z_ref=0.5, depth_unit=0.0, min_range=0.3,
                         max_range=1.2, grazing_cos=0.1, edge_threshold=0.02, edge_width=1, dropout=0.0),
}


def _as_noise(noise: Union[SensorNoise, str, None]) -> SensorNoise:
    if noise is None:
        return NOISE_PRESETS["none"]
    if isinstance(noise, str):
        try:
            return NOISE_PRESETS[noise]
        except KeyError:
            raise ValueError(f"unknown noise preset {noise!r}; known: {sorted(NOISE_PRESETS)}") from None
    if not isinstance(noise, SensorNoise):
        raise TypeError(f"noise: expected SensorNoise or a preset name, got {type(noise)!r}")
    return noise


# --------------------------------------------------------------------------- scans


@dataclass
class SyntheticScan:
    """A rendered scan with its ground truth.

    Attributes:
        frames: one :class:`scanalign.camera.Frame` per pose: ``depth`` (uint16 in units of
            ``depth_scale`` metres, 0 = missing -- by default the sensor's own unit, see
            :func:`render_scan`; or float32 metres with NaN when rendered with
            ``depth_unit=None``), ``rgb`` (uint8, registered to the depth), ``timestamp`` (s),
            ``T_base_camera`` (the exact pose), ``index``; ``meta`` holds ``T_base_flange``
            when known, ``joints`` (6 rad) and ``robot`` (its name) when a robot moved the
            camera, and, with ``keep_ground_truth``, ``depth_true`` (float32 m, NaN = no
            hit) and ``face_id`` (int32, indexes :attr:`mesh`).
        reference: the exact camera trajectory, ``T_base_camera`` per frame.
        mesh: the whole scene (objects and table) in the base frame, metres.
        object_mesh: the objects only, base frame.
        intrinsics: the camera's pinhole intrinsics.
        noise: the sensor model used.
        T_flange_camera: the hand-eye transform, when the poses came from a
            :class:`ScanTrajectory` (else None).
        T_base_flange: (N, 4, 4) flange poses, or None.
        scene: the scene rendered.
        seed: the noise seed.
        joints: (N, 6) joints of the robot that moved the camera (rad), when the poses came
            from a :class:`ScanTrajectory` with a robot (else None); also in each frame's
            ``meta["joints"]``.
        robot: that robot, placed in the scene (``robot.fk(joints) == T_base_flange``), or None.
        T_base_robot: the robot's mounting in the scene (robot base -> base), or None.
    """

    frames: List[Frame]
    reference: Trajectory
    mesh: _io.Mesh
    object_mesh: _io.Mesh
    intrinsics: Intrinsics
    noise: SensorNoise
    T_flange_camera: Optional[np.ndarray]
    T_base_flange: Optional[np.ndarray]
    scene: Scene
    seed: int
    joints: Optional[np.ndarray] = None
    robot: Optional[Any] = None
    T_base_robot: Optional[np.ndarray] = None

    def __len__(self) -> int:
        return len(self.frames)

    def points(self, index: int, in_base: bool = False) -> np.ndarray:
        """(N, 3) float64 points of frame ``index``'s valid depth pixels, back-projected with
        the intrinsics: in the camera frame, or the base frame with ``in_base`` (m)."""
        frame = self.frames[index]
        z = frame.depth_metres()
        v, u = np.nonzero(np.isfinite(z))
        zz = z[v, u].astype(np.float64)
        K = self.intrinsics
        p = np.column_stack([(u - K.cx) / K.fx * zz, (v - K.cy) / K.fy * zz, zz])
        if in_base:
            T = frame.T_base_camera
            p = p @ T[:3, :3].T + T[:3, 3]
        return p


def render_scan(
    scene: Scene,
    poses: Union[ScanTrajectory, Trajectory, np.ndarray],
    intrinsics: Union[Intrinsics, str] = "sr300",
    noise: Union[SensorNoise, str, None] = "sr300",
    seed: int = 0,
    *,
    depth_unit: Union[float, str, None] = "auto",
    near: float = 0.01,
    keep_ground_truth: bool = False,
    frame_rate: float = 10.0,
    num_threads: int = 0,
) -> SyntheticScan:
    """Renders a scan: noisy depth and shaded colour for every camera pose.

    Args:
        scene: what is seen.
        poses: a :class:`ScanTrajectory` (flange poses + hand-eye, and the robot's joints
            when it has a robot: stored in the scan and each frame's meta), a :class:`Trajectory` of
            ``T_base_camera``, or an (N, 4, 4) array of ``T_base_camera`` (camera -> base, m).
        intrinsics: camera intrinsics or a preset name (:data:`scanalign.camera.INTRINSICS_PRESETS`).
        noise: a :class:`SensorNoise` or a preset name (:data:`NOISE_PRESETS`); None = "none".
        seed: noise seed. Frame ``k`` draws from ``numpy.random.default_rng`` seeded with
            ``numpy.random.SeedSequence(seed).spawn(N)[k]``: equal seeds give bit-identical
            frames, and a frame does not depend on how many others are rendered.
        depth_unit: metres per unit of the stored uint16 depth (depths above 65535 units are
            stored as missing); ``"auto"`` (default): the sensor's own quantisation step when it
            has one (what the real camera delivers: 1/8 mm for the SR300, 1 mm for the D435),
            else 0.1 mm so that sub-millimetre noise survives; None: float32 metres with NaN for
            missing pixels.
        near: renderer near plane (m).
        keep_ground_truth: also store the noise-free depth and face ids in ``frame.meta``.
        frame_rate: Hz, for timestamps when ``poses`` has none (an array).
        num_threads: frames rendered concurrently (each on one thread); 0 = one per CPU.

    Returns:
        A :class:`SyntheticScan`.

    Raises:
        TypeError, ValueError: bad arguments (unknown preset, malformed poses, non-positive
            depth unit ...).
    """
    if not isinstance(scene, Scene):
        raise TypeError(f"scene: expected Scene, got {type(scene)!r}")
    K = _check_intrinsics(intrinsics)
    model = _as_noise(noise)
    if isinstance(depth_unit, str):
        if depth_unit != "auto":
            raise ValueError(f"depth_unit must be a length in metres, 'auto' or None, got {depth_unit!r}")
        depth_unit = model.depth_unit if model.depth_unit > 0 else 1e-4
    elif depth_unit is not None and not (math.isfinite(depth_unit) and depth_unit > 0):
        raise ValueError(f"depth_unit must be a positive length in metres, 'auto' or None, got {depth_unit!r}")
    if int(seed) != seed or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if int(num_threads) != num_threads or num_threads < 0:
        raise ValueError(f"num_threads must be a non-negative integer, got {num_threads!r}")
    T_flange_camera = T_base_flange = joints = robot = T_base_robot = None
    if isinstance(poses, ScanTrajectory):
        T_cams, stamps = poses.T_base_camera, poses.timestamps
        T_flange_camera, T_base_flange = poses.T_flange_camera.copy(), poses.T_base_flange.copy()
        if poses.joints is not None:
            joints, robot = poses.joints.copy(), poses.robot
            T_base_robot = None if poses.T_base_robot is None else poses.T_base_robot.copy()
    elif isinstance(poses, Trajectory):
        T_cams, stamps = poses.poses, poses.timestamps
    else:
        T_cams = np.asarray(poses, dtype=np.float64)
        if T_cams.ndim == 2:
            T_cams = T_cams[None]
        if T_cams.ndim != 3 or T_cams.shape[1:] != (4, 4):
            raise ValueError(f"poses: expected (N, 4, 4) camera poses, got shape {T_cams.shape}")
        if not (math.isfinite(frame_rate) and frame_rate > 0):
            raise ValueError("frame_rate must be positive (Hz)")
        stamps = np.arange(len(T_cams)) / frame_rate
    T_cams = np.array([se3.require_rigid(T, f"poses[{k}]") for k, T in enumerate(T_cams)]).reshape(-1, 4, 4)
    if len(T_cams) == 0:
        raise ValueError("poses: no camera poses given")

    children = np.random.SeedSequence(int(seed)).spawn(len(T_cams))
    scene._prepare_shading()  # build the shared caches before the worker threads read them

    def render_frame(k: int) -> Frame:
        T = T_cams[k]
        clean = scene.render(T, K, near=near, num_threads=1)
        z = model.apply(clean.depth, clean.cos_incidence, np.random.default_rng(children[k]))
        if depth_unit is None:
            depth: np.ndarray = z
            scale = 1.0
        else:
            units = np.round(np.nan_to_num(z, nan=0.0) / depth_unit)
            units[(units > 65535) | (units < 0)] = 0
            depth = units.astype(np.uint16)
            scale = float(depth_unit)
        meta: Dict[str, Any] = {"noise": model.name}
        if T_base_flange is not None:
            meta["T_base_flange"] = T_base_flange[k].copy()
        if joints is not None:
            meta["joints"] = joints[k].copy()
            if robot is not None:
                meta["robot"] = robot.name
        if keep_ground_truth:
            meta["depth_true"] = clean.depth
            meta["face_id"] = clean.face_id
        return Frame(depth=depth, intrinsics=K, rgb=scene.shade(clean, T, K), depth_scale=scale,
                     timestamp=float(stamps[k]), T_base_camera=T.copy(), index=k, meta=meta)

    # Frames are independent: render them on a pool of threads, each frame single-threaded
    # (the renderer and most NumPy work release the GIL). This scales better than threads
    # inside one small frame, whose barriers stall when the machine is oversubscribed; the
    # output does not depend on the number of workers.
    workers = int(num_threads) if num_threads else (os.cpu_count() or 1)
    workers = max(1, min(workers, len(T_cams)))
    if workers == 1:
        frames = [render_frame(k) for k in range(len(T_cams))]
    else:
        with concurrent.futures.ThreadPoolExecutor(max_workers=workers) as pool:
            frames = list(pool.map(render_frame, range(len(T_cams))))
    return SyntheticScan(
        frames=frames,
        reference=Trajectory(np.asarray(stamps, dtype=np.float64).copy(), T_cams.copy()),
        mesh=scene.mesh,
        object_mesh=scene.object_mesh,
        intrinsics=K,
        noise=model,
        T_flange_camera=T_flange_camera,
        T_base_flange=T_base_flange,
        scene=scene,
        seed=int(seed),
        joints=joints,
        robot=robot,
        T_base_robot=T_base_robot,
    )


# --------------------------------------------------------------------------- configuration


@dataclass
class SyntheticConfig:
    """Everything that defines a synthetic scan; read from JSON or flat YAML (``key: value``).

    Attributes:
        mesh: ``"builtin"`` (the procedural part, :func:`builtin_mesh`), a CGAL demo mesh name
            (``"bunny00"``, ``"fandisk"``, ... fetched by :mod:`scanalign.datasets`), or a path
            to a .ply/.off/.stl/.obj file.
        object_size: largest extent of the object (m) after scaling; None keeps the builtin
            part's size (80 mm) and scales other meshes to 0.15 m.
        object_x, object_y: object position on the table, base frame (m).
        object_yaw: rotation about the vertical (rad).
        table_size: side of the square table top (m); 0 for no table.
        trajectory: ``"loop"`` or ``"hemisphere"``.
        n_frames: number of frames.
        height: loop: camera height above the table (m).
        radius: loop: radius of the camera circle (m).
        distance: hemisphere: camera distance to the object (m); None = sqrt(height^2 + radius^2).
        rings: hemisphere: number of rings, at elevations evenly spaced in
            [min_elevation, max_elevation] (rad).
        start_angle: azimuth of the first frame (rad).
        intrinsics: a preset name of :data:`scanalign.camera.INTRINSICS_PRESETS` or a mapping
            width/height/fx/fy/cx/cy.
        resolution_scale: image resize factor (e.g. 0.5 for 320x240).
        noise: a preset name of :data:`NOISE_PRESETS`.
        seed: noise seed.
        depth_unit: metres per uint16 depth unit; ``"auto"`` for the sensor's own unit (0.1 mm
            without one); 0 stores float32 metres.
        frame_rate: Hz.
        robot: the arm that moves the camera: a name of
            :meth:`scanalign.kinematics.Robot.by_name` (default ``"ur5"``), or ``"none"`` for
            camera poses exactly as planned without an arm (no joints).
        robot_x, robot_y, robot_z: position of the robot's base frame in the scene (m); x, y
            None (default) = above the object (``object_x``, ``object_y``); z default 0.9
            (:data:`DEFAULT_ROBOT_HEIGHT` above the table top).
        robot_roll, robot_pitch, robot_yaw: orientation of the robot base in the scene (rad,
            ``Rz(yaw) Ry(pitch) Rx(roll)``); default (pi, 0, 0): hanging, first axis down
            (see :func:`robot_mount` for why).
        robot_elbow: start configuration: ``"up"`` (default: elbow away from the table),
            ``"down"`` or ``"any"`` (see :func:`attach_robot`).
    """

    mesh: str = "builtin"
    object_size: Optional[float] = None
    object_x: float = 0.5
    object_y: float = 0.0
    object_yaw: float = 0.3
    table_size: float = 0.6
    trajectory: str = "loop"
    n_frames: int = 36
    height: float = 0.40
    radius: float = 0.20
    distance: Optional[float] = None
    rings: int = 3
    min_elevation: float = math.radians(35.0)
    max_elevation: float = math.radians(75.0)
    start_angle: float = 0.0
    intrinsics: Union[str, Dict[str, Any]] = "sr300"
    resolution_scale: float = 1.0
    noise: str = "sr300"
    seed: int = 0
    depth_unit: Union[float, str] = "auto"
    frame_rate: float = 10.0
    robot: str = "ur5"
    robot_x: Optional[float] = None
    robot_y: Optional[float] = None
    robot_z: float = DEFAULT_ROBOT_HEIGHT
    robot_roll: float = math.pi
    robot_pitch: float = 0.0
    robot_yaw: float = 0.0
    robot_elbow: str = "up"

    def __post_init__(self) -> None:
        if self.trajectory not in ("loop", "hemisphere"):
            raise ValueError(f"trajectory must be 'loop' or 'hemisphere', got {self.trajectory!r}")
        if isinstance(self.noise, str) and self.noise not in NOISE_PRESETS:
            raise ValueError(f"unknown noise preset {self.noise!r}; known: {sorted(NOISE_PRESETS)}")
        if isinstance(self.intrinsics, str) and self.intrinsics not in INTRINSICS_PRESETS:
            raise ValueError(f"unknown intrinsics preset {self.intrinsics!r}; known: {sorted(INTRINSICS_PRESETS)}")
        if int(self.n_frames) != self.n_frames or self.n_frames < 1:
            raise ValueError(f"n_frames must be a positive integer, got {self.n_frames!r}")
        self.n_frames = int(self.n_frames)
        if int(self.rings) != self.rings or self.rings < 1:
            raise ValueError("rings must be a positive integer")
        self.rings = int(self.rings)
        if int(self.seed) != self.seed or self.seed < 0:
            raise ValueError("seed must be a non-negative integer")
        self.seed = int(self.seed)
        for name in ("height", "resolution_scale", "frame_rate"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number, got {v!r}")
        if isinstance(self.depth_unit, str) and self.depth_unit != "auto":
            raise ValueError(f"depth_unit must be a length in metres or 'auto', got {self.depth_unit!r}")
        for name in ("radius", "table_size") + (() if isinstance(self.depth_unit, str) else ("depth_unit",)):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a non-negative number, got {v!r}")
        for name in ("object_size", "distance"):
            v = getattr(self, name)
            if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number or null, got {v!r}")
        if not 0 < self.min_elevation <= self.max_elevation <= math.pi / 2:
            raise ValueError("need 0 < min_elevation <= max_elevation <= pi/2 (radians)")
        if not isinstance(self.robot, str):
            raise ValueError(f"robot must be a robot name or 'none', got {self.robot!r}")
        if self.robot != "none":
            try:
                _as_robot(self.robot)
            except ValueError as e:
                raise ValueError(f"robot: {e} (or 'none' for no robot)") from None
        for name in ("robot_x", "robot_y", "robot_z", "robot_roll", "robot_pitch", "robot_yaw"):
            v = getattr(self, name)
            if v is None and name in ("robot_x", "robot_y"):
                continue
            if not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)):
                raise ValueError(f"{name} must be a finite number (m or rad), got {v!r}")
        if self.robot_elbow not in ("up", "down", "any"):
            raise ValueError(f"robot_elbow must be 'up', 'down' or 'any', got {self.robot_elbow!r}")

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "SyntheticConfig":
        """From a mapping of field names to values; unknown keys raise ValueError."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown synthetic config keys {unknown}; known: {sorted(known)}")
        values = dict(d)
        for key in ("object_size", "distance", "robot_x", "robot_y"):
            if isinstance(values.get(key), str) and values[key].lower() in ("null", "none", "~", ""):
                values[key] = None
        return cls(**values)

    @classmethod
    def from_file(cls, path: PathLike) -> "SyntheticConfig":
        """Reads a JSON file, or flat YAML (``key: value`` lines, ``#`` comments)."""
        return cls.from_dict(read_camera_file(path))

    def to_dict(self) -> Dict[str, Any]:
        """A JSON-serialisable dict that :meth:`from_dict` turns back into this config."""
        return dataclasses.asdict(self)

    def to_json(self, path: PathLike) -> None:
        """Writes the config as JSON."""
        Path(path).write_text(json.dumps(self.to_dict(), indent=2) + "\n", encoding="utf-8")

    def load_mesh(self) -> _io.Mesh:
        """The object mesh in metres, in its own frame (scaled per ``object_size``)."""
        if self.mesh == "builtin":
            m = builtin_mesh()
            return m if self.object_size is None else normalize_mesh(m, self.object_size)
        if os.path.exists(self.mesh):
            m = _io.read_mesh(self.mesh)
        elif os.sep in self.mesh or (os.altsep and os.altsep in self.mesh):
            raise FileNotFoundError(f"mesh file {self.mesh!r} does not exist")
        else:  # a CGAL demo mesh name, optionally with an extension ("pig.stl")
            from . import datasets

            m = datasets.load_cgal_mesh(self.mesh)
        return normalize_mesh(m, 0.15 if self.object_size is None else self.object_size)

    def intrinsics_object(self) -> Intrinsics:
        """The camera intrinsics after ``resolution_scale``."""
        K = Intrinsics.preset(self.intrinsics) if isinstance(self.intrinsics, str) else Intrinsics.from_dict(
            self.intrinsics)
        return K if self.resolution_scale == 1.0 else K.scaled(self.resolution_scale)

    def build_scene(self) -> Scene:
        scene = Scene(table_size=(self.table_size, self.table_size) if self.table_size > 0 else None,
                      table_center=(self.object_x, self.object_y))
        name = Path(self.mesh).stem if self.mesh != "builtin" else "builtin"
        scene.add_object(self.load_mesh(), position=(self.object_x, self.object_y), yaw=self.object_yaw, name=name)
        return scene

    def T_base_robot(self) -> Optional[np.ndarray]:
        """The robot's mounting in the scene (robot base -> base, 4x4, m), or None without a robot."""
        if self.robot == "none":
            return None
        return robot_mount(self.object_x if self.robot_x is None else self.robot_x,
                           self.object_y if self.robot_y is None else self.robot_y,
                           self.robot_z, self.robot_roll, self.robot_pitch, self.robot_yaw)

    def build_trajectory(self, scene: Scene) -> ScanTrajectory:
        """The planned camera path; with a robot, followed by the arm (:func:`attach_robot`).

        Raises:
            ValueError: a pose the robot cannot reach from its mount (naming the frame and the
                IK status).
        """
        if self.trajectory == "loop":
            traj = loop_trajectory(self.n_frames, center=scene.center, height=self.height, radius=self.radius,
                                   start_angle=self.start_angle, frame_rate=self.frame_rate)
        else:
            distance = self.distance if self.distance is not None else math.hypot(self.height, self.radius)
            elevations = np.linspace(self.min_elevation, self.max_elevation, self.rings)
            traj = hemisphere_trajectory(self.n_frames, center=scene.center, distance=distance,
                                         elevations=elevations, start_angle=self.start_angle,
                                         frame_rate=self.frame_rate)
        if self.robot == "none":
            return traj
        return attach_robot(traj, self.robot, T_base_robot=self.T_base_robot(), elbow=self.robot_elbow)

    def build(self, *, keep_ground_truth: bool = False) -> SyntheticScan:
        """Builds the scene and trajectory and renders the scan."""
        scene = self.build_scene()
        unit = self.depth_unit if isinstance(self.depth_unit, str) or self.depth_unit > 0 else None
        return render_scan(scene, self.build_trajectory(scene), self.intrinsics_object(), self.noise, self.seed,
                           depth_unit=unit,
                           keep_ground_truth=keep_ground_truth, frame_rate=self.frame_rate)


def builtin_scan(
    n_frames: int = 36,
    noise: str = "sr300",
    seed: int = 0,
    *,
    trajectory: str = "loop",
    intrinsics: str = "sr300",
    resolution_scale: float = 1.0,
    keep_ground_truth: bool = False,
    robot: str = "ur5",
) -> SyntheticScan:
    """The demo scan: the built-in part on a 60 cm table, seen by an SR300-like camera on a
    loop 40 cm above the table (radius 20 cm), 10 Hz, no download needed. The camera is on
    the hand of a UR5 hanging 0.9 m above the table: the reference poses are its forward
    kinematics, the joints are in ``scan.joints``.

    Args:
        n_frames: frames around the full loop.
        noise: preset name (:data:`NOISE_PRESETS`).
        seed: noise seed.
        trajectory: ``"loop"`` or ``"hemisphere"``.
        intrinsics: intrinsics preset name.
        resolution_scale: image resize factor.
        keep_ground_truth: store noise-free depth and face ids in each frame's ``meta``.
        robot: the arm's name, or ``"none"`` for the planned poses without an arm.
    """
    return SyntheticConfig(n_frames=n_frames, noise=noise, seed=seed, trajectory=trajectory, intrinsics=intrinsics,
                           resolution_scale=resolution_scale, robot=robot).build(keep_ground_truth=keep_ground_truth)

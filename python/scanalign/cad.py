"""CAD model to point clouds (thesis §7.3 and spec §8): viewpoint sampling.

A part's CAD mesh becomes the partial clouds a depth camera would see of it. Virtual
cameras sit on the vertices of a tessellated sphere around the model and look at its
centre; the thesis uses the icosahedron subdivided once, whose 42 vertices give 42 views
(PCL's ``renderViewTesselatedSphere``; spec claim 30). Each view is rendered with the exact
z-buffer of :func:`scanalign.synthetic.render_depth`. A view's points are back-projected
into the model frame and carry the normal of the triangle they lie on, oriented towards
that view's camera. Monte Carlo (area-weighted) sampling of the whole surface is
:func:`scanalign.datasets.sample_mesh`. It also samples surfaces a camera never sees
(concave interiors, faces hidden by others), which is why the thesis prefers views.

Units are metres and radians. ``T_model_camera`` maps camera coordinates (OpenCV: x
right, y down, z along the optical axis) into the model frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple, Union

import numpy as np

from .camera import Intrinsics

__all__ = ["tessellated_sphere", "ModelView", "render_views", "view_intrinsics", "DEFAULT_VIEW_ANGLE"]

#: PCL's default field of view for ``renderViewTesselatedSphere``, radians (57 degrees).
DEFAULT_VIEW_ANGLE: float = math.radians(57.0)


def tessellated_sphere(level: int = 1) -> Tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of an icosahedron subdivided ``level`` times, projected onto the
    unit sphere: level 0 has 12 vertices and 20 faces, level 1 has 42 and 80 (spec claim 30),
    level k has 10·4^k + 2 and 20·4^k.

    Each subdivision splits every triangle into four at its edge midpoints (shared between
    neighbours) and pushes the new vertices onto the sphere. Faces are wound
    counter-clockwise seen from outside.

    Returns:
        ``(vertices (V, 3) float64, unit length; faces (F, 3) int64)``.
    """
    if int(level) != level or not 0 <= level <= 6:
        raise ValueError(f"level must be an integer in [0, 6], got {level!r}")
    t = (1.0 + math.sqrt(5.0)) / 2.0
    verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
             (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
             (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
             (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    v = [np.array(p, dtype=np.float64) / np.linalg.norm(p) for p in verts]
    for _ in range(int(level)):
        midpoint: dict = {}

        def mid(a: int, b: int) -> int:
            key = (a, b) if a < b else (b, a)
            if key not in midpoint:
                m = v[a] + v[b]
                v.append(m / np.linalg.norm(m))
                midpoint[key] = len(v) - 1
            return midpoint[key]

        new_faces = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new_faces += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new_faces
    return np.array(v), np.array(faces, dtype=np.int64)


def view_intrinsics(resolution: int, view_angle: float = DEFAULT_VIEW_ANGLE) -> Intrinsics:
    """Square pinhole intrinsics with the field of view ``view_angle`` (rad) across
    ``resolution`` pixels: f = (resolution / 2) / tan(view_angle / 2), principal point at
    the image centre."""
    if int(resolution) != resolution or resolution < 2:
        raise ValueError(f"resolution must be an integer >= 2 (pixels), got {resolution!r}")
    if not (0 < view_angle < math.pi):
        raise ValueError(f"view_angle must be in (0, pi) radians, got {view_angle!r}")
    f = 0.5 * resolution / math.tan(0.5 * view_angle)
    c = 0.5 * (resolution - 1)
    return Intrinsics(int(resolution), int(resolution), f, f, c, c)


@dataclass(frozen=True)
class ModelView:
    """One virtual depth camera's view of a model.

    Attributes:
        points: (N, 3) float64 visible surface points, model frame, metres (one per pixel
            that sees the model).
        normals: (N, 3) unit normals of the triangles the points lie on, oriented towards
            the camera (``n · (camera centre − p) > 0``).
        face_id: (N,) int64 index of each point's triangle in the mesh.
        T_model_camera: (4, 4) camera -> model (OpenCV camera axes).
        intrinsics: the camera's pinhole intrinsics.
        pixels: (N, 2) int64 (column, row) of each point in the image.
    """

    points: np.ndarray
    normals: np.ndarray
    face_id: np.ndarray
    T_model_camera: np.ndarray
    intrinsics: Intrinsics
    pixels: np.ndarray

    @property
    def viewpoint(self) -> np.ndarray:
        """(3,) camera centre in the model frame, metres."""
        return self.T_model_camera[:3, 3].copy()

    def points_in_camera(self) -> np.ndarray:
        """(N, 3) the points in the camera frame (z = depth along the optical axis)."""
        R, t = self.T_model_camera[:3, :3], self.T_model_camera[:3, 3]
        return (self.points - t) @ R

    def __len__(self) -> int:
        return int(self.points.shape[0])


def _mesh_arrays(mesh: object) -> Tuple[np.ndarray, np.ndarray]:
    if isinstance(mesh, tuple) and len(mesh) == 2:
        vertices, faces = mesh
    else:
        vertices, faces = getattr(mesh, "vertices", None), getattr(mesh, "faces", None)
        if vertices is None or faces is None:
            raise TypeError("mesh: expected a scanalign.io.Mesh or a (vertices, faces) pair")
    V = np.asarray(vertices, dtype=np.float64)
    F = np.asarray(faces)
    if V.ndim != 2 or V.shape[1] != 3 or V.shape[0] < 3:
        raise ValueError(f"mesh vertices: expected shape (V >= 3, 3), got {V.shape}")
    if not np.all(np.isfinite(V)):
        raise ValueError("mesh vertices: non-finite coordinates")
    if F.ndim != 2 or F.shape[1] != 3 or F.shape[0] < 1 or F.dtype.kind not in "iu":
        raise ValueError(f"mesh faces: expected an integer array of shape (F >= 1, 3), got {F.shape} {F.dtype}")
    if F.min() < 0 or F.max() >= V.shape[0]:
        raise ValueError("mesh faces: vertex index out of range")
    return V, F.astype(np.int64)


def render_views(
    mesh: object,
    *,
    resolution: int = 150,
    view_angle: float = DEFAULT_VIEW_ANGLE,
    level: int = 1,
    distance: Optional[float] = None,
    center: Optional[Sequence[float]] = None,
    num_threads: int = 0,
) -> List[ModelView]:
    """The partial clouds of a model seen from the vertices of a tessellated sphere.

    Args:
        mesh: a :class:`scanalign.io.Mesh` or ``(vertices (V, 3), faces (F, 3))``, metres, in
            the model frame.
        resolution: image width and height, pixels (the thesis uses 90 to 400).
        view_angle: field of view, rad (PCL's default 57 degrees).
        level: subdivisions of the icosahedron; 1 gives the thesis's 42 views.
        distance: camera distance from ``center``, m. Default: the smallest distance at
            which the model's bounding sphere (about ``center``) fills at most 90 % of the
            field of view from every viewpoint, so the whole model is in every image.
        center: what the cameras look at, model frame (m); default the centre of the
            model's bounding box.
        num_threads: rasteriser threads (0 = all cores).

    Returns:
        One :class:`ModelView` per sphere vertex, in the order of
        :func:`tessellated_sphere`. A view of a model that hides itself entirely (not
        possible for a model inside the field of view) would have 0 points.

    Raises:
        ValueError / TypeError: a malformed or non-finite mesh, bad resolution, view angle,
            level or distance.
    """
    from .synthetic import look_at, render_depth

    V, F = _mesh_arrays(mesh)
    intr = view_intrinsics(resolution, view_angle)
    c = 0.5 * (V.min(axis=0) + V.max(axis=0)) if center is None else np.asarray(center, dtype=np.float64)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise ValueError(f"center: expected 3 finite coordinates (m), got {center!r}")
    radius = float(np.max(np.linalg.norm(V - c, axis=1)))
    if not radius > 0:
        raise ValueError("mesh: all vertices coincide")
    if distance is None:
        distance = radius / math.sin(0.5 * 0.9 * view_angle)
    if not (math.isfinite(distance) and distance > radius):
        raise ValueError(f"distance must be finite and larger than the model's bounding radius {radius:.4g} m, "
                         f"got {distance!r}")
    dirs, _ = tessellated_sphere(level)
    # Face normals (right-hand rule); degenerate triangles get a zero normal and are never
    # the visible face of a pixel in practice.
    n = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    nn = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, nn, out=np.zeros_like(n), where=nn > 0)
    rows, cols = np.mgrid[0:intr.height, 0:intr.width]
    views: List[ModelView] = []
    for d in dirs:
        eye = c + distance * d
        up = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
        T_model_camera = look_at(eye, c, up)
        T_camera_model = np.linalg.inv(T_model_camera)
        r = render_depth(V, F, intr, T_camera_model, near=1e-3 * distance, num_threads=num_threads)
        hit = r.hit
        z = r.depth[hit].astype(np.float64)
        u, v = cols[hit], rows[hit]
        pc = np.column_stack([(u - intr.cx) * z / intr.fx, (v - intr.cy) * z / intr.fy, z])
        pts = pc @ T_model_camera[:3, :3].T + T_model_camera[:3, 3]
        fid = r.face_id[hit].astype(np.int64)
        nrm = n[fid]
        flip = np.einsum("ij,ij->i", nrm, eye - pts) < 0
        nrm[flip] *= -1.0
        views.append(ModelView(points=pts, normals=nrm, face_id=fid, T_model_camera=T_model_camera,
                               intrinsics=intr, pixels=np.column_stack([u, v]).astype(np.int64)))
    return views

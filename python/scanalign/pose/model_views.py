"""CAD model to point clouds: viewpoint sampling (Kleppe, PhD thesis, NTNU 2018, §7.3).

A part's CAD mesh becomes the partial clouds a depth camera would see of it. Virtual cameras sit on the vertices of a
tessellated sphere around the model and look at its centre; the thesis uses the icosahedron subdivided once, whose 42
vertices give 42 views (PCL's ``renderViewTesselatedSphere``). Each view is rendered with the exact z-buffer of the C++
depth renderer; its points are back-projected into the model frame and carry the normal of the triangle they lie on,
oriented towards that view's camera. Area-weighted sampling of the whole surface also samples surfaces a camera never
sees (concave interiors, faces hidden by others), which is why the thesis prefers views.

Units are metres and radians. ``T_model_camera`` maps camera coordinates (OpenCV: x right, y down, z along the optical
axis) into the model frame. The rendering runs in C++ (``scanalign/pose/model_views.hpp``).
"""

from __future__ import annotations

from typing import Any, List, Optional, Tuple

import numpy as np

from scanalign import _core
from scanalign.common.arrays import mesh_arrays
from scanalign.common.settings import with_overrides

__all__ = ["tessellated_sphere", "ModelView", "ModelViewSettings", "render_views", "view_intrinsics",
           "DEFAULT_VIEW_ANGLE"]

_P = _core.pose
ModelView = _P.ModelView
ModelViewSettings = _P.ModelViewSettings
#: PCL's default field of view for ``renderViewTesselatedSphere``, radians (57 degrees).
DEFAULT_VIEW_ANGLE: float = float(_P.DEFAULT_VIEW_ANGLE)


def tessellated_sphere(level: int = 1) -> Tuple[np.ndarray, np.ndarray]:
    """``(vertices (V, 3) unit length, faces (F, 3) int64)`` of an icosahedron subdivided
    ``level`` (0..6) times: 10·4^level + 2 vertices and 20·4^level faces, wound
    counter-clockwise seen from outside (level 1: the thesis's 42 viewpoints)."""
    return _P.tessellated_sphere(level)


def view_intrinsics(resolution: int, view_angle: float = DEFAULT_VIEW_ANGLE):
    """Square pinhole intrinsics (``PinholeIntrinsics``: width, height, fx, fy, cx, cy in
    pixels) with the field of view ``view_angle`` (rad) across ``resolution`` pixels."""
    return _P.view_intrinsics(resolution, view_angle)


def _mesh_arrays(mesh: object) -> Tuple[np.ndarray, np.ndarray]:
    """(vertices float64, faces int64) of a Mesh, a (vertices, faces) pair or an Open3D / trimesh mesh."""
    if (pair := mesh_arrays(mesh)) is None:  # not an Open3D or trimesh mesh
        pair = mesh if isinstance(mesh, tuple) and len(mesh) == 2 else (getattr(mesh, "vertices", None),
                                                                        getattr(mesh, "faces", None))
    vertices, faces = pair
    if vertices is None or faces is None:
        raise TypeError("mesh: expected a scanalign.io.Mesh or a (vertices, faces) pair")
    F = np.asarray(faces)
    if F.size and F.dtype.kind not in "iu":
        raise TypeError(f"mesh faces: expected integers, got {F.dtype}")
    if (V := np.asarray(vertices)).dtype.kind not in "biuf":  # complex would lose its imaginary part
        raise TypeError(f"mesh vertices: expected real numbers, got {V.dtype}")
    return np.ascontiguousarray(V, dtype=np.float64), F.astype(np.int64)


def render_views(mesh: object, settings: Optional[ModelViewSettings] = None, **overrides: Any) -> List[ModelView]:
    """The partial clouds of a model seen from the vertices of a tessellated sphere.

    Args:
        mesh: a :class:`scanalign.io.Mesh`, ``(vertices (V, 3), faces (F, 3))`` or an Open3D /
            trimesh triangle mesh, metres, in the model frame.
        settings: ``ModelViewSettings`` (default its C++ defaults: 150-pixel images, PCL's 57-degree field of view, the
            thesis's 42 views, automatic distance and centre); keyword ``overrides`` name its fields (``resolution``,
            ``view_angle`` rad, ``level``, ``distance`` m, ``center`` m, ``num_threads``).

    Returns:
        One :class:`ModelView` per sphere vertex, in the order of :func:`tessellated_sphere`
        (``points``, ``normals`` towards the camera, ``face_id``, ``pixels``,
        ``T_model_camera``, ``intrinsics``, ``viewpoint``, ``points_in_camera()``).

    Raises:
        ValueError / TypeError: a malformed or non-finite mesh, bad resolution, view angle, level or distance.
    """
    V, F = _mesh_arrays(mesh)
    return _P.render_model_views(V, F, with_overrides(ModelViewSettings, settings, overrides, "view"))

"""CAD model to point clouds: viewpoint sampling (Kleppe, PhD thesis, NTNU 2018, §7.3).

A part's CAD mesh becomes the partial clouds a depth camera would see of it. Virtual cameras sit on the vertices of a
tessellated sphere around the model and look at its centre; the thesis uses the icosahedron subdivided once, whose 42
vertices give 42 views (PCL's ``renderViewTesselatedSphere``). Each view is rendered with the exact z-buffer of the C++
depth renderer; its points are back-projected into the model frame and carry the normal of the triangle they lie on,
oriented towards that view's camera. Area-weighted sampling of the whole surface also samples surfaces a camera never
sees (concave interiors, faces hidden by others), which is why the thesis prefers views.

A scanned part (a model *cloud*, whole or partial: a PCD, a face-less PLY, an (N, 3) array, an Open3D or trimesh
cloud) has no faces to rasterise. Its views are the points each of the same cameras sees: every point is drawn as a
disc (a splat) into the view's depth buffer, and the points at most ``depth_tolerance`` behind it make the view
(``ModelViewSettings.cloud``: ``normal_radius``, ``splat_radius``, ``depth_tolerance``, metres). Normals, given or
estimated, are turned towards each camera as the mesh views' are.

Units are metres and radians. ``T_model_camera`` maps camera coordinates (OpenCV: x right, y down, z along the optical
axis) into the model frame. The rendering runs in C++ (``scanalign/pose/model_views.hpp``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, List, Optional, Tuple, Union

import numpy as np

from scanalign import _core, io
from scanalign.common.arrays import as_points, foreign_attribute, foreign_kind, mesh_arrays
from scanalign.common.settings import with_overrides
from scanalign.io.interop import Cloud

__all__ = ["tessellated_sphere", "ModelView", "ModelViewSettings", "CloudModelSettings", "render_views",
           "cloud_views", "model_views", "read_model", "is_cloud_model", "surface_points", "view_intrinsics",
           "DEFAULT_VIEW_ANGLE"]

_P = _core.pose
ModelView = _P.ModelView
ModelViewSettings = _P.ModelViewSettings
CloudModelSettings = _P.CloudModelSettings
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


def read_model(path: Union[str, Path]) -> Union[io.Mesh, Cloud]:
    """A part's model file: a triangle mesh (``.off``, ``.stl``, ``.obj``, a ``.ply`` with faces; :func:`scanalign.io.
    read_mesh`) or a model cloud (``.pcd``, a ``.ply`` without faces; :func:`scanalign.io.read_cloud`, normals kept
    when the file has them, non-finite points dropped) as an :class:`scanalign.io.interop.Cloud`. Units are the file's
    (metres expected). ValueError naming the file for another extension or a malformed file."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".ply":
        mesh = io.read_mesh(path)
        if len(mesh.faces):
            return mesh
    if suffix in (".pcd", ".ply"):
        points, normals = io.read_cloud(path)
        keep = np.all(np.isfinite(points), axis=1)
        return Cloud(points[keep], None if normals is None else np.asarray(normals, dtype=np.float64)[keep])
    if suffix not in (".off", ".stl", ".obj"):
        raise ValueError(f"{path}: unsupported model extension {suffix!r} (a mesh: .off, .ply, .stl, .obj; a cloud: "
                         ".pcd, .ply without faces)")
    return io.read_mesh(path)


def _cloud_arrays(cloud: object) -> Tuple[np.ndarray, Optional[np.ndarray]]:
    """(points float64, normals float64 or None) of a model cloud: a :class:`Cloud`, an (N, 3) array, or an Open3D /
    trimesh point cloud (with its normals when it has them)."""
    if isinstance(cloud, Cloud):
        points, normals = cloud.points, cloud.normals
    elif foreign_kind(cloud) == "cloud":
        points, normals = cloud, foreign_attribute(cloud, "normals")
    else:
        points, normals = cloud, None
    p = as_points(points, "model cloud", np.dtype(np.float64))
    n = None if normals is None or len(normals) == 0 else as_points(normals, "model normals", np.dtype(np.float64))
    return p, n


def cloud_views(model: object, settings: Optional[ModelViewSettings] = None, **overrides: Any) -> List[ModelView]:
    """The views of a model cloud (a scanned part, whole or partial) from the cameras :func:`render_views` uses.

    Args:
        model: the model cloud: an (N, 3) array, a :class:`scanalign.io.interop.Cloud` (``points`` and optional ``normals``), or an
            Open3D / trimesh point cloud; metres, model frame. Normals are unoriented lines (each view turns them towards
            its camera); without normals, PCA normals of radius ``settings.cloud.normal_radius`` (m) are estimated
            and points without 3 neighbours within it left out.
        settings: ``ModelViewSettings`` (the cameras as for meshes, and ``cloud``: ``CloudModelSettings``); keyword
            ``overrides`` name its fields (``resolution``, ``cloud={"splat_radius": 0.002}``, ...).

    Returns:
        One :class:`ModelView` per sphere vertex: the points that camera sees (each point's disc drawn into the depth
        buffer hides what lies behind it), ``face_id`` -1, ``pixels`` the points' image positions. A view may be empty
        (a partial scan seen from a side it has no points on).

    Raises:
        ValueError / TypeError: fewer than 3 points, a non-finite point or normal, normals of another count, no point
        with a normal, or bad settings.
    """
    points, normals = _cloud_arrays(model)
    return _P.cloud_model_views(points, normals, with_overrides(ModelViewSettings, settings, overrides, "view"))


def is_cloud_model(views: List[ModelView]) -> bool:
    """Whether ``views`` are a model cloud's (:func:`cloud_views`): ``find_parts`` then checks the matching view's
    points against the cluster, since a scanned model may show only part of the part."""
    return bool(_P.is_cloud_model(list(views)))


def model_views(model: object, settings: Optional[ModelViewSettings] = None) -> List[ModelView]:
    """A part model as views: its given views (a list of :class:`ModelView`), the views of a mesh
    (:func:`render_views`: a :class:`scanalign.io.Mesh`, ``(vertices, faces)``, an Open3D / trimesh mesh), of a model
    cloud (:func:`cloud_views`: an (N, 3) array, a :class:`scanalign.io.interop.Cloud`, an Open3D / trimesh cloud),
    or of a model file (:func:`read_model`: a mesh or a cloud by its extension and contents)."""
    if isinstance(model, list) and model and all(isinstance(v, ModelView) for v in model):
        return model
    if isinstance(model, (str, Path)):
        model = read_model(model)
    if isinstance(model, (Cloud, np.ndarray)) or foreign_kind(model) == "cloud":
        return cloud_views(model, settings)
    return render_views(model, settings)


def surface_points(model: object, n: int, seed: int = 0) -> np.ndarray:
    """(n, 3) points of a model's surface, model frame, m: a mesh sampled uniformly by area
    (:func:`scanalign.data.parts.sample_mesh`), or n of a model cloud's points drawn without replacement (all of them,
    in order, when it has no more than n) -- for plots, sizes and checks that treat meshes and scans alike."""
    if isinstance(model, (Cloud, np.ndarray)) or foreign_kind(model) == "cloud":
        points = _cloud_arrays(model)[0]
        if len(points) <= n:
            return points
        return points[np.sort(np.random.default_rng(seed).choice(len(points), n, replace=False))]
    from scanalign.data.parts import sample_mesh  # a mesh: sampled in C++

    return sample_mesh(model, n, seed=seed)[0]

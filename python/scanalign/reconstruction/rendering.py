"""Depth rendering of triangle meshes: the C++ z-buffer renderer, and camera placement.

Pinhole cameras in the OpenCV convention (:mod:`scanalign.reconstruction.camera`): x right, y down, z along the optical
axis; depth is z, in metres. Used by the CAD view sampler and by the synthetic scanner.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Union

import numpy as np

from scanalign import _core
from scanalign.common.arrays import as_points, as_transform
from scanalign.reconstruction.camera import Intrinsics, intrinsics_preset

__all__ = ["RenderResult", "render_depth", "look_at", "as_intrinsics"]


@dataclass(frozen=True)
class RenderResult:
    """What a pinhole camera sees of a triangle mesh, per pixel (row-major, (H, W)): ``depth``, float32 z along the
    optical axis, metres (NaN where nothing is hit); ``face_id``, int32 index (row of ``faces``) of the visible triangle
    (-1 where nothing is hit); ``cos_incidence``, float32 cosine between the visible face's normal (right-hand rule on
    its winding) and the direction from the surface point to the camera: 1 head on, about 0 at grazing angles, negative
    when the back of a face is seen (0 where nothing is hit)."""

    depth: np.ndarray
    face_id: np.ndarray
    cos_incidence: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """(H, W) bool: pixels that see a surface."""
        return self.face_id >= 0


def as_intrinsics(intrinsics: object) -> Intrinsics:
    """``intrinsics`` itself, or the preset of that name; TypeError for anything else."""
    if isinstance(intrinsics, str):
        return intrinsics_preset(intrinsics)
    if isinstance(intrinsics, Intrinsics) and intrinsics.has_distortion:
        # The renderer is a pinhole camera: a distorted camera would get pinhole images that the
        # back-projection then "undistorts" into a bent scene.
        raise ValueError("intrinsics: the renderer draws pinhole images; give intrinsics without distortion "
                         f"(got distortion={intrinsics.distortion})")
    if not isinstance(intrinsics, Intrinsics):
        raise TypeError("intrinsics: expected scanalign.reconstruction.camera.Intrinsics or a preset name, "
                        f"got {type(intrinsics)!r}")
    return intrinsics


def render_depth(vertices: np.ndarray, faces: np.ndarray, intrinsics: Union[Intrinsics, str],
                 T_camera_world: np.ndarray, *, near: float = 0.01, far: float = math.inf,
                 cull_backfaces: bool = False, num_threads: int = 0) -> RenderResult:
    """Renders a triangle mesh with a z-buffer: depth, visible face and incidence per pixel, as a :class:`RenderResult`
    of (H, W) arrays.

    Pixel ``(u, v)`` samples the ray through its centre. Depth is the exact intersection of that ray with the visible
    triangle's plane (a rendered plane back-projects onto the plane to ~1e-8 m, the float32 rounding). Pixel centres on
    an edge shared by two triangles belong to exactly one of them (top-left rule), so closed meshes show no holes.
    Triangles crossing the near plane are clipped; surfaces beyond ``far`` are not drawn. Both sides of every face are
    drawn unless ``cull_backfaces`` (which drops faces whose winding is clockwise as seen by the camera).

    ``vertices``: (V, 3) float32/float64 positions in the world frame, metres (faces using a non-finite vertex are
    skipped); ``faces``: (F, 3) vertex indices of any integer dtype; ``intrinsics``: image size and pinhole parameters,
    or a preset name (``"sr300"``); ``T_camera_world``: 4x4 rigid transform mapping world coordinates into the camera
    frame; ``near`` (> 0) and ``far`` (> near): clip distances along the optical axis, metres; ``num_threads``: OpenMP
    threads, 0 for the default. TypeError: vertices not float32/float64, faces not integer, intrinsics of another type.
    ValueError: bad shapes, a face index out of range, a non-finite or non-rigid transform, or bad clip distances
    (``near_clip``, ``far_clip`` in the C++ message).
    """
    K = as_intrinsics(intrinsics)
    T = as_transform(T_camera_world, "T_camera_world")  # rigidity: checked in C++, naming T_camera_world
    settings = _core.reconstruction.DepthRenderSettings(near_clip=near, far_clip=far,
                                                        cull_backfaces=bool(cull_backfaces), num_threads=num_threads)
    # Face dtype, shape and index range: checked in C++, naming faces.
    depth, face_id, cos = _core.reconstruction.render_depth(as_points(vertices, "vertices"), np.asarray(faces), K, T,
                                                            settings)
    return RenderResult(depth, face_id, cos)


#: ``look_at(eye, target, up=(0, 0, 1))``: the camera pose ``T_world_camera`` (4x4, metres) at
#: ``eye`` whose optical axis (camera z) points at ``target``, image up (camera -y) as close as
#: possible to ``up``; ValueError for non-finite input, eye == target or a view along ``up``.
look_at = _core.common.look_at

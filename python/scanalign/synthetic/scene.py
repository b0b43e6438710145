"""Objects on a table in the scene (base) frame, rendered as one mesh, with shaded colour."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from scanalign import _core, io
from scanalign.common import rigid as se3
from scanalign.common.arrays import as_transform
from scanalign.reconstruction.camera import Intrinsics
from scanalign.reconstruction.rendering import RenderResult, as_intrinsics, render_depth

__all__ = ["SceneObject", "Scene"]


def _finite(value: object, shape: Tuple[int, ...], name: str, what: str, lo: float = -math.inf,
            hi: float = math.inf) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64)
    if a.shape != shape or not np.all(np.isfinite(a)) or a.min() < lo or a.max() > hi:
        raise ValueError(f"{name}: expected {what}, got {value!r}")
    return a


def _as_color(color: Sequence[float], name: str = "color") -> np.ndarray:
    return _finite(color, (3,), name, "three values in [0, 1] (linear RGB)", 0.0, 1.0)


@dataclass
class SceneObject:
    """A mesh (its own frame, metres) placed in the scene at ``T_base_object`` (object -> base),
    with its RGB albedo ``color`` in [0, 1] and a ``name``."""

    name: str
    mesh: io.Mesh
    T_base_object: np.ndarray
    color: Tuple[float, float, float]


class Scene:
    """Objects on a table, in the robot base frame (z up, metres): the table top (``table_size`` (x, y), None for
    none, centred at ``table_center`` (x, y), at z = ``table_height``) is two triangles, normal +z, with a checker
    pattern of ``checker_size`` squares in the two RGB albedos ``checker_colors`` (in [0, 1]) in the colour image.
    Shading is two-sided Lambertian under a distant light in direction ``light_direction`` (base frame, normalised
    here) plus an ``ambient`` fraction in [0, 1].  Rendering uses one combined mesh (:attr:`mesh`;
    :attr:`face_object`, :attr:`face_source`)."""

    def __init__(self, table_size: Optional[Tuple[float, float]] = (0.6, 0.6),
                 table_center: Tuple[float, float] = (0.5, 0.0), table_height: float = 0.0, checker_size: float = 0.05,
                 checker_colors: Tuple[Sequence[float], Sequence[float]] = ((0.80, 0.78, 0.72), (0.45, 0.43, 0.40)),
                 light_direction: Sequence[float] = (0.3, -0.2, 1.0), ambient: float = 0.3) -> None:
        ts = None if table_size is None else _finite(table_size, (2,), "table_size", "two lengths in metres")
        light = _finite(light_direction, (3,), "light_direction", "a non-zero 3-vector")
        for name, ok, what in (("table_size", ts is None or ts.min() > 0, "two positive lengths (m) or None"),
                               ("table_height", math.isfinite(table_height), "finite (m)"),
                               ("checker_size", math.isfinite(checker_size) and checker_size > 0, "a length > 0 (m)"),
                               ("light_direction", np.linalg.norm(light) > 0, "a non-zero 3-vector"),
                               ("ambient", 0 <= ambient <= 1, "in [0, 1]"),
                               ("checker_colors", len(checker_colors) == 2, "two RGB albedos")):
            if not ok:
                raise ValueError(f"{name} must be {what}, got {locals()[name]!r}")
        self.table_size = None if ts is None else (float(ts[0]), float(ts[1]))
        self.table_center = tuple(float(c) for c in _finite(table_center, (2,), "table_center", "(x, y) in metres"))
        self.table_height, self.checker_size, self.ambient = float(table_height), float(checker_size), float(ambient)
        self.checker_colors = tuple(_as_color(c, "checker_colors") for c in checker_colors)
        self.light_direction = light / np.linalg.norm(light)
        self.objects: List[SceneObject] = []
        self._combined: Optional[Dict[str, np.ndarray]] = None

    def add_object(self, mesh: io.Mesh, T_base_object: Optional[np.ndarray] = None, *,
                   position: Optional[Tuple[float, float]] = None, yaw: float = 0.0,
                   color: Sequence[float] = (0.75, 0.45, 0.20), name: Optional[str] = None) -> SceneObject:
        """Places a mesh (metres, its own frame) in the scene and returns its :class:`SceneObject`: at ``T_base_object``
        (object -> base) if given, else standing on the table, rotated by ``yaw`` (rad) about the vertical, its lowest
        vertex on the table top, the centre of its bounding box at ``position`` (x, y, base frame, m; default the
        table centre)."""
        if not isinstance(mesh, io.Mesh):
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
            xy = _finite(self.table_center if position is None else position, (2,), "position", "(x, y) in metres")
            used = mesh.vertices[np.unique(mesh.faces)]
            if not np.all(np.isfinite(used)):
                raise ValueError("mesh has non-finite vertices")
            T = se3.rigid([0.0, 0.0, 1.0], yaw, [0.0, 0.0, 0.0])
            rotated = _core.common.transform_points(T, used)
            lo, hi = rotated.min(axis=0), rotated.max(axis=0)
            T[:3, 3] = [xy[0] - (lo[0] + hi[0]) / 2, xy[1] - (lo[1] + hi[1]) / 2, self.table_height - lo[2]]
        obj = SceneObject(name=name or f"object{len(self.objects)}", mesh=mesh, T_base_object=T,
                          color=tuple(float(c) for c in _as_color(color)))  # type: ignore[arg-type]
        self.objects.append(obj)
        self._combined = None
        return obj

    @property
    def center(self) -> np.ndarray:
        """(3,) centre of the objects' bounding box in the base frame (m) at table height, the default target of
        trajectories; the table centre when there are no objects."""
        if not self.objects:
            return np.array([*self.table_center, self.table_height])
        v = self.object_mesh.vertices[:, :2]
        return np.append((v.min(axis=0) + v.max(axis=0)) / 2, self.table_height)

    def _build(self) -> Dict[str, np.ndarray]:
        """The combined mesh, built once by C++ ``compose_scene`` (faces in Morton order, for the renderer's cache)."""
        if self._combined is not None:
            return self._combined
        objects = [(obj.mesh.vertices, obj.mesh.faces, obj.T_base_object, obj.color) for obj in self.objects]
        self._combined = _core.synthetic.compose_scene(objects, self.table_size, self.table_center, self.table_height,
                                                       self.checker_colors[0])
        return self._combined

    @property
    def mesh(self) -> io.Mesh:
        """The whole scene (objects and table) as one mesh in the base frame, metres. Its face
        order is the renderer's: ``RenderResult.face_id`` indexes these faces."""
        c = self._build()
        return io.Mesh(c["vertices"].copy(), c["faces"].astype(np.int64))

    @property
    def object_mesh(self) -> io.Mesh:
        """The objects only (no table) as one mesh in the base frame, metres; its faces are the
        first ``len(object_mesh.faces)`` faces of :attr:`mesh`."""
        c = self._build()
        F = c["faces"][: int(c["n_object_faces"])].astype(np.int64)
        used, faces = np.unique(F, return_inverse=True)  # the used vertices, renumbered
        return io.Mesh(c["vertices"][used], faces.reshape(F.shape).astype(np.int64))

    @property
    def face_object(self) -> np.ndarray:
        """(F,) int32: for each face of :attr:`mesh`, its object's index in :attr:`objects`, or -1 for the table."""
        return self._build()["owner"].copy()

    @property
    def face_source(self) -> np.ndarray:
        """(F,) int64: for each face of :attr:`mesh`, its row in its object's mesh (or in the table's two triangles)."""
        return self._build()["source"].copy()

    def render(self, T_base_camera: np.ndarray, intrinsics: Union[Intrinsics, str], *, near: float = 0.01,
               far: float = math.inf, num_threads: int = 0) -> RenderResult:
        """Noise-free depth, face ids (into :attr:`mesh`) and incidence for a camera at ``T_base_camera``
        (camera -> base, m)."""
        c, T = self._build(), se3.require_rigid(T_base_camera, "T_base_camera")
        return render_depth(c["vertices"], c["faces"], intrinsics, se3.inverse(T), near=near, far=far,
                            num_threads=num_threads)

    def _prepare_shading(self) -> None:
        """Colour of every face for both checker albedos, built once (C++ ``_core.synthetic.scene_colors``)."""
        if "lut" not in (c := self._build()):
            c["lut"], c["lut_alt"] = _core.synthetic.scene_colors(c["normals"], c["albedo"], c["owner"],
                                                                  int(c["n_object_faces"]), self.light_direction,
                                                                  self.ambient, self.checker_colors[1])

    def shade(self, result: RenderResult, T_base_camera: np.ndarray,
              intrinsics: Union[Intrinsics, str]) -> np.ndarray:
        """(H, W, 3) uint8 colour image registered to ``result`` (same pixels), seen from ``T_base_camera``
        (camera -> base, m): each face's shaded albedo (the table's checker at the point hit); black where no hit."""
        c = self._build()
        K = as_intrinsics(intrinsics)
        T = as_transform(T_base_camera, "T_base_camera")
        fid = np.asarray(result.face_id)
        if fid.shape != K.shape:
            raise ValueError(f"result has shape {fid.shape}, intrinsics expect {K.shape}")
        self._prepare_shading()
        return _core.synthetic.shade_scene(c["lut"], c["lut_alt"], int(c["n_object_faces"]), fid,
                                           np.asarray(result.depth), K, T, self.table_center, self.checker_size)

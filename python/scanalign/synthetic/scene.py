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


def _as_color(color: Sequence[float], name: str = "color") -> np.ndarray:
    c = np.asarray(color, dtype=np.float64)
    if c.shape != (3,) or not np.all(np.isfinite(c)) or c.min() < 0 or c.max() > 1:
        raise ValueError(f"{name}: expected three values in [0, 1] (linear RGB), got {color!r}")
    return c


def _finite(value: object, shape: Tuple[int, ...], name: str, what: str) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64)
    if a.shape != shape or not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected {what}, got {value!r}")
    return a


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
    mesh: io.Mesh
    T_base_object: np.ndarray
    color: Tuple[float, float, float]


class Scene:
    """Objects on a table, in the robot base frame (z up, table top at ``table_height``).

    The table is a finite rectangle (two triangles, normal +z) with a checker pattern in the
    colour image. Rendering uses one combined mesh in the base frame, its faces reordered
    along a Morton curve for cache locality; :attr:`face_object` and :attr:`face_source` map
    its faces back to the objects.

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

    def add_object(
        self,
        mesh: io.Mesh,
        T_base_object: Optional[np.ndarray] = None,
        *,
        position: Optional[Tuple[float, float]] = None,
        yaw: float = 0.0,
        color: Sequence[float] = (0.75, 0.45, 0.20),
        name: Optional[str] = None,
    ) -> SceneObject:
        """Places a mesh (metres, its own frame) in the scene.

        Either give ``T_base_object`` (object -> base), or let the object stand on the table:
        rotated by ``yaw`` (rad) about the vertical, its lowest vertex on the table top, the
        centre of its bounding box at ``position`` (x, y, base frame, m; default the table centre).

        Returns:
            The :class:`SceneObject` (its ``T_base_object`` is the pose used).
        """
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
        """(3,) centre of the objects' bounding box in the base frame, at table height (the
        default target of trajectories); the table centre when there are no objects."""
        if not self.objects:
            return np.array([*self.table_center, self.table_height])
        v = self.object_mesh.vertices
        lo, hi = v.min(axis=0), v.max(axis=0)
        return np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, self.table_height])

    def _build(self) -> Dict[str, np.ndarray]:
        """The combined mesh (C++ ``_core.synthetic.compose_scene``): each object moved into the
        base frame, its faces in Morton order of their centroids and its vertices in order of
        first use (neighbouring faces end up close in memory, which cuts the renderer's cache
        misses on meshes stored in random order; unused vertices are dropped), then the table."""
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
        used = np.unique(F)
        remap = np.full(len(c["vertices"]), -1, dtype=np.int64)
        remap[used] = np.arange(len(used))
        return io.Mesh(c["vertices"][used].copy(), remap[F])

    @property
    def face_object(self) -> np.ndarray:
        """(F,) int32: for each face of :attr:`mesh`, its object's index in :attr:`objects`,
        or -1 for the table."""
        return self._build()["owner"].copy()

    @property
    def face_source(self) -> np.ndarray:
        """(F,) int64: for each face of :attr:`mesh`, its row in its object's own mesh (or in
        the table's two triangles)."""
        return self._build()["source"].copy()

    def render(self, T_base_camera: np.ndarray, intrinsics: Union[Intrinsics, str], *, near: float = 0.01,
               far: float = math.inf, num_threads: int = 0) -> RenderResult:
        """Noise-free depth, face ids and incidence for a camera at ``T_base_camera``
        (camera -> base, m). Face ids index :attr:`mesh`."""
        c = self._build()
        T = se3.require_rigid(T_base_camera, "T_base_camera")
        return render_depth(c["vertices"], c["faces"], intrinsics, se3.inverse(T), near=near, far=far,
                            num_threads=num_threads)

    def _prepare_shading(self) -> None:
        """Colour of every face under the fixed light, for both checker albedos (they differ
        on table faces only); the last row is the background (black). Built once (C++
        ``_core.synthetic.scene_colors``)."""
        c = self._build()
        if "lut" in c:
            return
        c["lut"], c["lut_alt"] = _core.synthetic.scene_colors(c["normals"], c["albedo"], c["owner"],
                                                              int(c["n_object_faces"]), self.light_direction,
                                                              self.ambient, self.checker_colors[1])

    def shade(self, result: RenderResult, T_base_camera: np.ndarray,
              intrinsics: Union[Intrinsics, str]) -> np.ndarray:
        """(H, W, 3) uint8 colour image registered to ``result`` (same pixels): two-sided
        Lambertian shading of each face's albedo (the object's colour, or the table's checker
        at the point hit) under :attr:`light_direction`; black where nothing is hit.
        ``T_base_camera``: camera -> base, m."""
        c = self._build()
        K = as_intrinsics(intrinsics)
        T = as_transform(T_base_camera, "T_base_camera")
        fid = np.asarray(result.face_id)
        if fid.shape != K.shape:
            raise ValueError(f"result has shape {fid.shape}, intrinsics expect {K.shape}")
        self._prepare_shading()
        # The table's checker parity from the base-frame point hit (the depth back-projected as
        # depth_to_cloud does): C++ _core.synthetic.shade_scene.
        return _core.synthetic.shade_scene(c["lut"], c["lut_alt"], int(c["n_object_faces"]), fid,
                                           np.asarray(result.depth), K, T, self.table_center, self.checker_size)

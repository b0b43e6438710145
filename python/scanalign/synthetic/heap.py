"""A heap of parts on the table: copies dropped one after another, each resting on the table or on the copies below
it, tilted, touching and occluding each other, with the share of each copy a camera sees.

The drop is a height field, not a physics engine: a copy in a random attitude (one of the six faces of its bounding box
down, a random yaw, a tilt of up to ``max_tilt``) is lowered at a random place until one of its surface samples meets
the table or a sample of a copy already there (within ``gap`` metres horizontally). Copies touch, stack and lean, and
none enters another by more than about ``gap``; whether the heap would stand under gravity is not checked.

Frames: ``base`` (z up, the table top at ``Scene.table_height``), as :mod:`scanalign.synthetic.scene`; metres, radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple

import numpy as np

from scanalign import io
from scanalign.common import rigid as se3
from scanalign.data.parts import sample_mesh
from scanalign.synthetic.scene import Scene

__all__ = ["Heap", "drop_heap", "visible_fractions"]

# The six attitudes that put one face of the part's bounding box down: rotations taking -x, +x, -y, +y, -z, +z to -z.
_FACE_DOWN = [se3.rigid(axis, angle, [0, 0, 0])[:3, :3] for axis, angle in
              (((0, 1, 0), -math.pi / 2), ((0, 1, 0), math.pi / 2), ((1, 0, 0), math.pi / 2),
               ((1, 0, 0), -math.pi / 2), ((1, 0, 0), 0.0), ((1, 0, 0), math.pi))]


@dataclass
class Heap:
    """The copies dropped into ``scene``: ``T_base_part[k]`` (4x4, part -> base) of ``scene.objects[first + k]``,
    ``part[k]`` the index of its mesh in the meshes given, and ``lifted[k]`` True when it rests on another copy."""

    scene: Scene
    T_base_part: List[np.ndarray] = field(default_factory=list)
    part: List[int] = field(default_factory=list)
    lifted: List[bool] = field(default_factory=list)
    first: int = 0


def drop_heap(meshes: Sequence[io.Mesh], count: int, *, scene: Optional[Scene] = None,
              center: Tuple[float, float] = (0.5, 0.0), radius: float = 0.05, max_tilt: float = 0.35,
              gap: float = 0.002, tries: int = 8, seed: int = 0,
              colors: Optional[Sequence[Sequence[float]]] = None) -> Heap:
    """Drops ``count`` copies, each of a mesh drawn from ``meshes`` in turn, centred within ``radius`` metres (x, y)
    of ``center`` (base frame) on ``scene`` (default: a new 0.6 m table centred there). ``max_tilt`` (rad) bounds the
    random tilt off a face-down attitude; ``gap`` (m) is the horizontal reach at which surface samples meet. Of
    ``tries`` random drops per copy the one whose centre rests lowest is kept: parts settle rather than tower."""
    if not meshes:
        raise ValueError("meshes: need at least one mesh")
    if count < 1:
        raise ValueError(f"count must be >= 1, got {count}")
    if not (radius >= 0 and max_tilt >= 0 and gap > 0):
        raise ValueError("radius and max_tilt must be >= 0 and gap > 0")
    if tries < 1:
        raise ValueError(f"tries must be >= 1, got {tries}")
    rng = np.random.default_rng(seed)
    scene = scene if scene is not None else Scene(table_size=(0.6, 0.6), table_center=center)
    heap = Heap(scene, first=len(scene.objects))
    # Surface samples and every vertex: the lowest point of a copy is a vertex.
    samples = [np.vstack([m.vertices[np.unique(m.faces)], sample_mesh(m, 3000, seed=seed)[0]]) for m in meshes]
    placed: List[np.ndarray] = []  # the surface samples of the copies dropped, base frame
    for k in range(count):
        j = k % len(meshes)
        # Gravity, roughly: of `tries` random drops the one whose centre comes to rest lowest.
        T, on_table, on_copies = min((_drop(samples[j], placed, rng, center, radius, max_tilt, gap, scene.table_height)
                                      for _ in range(tries)), key=lambda d: d[0][2, 3] + d[3])[:3]
        placed.append(samples[j] @ T[:3, :3].T + T[:3, 3])
        color = colors[k % len(colors)] if colors else (0.75, 0.45, 0.20)
        scene.add_object(meshes[j], T, color=color, name=f"heap{k}")
        heap.T_base_part.append(T)
        heap.part.append(j)
        heap.lifted.append(bool(on_copies > on_table))
    return heap


def visible_fractions(scene: Scene, T_base_camera: np.ndarray, intrinsics: object,
                      objects: Optional[Sequence[int]] = None) -> np.ndarray:
    """Per object of ``scene`` (or of ``objects``, indices into ``scene.objects``): the pixels of the camera at
    ``T_base_camera`` (camera -> base, m) that see it, over the pixels that would see it were it alone on the table:
    1 unoccluded, 0 hidden by the others."""
    seen = scene.face_object[(r := scene.render(T_base_camera, intrinsics)).face_id[r.face_id >= 0]]
    out = []
    for k in (range(len(scene.objects)) if objects is None else objects):
        alone = Scene(table_size=scene.table_size, table_center=scene.table_center, table_height=scene.table_height)
        alone.add_object(scene.objects[k].mesh, scene.objects[k].T_base_object)
        a = alone.render(T_base_camera, intrinsics)
        full = int(np.count_nonzero(alone.face_object[a.face_id[a.face_id >= 0]] == 0))
        out.append(np.count_nonzero(seen == k) / full if full else 0.0)
    return np.asarray(out)


def _drop(samples: np.ndarray, placed: List[np.ndarray], rng: np.random.Generator, center: Tuple[float, float],
          radius: float, max_tilt: float, gap: float, table_height: float) -> Tuple[np.ndarray, float, float, float]:
    """One random drop of a copy (its surface ``samples``, own frame): (T_base_part, its rest height on the table, on
    the copies ``placed``, the z of its samples' centre in its own attitude)."""
    R = _attitude(rng, max_tilt)
    rotated = samples @ R.T
    xy = np.asarray(center, dtype=np.float64) + radius * math.sqrt(rng.uniform()) * _unit(rng.uniform(0, 2 * math.pi))
    T = np.eye(4)
    T[:3, :3] = R
    T[:2, 3] = xy - (rotated[:, :2].min(axis=0) + rotated[:, :2].max(axis=0)) / 2
    on_table = table_height - rotated[:, 2].min()
    on_copies = _rest_height(rotated + [T[0, 3], T[1, 3], 0.0], placed, gap)
    T[2, 3] = max(on_table, on_copies)
    return T, on_table, on_copies, float(rotated[:, 2].mean())


def _attitude(rng: np.random.Generator, max_tilt: float) -> np.ndarray:
    """A face-down attitude, tilted by up to ``max_tilt`` about a random horizontal axis, at a random yaw."""
    R = _FACE_DOWN[int(rng.integers(6))]
    tilt = se3.rigid([*_unit(rng.uniform(0, 2 * math.pi)), 0.0], rng.uniform(0, max_tilt), [0, 0, 0])[:3, :3]
    yaw = se3.rigid([0, 0, 1], rng.uniform(0, 2 * math.pi), [0, 0, 0])[:3, :3]
    return yaw @ tilt @ R


def _unit(angle: float) -> np.ndarray:
    return np.array([math.cos(angle), math.sin(angle)])


def _rest_height(pts: np.ndarray, placed: List[np.ndarray], gap: float) -> float:
    """The lift (m, along z) that puts ``pts`` on the samples of ``placed``: the largest (placed z - own z) over pairs
    within ``gap`` horizontally; -inf when nothing is below."""
    if not placed:
        return -math.inf
    from scipy.spatial import cKDTree  # scipy: a set-up dependency; only the heap uses it here
    other = np.concatenate(placed)
    best = -math.inf
    for i, nbrs in enumerate(cKDTree(other[:, :2]).query_ball_point(pts[:, :2], gap)):
        if nbrs:
            best = max(best, float(other[nbrs, 2].max() - pts[i, 2]))
    return best

"""A synthetic scan described by one flat configuration (JSON or flat YAML), and the demo scan."""

from __future__ import annotations

import dataclasses
import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Dict, Mapping, Optional, Union

import numpy as np

from scanalign import io
from scanalign.data import downloads as datasets  # the downloader, only for CGAL mesh names
from scanalign.data.parts import builtin_mesh, normalize_mesh
from scanalign.reconstruction.camera import (INTRINSICS_PRESETS, Intrinsics, intrinsics_from_dict, intrinsics_preset,
                                             read_camera_file)
from scanalign.synthetic.noise import NOISE_PRESETS
from scanalign.synthetic.scan import SyntheticScan, render_scan
from scanalign.synthetic.scene import Scene
from scanalign.synthetic.trajectories import (DEFAULT_ROBOT_HEIGHT, ScanTrajectory, as_robot, attach_robot,
                                              hemisphere_trajectory, loop_trajectory, robot_mount)

__all__ = ["SyntheticConfig", "builtin_scan"]

PathLike = Union[str, "os.PathLike[str]"]


# The numeric fields: (names, what they must be, the test for a finite number).
_CHECKS = [(("n_frames", "rings"), "an integer in [1, 100000]", lambda v: 1 <= int(v) == v <= 100000),
           (("seed",), "an integer >= 0", lambda v: int(v) == v >= 0),
           (("height", "resolution_scale", "frame_rate"), "a positive number", lambda v: v > 0),
           (("radius", "table_size"), "a non-negative number", lambda v: v >= 0),
           (("depth_unit",), "a non-negative number or 'auto'", lambda v: v >= 0),
           (("object_size", "distance"), "a positive number or null", lambda v: v > 0),
           (("robot_x", "robot_y"), "a finite number (m) or null", lambda v: True),
           (("robot_z", "robot_roll", "robot_pitch", "robot_yaw"), "a finite number (m or rad)", lambda v: True)]


@dataclass
class SyntheticConfig:
    """Everything that defines a synthetic scan; read from JSON or flat YAML (``key: value``).

    Attributes:
        mesh: ``"builtin"`` (:func:`scanalign.data.parts.builtin_mesh`), a CGAL demo mesh name (``"bunny00"``,
            ``"fandisk"``, ... fetched by :mod:`scanalign.data.downloads`), or a path to a .ply/.off/.stl/.obj file.
        object_size: largest extent of the object (m) after scaling; None keeps the builtin part's size (80 mm) and
            scales other meshes to 0.15 m.
        object_x, object_y, object_yaw: position on the table (base frame, m) and rotation about the vertical (rad).
        table_size: side of the square table top (m); 0 for no table.
        trajectory: ``"loop"`` (``height``, ``radius``: :func:`loop_trajectory`) or ``"hemisphere"`` (``distance``,
            default ``hypot(height, radius)``, and ``rings`` elevations evenly spaced in [``min_elevation``,
            ``max_elevation``]: :func:`hemisphere_trajectory`) of ``n_frames`` from ``start_angle`` at ``frame_rate``
            (Hz); lengths in m, angles in rad.
        intrinsics: a preset name of :data:`scanalign.reconstruction.camera.INTRINSICS_PRESETS` or a mapping
            width/height/fx/fy/cx/cy; resolution_scale: image resize factor (0.5: 320x240).
        noise, seed: a preset name of ``NOISE_PRESETS`` and the noise seed.
        depth_unit: metres per uint16 depth unit; ``"auto"``: the sensor's own (0.1 mm without one); 0: float32 metres.
        robot, robot_elbow: a name of :meth:`scanalign.kinematics.Robot.by_name` (``"none"``: no arm) and its start
            configuration, ``"up"``, ``"down"`` or ``"any"`` (:func:`attach_robot`).
        robot_x, robot_y, robot_z, robot_roll, robot_pitch, robot_yaw: :func:`robot_mount` of the robot base in the
            scene; x, y None = above the object.
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
        for name, allowed in (("trajectory", ("loop", "hemisphere")), ("robot_elbow", ("up", "down", "any")),
                              ("noise", NOISE_PRESETS), ("intrinsics", INTRINSICS_PRESETS)):
            v = getattr(self, name)
            if not isinstance(v, dict) and v not in allowed:  # intrinsics may be a mapping
                raise ValueError(f"unknown {name} {v!r}; known: {sorted(allowed)}")
        for names, what, ok in _CHECKS:
            for name in names:
                v = getattr(self, name)
                number = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                if not (ok(v) if number else v is None and "null" in what or v == "auto" in what):
                    raise ValueError(f"{name} must be {what}, got {v!r}")
        self.n_frames, self.rings, self.seed = int(self.n_frames), int(self.rings), int(self.seed)
        if not 0 < self.min_elevation <= self.max_elevation <= math.pi / 2:
            raise ValueError("need 0 < min_elevation <= max_elevation <= pi/2 (radians)")
        self.intrinsics_object()  # now, not at build: a bad or huge image (2**27 pixels at most) is a ValueError
        if not isinstance(self.robot, str):
            raise ValueError(f"robot must be a robot name or 'none', got {self.robot!r}")
        if self.robot != "none":
            try:
                as_robot(self.robot)
            except ValueError as e:
                raise ValueError(f"robot: {e} (or 'none' for no robot)") from None

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "SyntheticConfig":
        """From a mapping of field names to values; unknown keys raise ValueError."""
        known = {f.name for f in dataclasses.fields(cls)}
        if unknown := sorted(set(d) - known):
            raise ValueError(f"unknown synthetic config keys {unknown}; known: {sorted(known)}")
        return cls(**{k: None if k in ("object_size", "distance", "robot_x", "robot_y") and isinstance(v, str)
                      and v.lower() in ("null", "none", "~", "") else v for k, v in d.items()})

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

    def load_mesh(self) -> io.Mesh:
        """The object mesh in metres, in its own frame (scaled per ``object_size``)."""
        if self.mesh == "builtin":
            return builtin_mesh() if self.object_size is None else normalize_mesh(builtin_mesh(), self.object_size)
        if os.path.exists(self.mesh):
            m = io.read_mesh(self.mesh)
        elif os.sep in self.mesh or (os.altsep and os.altsep in self.mesh):
            raise FileNotFoundError(f"mesh file {self.mesh!r} does not exist")
        else:  # a CGAL demo mesh name, optionally with an extension ("pig.stl")
            m = datasets.load_cgal_mesh(self.mesh)
        return normalize_mesh(m, 0.15 if self.object_size is None else self.object_size)

    def intrinsics_object(self) -> Intrinsics:
        """The camera intrinsics after ``resolution_scale``."""
        K = (intrinsics_preset if isinstance(self.intrinsics, str) else intrinsics_from_dict)(self.intrinsics)
        return K if self.resolution_scale == 1.0 else K.scaled(self.resolution_scale)

    def build_scene(self) -> Scene:
        """The table (if any) with the object standing on it."""
        scene = Scene(table_size=(self.table_size, self.table_size) if self.table_size > 0 else None,
                      table_center=(self.object_x, self.object_y))
        scene.add_object(self.load_mesh(), position=(self.object_x, self.object_y), yaw=self.object_yaw,
                         name=Path(self.mesh).stem)
        return scene

    def T_base_robot(self) -> Optional[np.ndarray]:
        """The robot's mounting in the scene (robot base -> base, 4x4, m), or None without a robot."""
        return None if self.robot == "none" else robot_mount(
            self.object_x if self.robot_x is None else self.robot_x,
            self.object_y if self.robot_y is None else self.robot_y,
            self.robot_z, self.robot_roll, self.robot_pitch, self.robot_yaw)

    def build_trajectory(self, scene: Scene) -> ScanTrajectory:
        """The planned camera path; with a robot, followed by the arm (:func:`attach_robot`: ValueError naming the
        frame and the IK status of a pose the robot cannot reach from its mount)."""
        if self.trajectory == "loop":
            traj = loop_trajectory(self.n_frames, center=scene.center, height=self.height, radius=self.radius,
                                   start_angle=self.start_angle, frame_rate=self.frame_rate)
        else:
            distance = self.distance if self.distance is not None else math.hypot(self.height, self.radius)
            traj = hemisphere_trajectory(self.n_frames, center=scene.center, distance=distance,
                                         elevations=np.linspace(self.min_elevation, self.max_elevation, self.rings),
                                         start_angle=self.start_angle, frame_rate=self.frame_rate)
        return traj if self.robot == "none" else attach_robot(traj, self.robot, T_base_robot=self.T_base_robot(),
                                                              elbow=self.robot_elbow)

    def build(self, *, keep_ground_truth: bool = False) -> SyntheticScan:
        """Builds the scene and trajectory and renders the scan (``keep_ground_truth``: noise-free
        depth and face ids in each frame's ``meta``)."""
        scene = self.build_scene()
        unit = self.depth_unit if isinstance(self.depth_unit, str) or self.depth_unit > 0 else None
        return render_scan(scene, self.build_trajectory(scene), self.intrinsics_object(), self.noise, self.seed,
                           depth_unit=unit, keep_ground_truth=keep_ground_truth, frame_rate=self.frame_rate)


def builtin_scan(n_frames: int = 36, noise: str = "sr300", seed: int = 0, *, trajectory: str = "loop",
                 intrinsics: str = "sr300", resolution_scale: float = 1.0, keep_ground_truth: bool = False,
                 robot: str = "ur5") -> SyntheticScan:
    """The demo scan, no download needed: the built-in part on a 60 cm table, seen by an SR300-like camera on a loop
    40 cm above the table (radius 20 cm), 10 Hz, carried by a UR5 hanging 0.9 m above the table.  The arguments are
    :class:`SyntheticConfig` fields and :meth:`SyntheticConfig.build`'s ``keep_ground_truth``."""
    return SyntheticConfig(n_frames=n_frames, noise=noise, seed=seed, trajectory=trajectory, intrinsics=intrinsics,
                           resolution_scale=resolution_scale, robot=robot).build(keep_ground_truth=keep_ground_truth)

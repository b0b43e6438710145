"""A live 3D view in rerun (https://rerun.io, optional: ``pip install rerun-sdk``) of a reconstruction while it runs
and of the outcome of a pick, in a viewer, a ``.rrd`` recording or both::

    from scanalign.pipelines.reconstruct import reconstruct
    from scanalign.viz.viewer import Viewer

    with Viewer(spawn=True, save="scan.rrd") as view:   # spawn: start / connect to the viewer
        result = reconstruct(frames, on_frame=view.on_frame)
        view.log_reconstruction(result)

``scanalign reconstruct|pick --view`` and ``--view-save FILE.rrd`` do the same from the
command line; :func:`scanalign.pipelines.pick.pick` takes ``viewer=``.

Entities (world = the model / robot base frame, metres): ``world/model`` (points), ``world/camera`` (pose and pinhole),
``world/camera_path`` and ``world/reference_path`` (the estimated and the robot's camera centres), ``world/arm`` (the
arm's joint origins, a line strip), ``world/scene``, ``world/parts/<k>_<name>`` (pick: the part's mesh at its pose) and
``world/grasps/<k>_<name>/arm`` (the arm at the chosen grasp). Timelines: ``frame`` (index) and ``time`` (timestamp, s).
"""

from __future__ import annotations

import os
import socket
import sys
import warnings
from typing import Any, List, Optional, Union

import numpy as np

from scanalign.common.rigid import transform_points
from scanalign.kinematics import Robot

__all__ = ["Viewer", "arm_points"]


def _rerun() -> Any:
    try:
        import rerun
    except ImportError as e:
        raise ImportError("the live view needs the optional package 'rerun-sdk': pip install rerun-sdk") from e
    return rerun


def _listening(port: int) -> bool:
    """True when something takes TCP connections on localhost:``port`` (a rerun viewer running)."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=1.0):
            return True
    except OSError:
        return False


def arm_points(robot: Any, q: np.ndarray, T_base_flange: Optional[np.ndarray] = None) -> np.ndarray:
    """(8, 3) points of the arm in its base frame, metres: ``Robot.joint_positions(q, tcp=True)``,
    the origins of DH frames 0..6 and the TCP; with ``T_base_flange`` (flange -> base) moved
    so that the flange lies there (a robot mounted elsewhere than its name's default)."""
    q = np.asarray(q, dtype=np.float64).reshape(6)
    points = np.asarray(robot.joint_positions(q, tcp=True))
    if T_base_flange is not None:
        M = np.asarray(T_base_flange, dtype=np.float64) @ np.linalg.inv(np.asarray(robot.fk_flange(q)))
        points = transform_points(M, points)
    return points


def _colors(c: Optional[np.ndarray]) -> Optional[np.ndarray]:
    if c is None or len(c) == 0:
        return None
    c = np.asarray(c)
    return c if c.dtype == np.uint8 else np.clip(np.rint(c * 255), 0, 255).astype(np.uint8)


class Viewer:
    """A rerun recording of scanalign runs (ImportError when rerun-sdk is not installed).

    Args:
        name: the rerun application id.
        spawn: start a rerun viewer (or connect to one already listening on its port, 9876). RuntimeError,
            before anything runs, when none can be shown: on Linux without a display (``DISPLAY`` /
            ``WAYLAND_DISPLAY`` unset), or when the viewer exits at once; use ``save=`` there.
        save: write the recording to this ``.rrd`` file (as well, with ``spawn``).
        connect: a rerun gRPC URL to stream to (a viewer on another machine).
        robot: the :class:`scanalign.kinematics.Robot` drawn from the frames' joints (default: by name from
            ``Frame.meta["robot"]``).
        model_every, max_model_points: log the growing model every this many merged frames,
            at most this many points (evenly subsampled).
    """

    def __init__(self, name: str = "scanalign", *, spawn: bool = False, save: Optional[Union[str, os.PathLike]] = None,
                 connect: Optional[str] = None, robot: Any = None, model_every: int = 5,
                 max_model_points: int = 500_000) -> None:
        rr = self.rr = _rerun()
        self.rec = rr.RecordingStream(name)
        if spawn:
            self._spawn()
        sinks = (([rr.GrpcSink()] if spawn else []) + ([rr.GrpcSink(connect)] if connect else [])
                 + ([rr.FileSink(os.fspath(save))] if save is not None else []))
        if sinks:
            self.rec.set_sinks(*sinks)
        self.robot, self.model_every, self.max_model_points = robot, max(1, int(model_every)), int(max_model_points)
        self._path: List[np.ndarray] = []
        self._merged = 0
        self._T_world_base: Optional[np.ndarray] = None
        self.rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)

    def _spawn(self, port: int = 9876) -> None:
        # A viewer without a window dies at once while the run goes on, streaming into nothing.
        fix = ("set DISPLAY (e.g. ssh -X), or record to a file instead, save='scan.rrd' (on the command line "
               "--view-save scan.rrd), and open it with 'rerun scan.rrd' where there is a display")
        displays = ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET")
        if sys.platform.startswith("linux") and not any(map(os.environ.get, displays)) and not _listening(port):
            raise RuntimeError(f"cannot show a rerun viewer (spawn=True / --view): no display (DISPLAY and "
                               f"WAYLAND_DISPLAY are unset) and no viewer listening on port {port}; {fix}")
        self.rec.spawn(port=port, connect=False)
        if not _listening(port):  # rerun waits a few seconds for the port, then goes on without a viewer
            raise RuntimeError(f"the rerun viewer did not start or exited at once (see its messages above); {fix}")

    def log_points(self, path: str, points: np.ndarray, colors: Optional[np.ndarray] = None, **kw: Any) -> None:
        """(N, 3) points (metres; optional (N, 3) colours, uint8 or float in [0, 1]) at ``path``."""
        p = np.asarray(points, dtype=np.float32).reshape(-1, 3)
        step = max(1, -(-len(p) // self.max_model_points))
        c = _colors(colors)
        self.rec.log(path, self.rr.Points3D(p[::step], colors=None if c is None else c[::step], **kw))

    def log_pose(self, path: str, T: np.ndarray, axis_length: float = 0.05) -> None:
        """A 4x4 pose (child -> world) at ``path``, drawn as axes."""
        T = np.asarray(T, dtype=np.float64)
        self.rec.log(path, self.rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]),
                     self.rr.TransformAxes3D(axis_length))

    def log_arm(self, path: str, robot: Any, q: np.ndarray, T_base_flange: Optional[np.ndarray] = None) -> None:
        """The arm at joints ``q`` (rad) as a line strip through :func:`arm_points`."""
        pts = arm_points(robot, q, T_base_flange)
        pts = pts if self._T_world_base is None else transform_points(self._T_world_base, pts)
        self.rec.log(path, self.rr.LineStrips3D([pts], radii=0.006, colors=[[255, 140, 0]]),
                     self.rr.Points3D(pts, radii=0.01))

    def on_frame(self, frame: Any, record: Any, reconstructor: Any) -> None:
        """The ``on_frame=`` hook of :func:`scanalign.pipelines.reconstruct.reconstruct`."""
        rr = self.rr
        self.rec.set_time("frame", sequence=int(record.index))
        self.rec.set_time("time", duration=float(record.timestamp))
        if self._T_world_base is None and record.merged and (T_bc := getattr(frame, "T_base_camera", None)) is not None:
            self._T_world_base = np.asarray(record.T_model_camera) @ np.linalg.inv(np.asarray(T_bc))
        if record.merged:
            T = np.asarray(record.T_model_camera, dtype=np.float64)
            self._path.append(T[:3, 3].copy())
            self.rec.log("world/camera", rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]))
            if (K := getattr(frame, "intrinsics", None)) is not None and self._merged == 0:  # the camera's image, once
                self.rec.log("world/camera", rr.Pinhole(focal_length=[K.fx, K.fy], principal_point=[K.cx, K.cy],
                                                        width=K.width, height=K.height, image_plane_distance=0.05))
            self.rec.log("world/camera_path", rr.LineStrips3D([np.array(self._path)], radii=0.001,
                                                              colors=[[30, 120, 220]]))
            self._merged += 1
            if self._merged % self.model_every == 1 or self.model_every == 1:
                self.log_points("world/model", reconstructor.model.points, reconstructor.model.colors, radii=0.0008)
        meta = getattr(frame, "meta", None) or {}
        if self.robot is None and meta.get("robot") is not None:
            self.robot = Robot.by_name(str(meta["robot"]))
        if self.robot is not None and meta.get("joints") is not None:
            self.log_arm("world/arm", self.robot, meta["joints"], meta.get("T_base_flange"))

    def log_reconstruction(self, result: Any) -> None:
        """The model and camera paths of a :class:`scanalign.pipelines.reconstruct.ReconstructionResult`."""
        if result.records:
            self.rec.set_time("frame", sequence=int(result.records[-1].index))
        self.log_points("world/model", result.model.points, result.model.colors, radii=0.0008)
        self.rec.log("world/camera_path", self.rr.LineStrips3D([result.estimate.positions], radii=0.001,
                                                               colors=[[30, 120, 220]]))
        if result.reference is not None and len(result.reference):
            ref = result.reference.positions
            ref = ref if self._T_world_base is None else transform_points(self._T_world_base, ref)
            self.rec.log("world/reference_path", self.rr.LineStrips3D([ref], radii=0.001, colors=[[40, 170, 60]]))

    def log_pick(self, result: Any) -> None:
        """A :class:`scanalign.pipelines.pick.PickResult`, in its base frame."""
        rr = self.rr
        self._T_world_base = None  # the pick's world is its base frame
        self.rec.set_time("frame", sequence=int(result.reconstruction.records[-1].index) + 1
                          if result.reconstruction is not None and result.reconstruction.records else 0)
        self.log_points("world/scene", result.points, np.full((len(result.points), 3), 160, np.uint8), radii=0.0008)
        meshes = {p.name: p.mesh for p in result.parts}
        for k, p in enumerate(result.picks):
            if p.T_base_model is None:
                continue
            key = f"{k}_{p.part}"
            self.log_pose(f"world/parts/{key}", p.T_base_model)
            m = meshes[p.part]
            if hasattr(m, "faces"):
                self.rec.log(f"world/parts/{key}", rr.Mesh3D(vertex_positions=m.vertices, triangle_indices=m.faces,
                                                             albedo_factor=[70, 130, 230, 255]))
            else:  # a scanned model cloud
                self.rec.log(f"world/parts/{key}", rr.Points3D(m.points, colors=[70, 130, 230], radii=0.0008))
            if p.status == "picked":
                self.log_arm(f"world/grasps/{key}/arm", result.tcp_robot(p), p.chosen.q_grasp)  # to the TCP
                self.log_pose(f"world/grasps/{key}/tcp", np.asarray(p.chosen.T_base_tcp_grasp), axis_length=0.03)

    def close(self, timeout: float = 60.0) -> None:
        """Flushes everything to the viewer / file, waiting at most ``timeout`` s, and disconnects
        (rerun waits at most 5 s for a viewer); rerun's RuntimeError when the viewer did not take it all."""
        try:
            self.rec.flush(timeout_sec=timeout)
        finally:
            self.rec.disconnect()

    def __enter__(self) -> "Viewer":
        return self

    def __exit__(self, *exc: Any) -> None:
        # A lost viewer must neither hide the caller's own exception nor fail a run that finished: a warning.
        try:
            self.close()
        except Exception as e:  # rerun's errors: a viewer gone, a timeout
            warnings.warn(f"the rerun viewer did not receive the whole recording ({e})", RuntimeWarning, stacklevel=2)

"""Recordings other than TUM folders as sequences of :class:`~scanalign.reconstruction.camera.Frame` (``len``, indexing,
iteration; images decoded when a frame is requested), opened by :func:`scanalign.datasets.open_source`: ROS 1 and ROS 2
bags (RealSense recordings included) as :class:`BagSequence`, read with the pure-Python ``rosbags`` package
(``pip install 'scanalign[ros]'``, no ROS install), and folders of PNG images with a camera file as
:class:`ImageFolderSequence`; :func:`write_bag` and :func:`write_image_folder` write both (samples from the synthetic
scanner: ``scanalign synth builtin OUT --format bag|png``)."""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any, Dict, Iterator, List, Optional, Sequence, Tuple

import numpy as np

from scanalign.datasets.tum import (ImageFileSequence, PathLike, camera_argument, check_number, check_selection,
                                    depth_units, interpolate, pair_frames, resolve_camera, write_tum_sequence)
from scanalign.evaluation.trajectory import Trajectory, pose_from_tum
from scanalign.reconstruction.camera import Frame, camera_from_dict, sequence_index

__all__ = ["BagSequence", "ImageFolderSequence", "is_bag", "is_image_folder", "write_bag", "write_image_folder",
           "DEPTH_ENCODINGS", "COLOR_ENCODINGS"]

#: Depth image encodings read from bags: numpy dtype and whether the values are metres.
DEPTH_ENCODINGS = {"16UC1": ("u2", False), "mono16": ("u2", False), "32FC1": ("f4", True)}
#: Colour encodings: channels and whether the order is BGR.
COLOR_ENCODINGS = {"rgb8": (3, False), "bgr8": (3, True), "rgba8": (4, False), "bgra8": (4, True)}

_IMAGE, _INFO = "sensor_msgs/msg/Image", "sensor_msgs/msg/CameraInfo"
_JOINTS, _TF, _FLOAT32 = "sensor_msgs/msg/JointState", "tf2_msgs/msg/TFMessage", "std_msgs/msg/Float32"

#: UR arms' joint names in kinematic order (the ROS drivers publish them alphabetically).
_UR_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint")


def is_bag(path: Any) -> bool:
    """True for a ROS 1 ``.bag`` file, a ROS 2 ``.mcap`` / ``.db3`` file or a ROS 2 bag folder
    (one with ``metadata.yaml``)."""
    try:
        p = Path(path)
        return (p.is_file() and p.suffix.lower() in (".bag", ".mcap", ".db3")) or (
            p.is_dir() and (p / "metadata.yaml").is_file())
    except (TypeError, ValueError, OSError):
        return False


_IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
_COLOR_DIRS = ("rgb", "color", "colour")


def is_image_folder(path: Any) -> bool:
    """True for a folder with a ``depth/`` sub-folder of PNG images (:class:`ImageFolderSequence`)."""
    try:
        d = Path(path) / "depth"
        return d.is_dir() and any(f.suffix.lower() == ".png" for f in d.iterdir())
    except (TypeError, ValueError, OSError):
        return False


def _field(msg: Any, *names: str) -> Any:
    """A message field under its ROS 2 name or its ROS 1 one (``k`` / ``K``)."""
    for n in names:
        if hasattr(msg, n):
            return getattr(msg, n)
    raise AttributeError(f"message {type(msg).__name__} has none of the fields {names}")


def _stamp_ns(msg: Any, bag_time: Optional[int] = None) -> int:
    """A message's header stamp (ns), or ``bag_time`` when given and the stamp is unset (<= 0)."""
    s = msg.header.stamp
    ns = int(s.sec) * 1_000_000_000 + int(_field(s, "nanosec", "nsec"))
    return ns if ns > 0 or bag_time is None else bag_time


def _seconds(ns: Any) -> Any:
    """Nanoseconds (int or int64 array) as float seconds, rounded once: whole seconds plus the
    fraction, so that a stamp of 1700000000.1 s reads as the float 1700000000.1."""
    whole, fraction = divmod(ns if isinstance(ns, np.ndarray) else int(ns), 1_000_000_000)
    return whole + fraction / 1e9


def _common_prefix(a: str, b: str) -> int:
    """Number of leading topic-name components two topics share."""
    return len(os.path.commonprefix([a.strip("/").split("/"), b.strip("/").split("/")]))


def _order_joints(names: Sequence[str]) -> List[str]:
    """A joint order for the robot: UR names (any prefix) in kinematic order, others as published."""
    for prefix in {n[: -len(u)] for n in names for u in _UR_JOINTS if n.endswith(u)}:
        ur = [prefix + u for u in _UR_JOINTS]
        if all(n in names for n in ur):
            return ur
    return list(names)


class BagSequence:
    """The RGB-D frames of a ROS 1 or ROS 2 bag, read with ``rosbags`` (pure Python).

    Opening the bag chooses the topics, reads every depth, colour, joint-state and tf message's
    timestamp and interpolates each frame's joints and pose at its depth timestamp; images are
    decoded when a frame is requested. Frames are the depth images in header-timestamp order,
    paired with colour and selected as in :class:`~scanalign.datasets.tum.TumSequence`.

    Args:
        path: a ROS 1 ``.bag``, a ROS 2 bag folder, or a ROS 2 ``.mcap`` / ``.db3`` file.
        depth_topic: the depth ``sensor_msgs/Image`` topic; default: the only one with a depth
            encoding (:data:`DEPTH_ENCODINGS`), preferring names with ``aligned_depth_to_color``
            when colour is present, then names with ``depth``.
        color_topic: the colour topic, or False for none; default: the colour-encoded (:data:`COLOR_ENCODINGS`) topic
            registered to the depth images (their size and ``header.frame_id``) sharing the longest name prefix with the
            depth topic (none: no colour, said in :attr:`notes`). A named one must have the depth size.
        camera_info_topic: the depth images' ``sensor_msgs/CameraInfo`` (its K and "plumb_bob"
            distortion); default: the one of their size sharing the longest name prefix.
        intrinsics: an :class:`Intrinsics`, a preset name or a camera file overriding
            camera_info (needed when the bag has none).
        depth_scale: metres per unit of 16-bit depth; default: a RealSense recording's ``Depth
            Units`` option, else 0.001 (the ROS convention). Float (32FC1) depth is metres.
        joint_states_topic: the robot's ``sensor_msgs/JointState`` topic, or False; default
            ``/joint_states`` or the only one.
        joint_names: the joints of ``meta["joints"]``, in order; default: the first message's
            names (a UR arm's in kinematic order, whatever order the driver publishes).
        tf, base_frame, camera_frame: ``T_base_camera`` from tf (``tf=False``: none), relative to
            ``base_frame`` (default: the root of the tf tree above the camera frame), of
            ``camera_frame`` (default: the depth images' ``header.frame_id``).
        max_time_difference: largest |t_depth - t_colour| (s) of a pair.
        max_joint_gap, max_tf_gap: largest time (s) between the two joint states / moving tf
            samples around a frame for it to get joints / a pose.
        start, stride, limit: frame selection after pairing.

    Attributes:
        path, depth_topic, color_topic / camera_info_topic / joint_states_topic (or None),
        joint_names, base_frame, camera_frame, intrinsics, depth_scale, timestamps ((N,)
        float64 depth header times, s), dropped_depth_frames, notes (what was chosen or ignored,
        and why).

    Frames: ``depth`` (H, W) uint16 (units of :attr:`depth_scale`) or float32 metres, ``rgb`` (H, W, 3) uint8 or None,
    ``timestamp`` the depth header time (s), ``T_base_camera`` from tf or None; ``meta``: ``joints`` ((n,) rad, when
    known), ``joint_names``, ``depth_topic``, ``rgb_timestamp``, ``bag``.

    Raises:
        ImportError: ``rosbags`` is not installed.
        ValueError: naming the file: not a readable bag, no depth topic (or several and none
            named), an unknown or mismatched encoding, no camera_info (and no intrinsics), a
            named topic that is missing or of the wrong type, a malformed image.
    """

    def __init__(self, path: PathLike, *, depth_topic: Optional[str] = None, color_topic: Any = None,
                 camera_info_topic: Optional[str] = None, intrinsics: Any = None, depth_scale: Optional[float] = None,
                 joint_states_topic: Any = None, joint_names: Optional[Sequence[str]] = None, tf: bool = True,
                 base_frame: Optional[str] = None, camera_frame: Optional[str] = None,
                 max_time_difference: float = 0.02, max_joint_gap: float = 0.1, max_tf_gap: float = 0.1,
                 start: int = 0, stride: int = 1, limit: Optional[int] = None) -> None:
        try:
            from rosbags.highlevel import AnyReader
            from rosbags.typesys import Stores, get_typestore
        except ImportError as e:
            raise ImportError("reading ROS bags needs the pure-Python package 'rosbags': pip install "
                              f"'scanalign[ros]' (or pip install rosbags) ({e})") from None
        self.path = Path(path)
        if not self.path.exists():
            raise FileNotFoundError(f"{self.path}: no such bag")
        check_selection(start, stride, limit)
        max_dt, max_joint_gap, max_tf_gap = (check_number(name, v, "a finite number >= 0 (s)") for name, v in (
            ("max_time_difference", max_time_difference), ("max_joint_gap", max_joint_gap), ("max_tf_gap", max_tf_gap)))
        self.notes: List[str] = []
        try:
            reader = AnyReader([self.path], default_typestore=get_typestore(
                Stores.ROS1_NOETIC if self.path.suffix.lower() == ".bag" else Stores.ROS2_HUMBLE))
            reader.open()
        except ImportError:
            raise
        except Exception as e:  # rosbags raises its own error types (and struct/OS errors on garbage)
            raise ValueError(f"{self.path}: not a readable ROS bag ({type(e).__name__}: {e})") from None
        self._reader = reader
        try:
            self._index(depth_topic, color_topic, camera_info_topic, intrinsics, depth_scale, camera_frame, max_dt,
                        start, stride, limit)
            t = np.array([self._depth[d][0] for d, _ in self._frames], dtype=np.int64)  # header times, ns
            self._joints = self._read_joints(joint_states_topic, joint_names, t, max_joint_gap * 1e9)
            self.base_frame = None
            self._poses = self._read_tf(base_frame, t, max_tf_gap * 1e9) if tf else [None] * len(t)
        except BaseException:
            self.close()
            raise

    def _error(self, message: str) -> ValueError:
        return ValueError(f"{self.path}: {message}")

    def _topics(self, msgtype: str) -> Dict[str, Any]:
        return {c.topic: c for c in self._reader.connections if c.msgtype == msgtype}

    def _first(self, connection: Any) -> Any:
        return next((self._deserialize(raw, c) for c, _, raw in self._reader.messages(connections=[connection])), None)

    def _deserialize(self, raw: bytes, conn: Any) -> Any:
        try:
            return self._reader.deserialize(raw, conn.msgtype)
        except Exception as e:
            raise self._error(f"topic {conn.topic}: cannot decode a {conn.msgtype} message ({type(e).__name__}: "
                              f"{e})") from None

    def _pick_topic(self, given: Any, msgtype: str, what: str) -> Any:
        topics = self._topics(msgtype)
        if given not in topics:
            other = [c.msgtype for c in self._reader.connections if c.topic == given]
            found = f"it is a {other[0]}" if other else "no such topic"
            raise self._error(f"{what} topic {given!r}: {found}; {msgtype} topics: {sorted(topics) or 'none'}")
        return topics[given]

    def _index(self, depth_topic, color_topic, info_topic, intrinsics, depth_scale, camera_frame, max_dt, start,
               stride, limit) -> None:
        images = self._topics(_IMAGE)
        firsts = {t: m for t, c in images.items() if (m := self._first(c)) is not None}

        # Depth.
        if depth_topic is not None:
            self._pick_topic(depth_topic, _IMAGE, "depth")
            if depth_topic not in firsts:
                raise self._error(f"depth topic {depth_topic!r} has no messages")
            if firsts[depth_topic].encoding not in DEPTH_ENCODINGS:
                raise self._error(f"depth topic {depth_topic!r} has encoding {firsts[depth_topic].encoding!r}; depth "
                                  f"must be one of {sorted(DEPTH_ENCODINGS)}")
        else:
            cands = sorted(t for t, m in firsts.items() if m.encoding in DEPTH_ENCODINGS)
            if not cands:
                listed = ", ".join(f"{t} ({m.encoding})" for t, m in sorted(firsts.items())) or "none"
                raise self._error(f"no depth images: no sensor_msgs/Image topic with a depth encoding "
                                  f"{sorted(DEPTH_ENCODINGS)} (image topics: {listed})")
            has_color = any(m.encoding in COLOR_ENCODINGS for m in firsts.values())
            for rule in (lambda t: has_color and "aligned_depth_to_color" in t, lambda t: "depth" in t.lower()):
                if len(cands) > 1 and sum(map(rule, cands)) >= 1:
                    cands = [t for t in cands if rule(t)]
            if len(cands) > 1:
                raise self._error(f"several depth image topics {cands}; pass depth_topic=")
            depth_topic = cands[0]
        first, self.depth_topic = firsts[depth_topic], depth_topic
        size = (int(first.width), int(first.height))

        # Colour.
        self.color_topic = None
        if color_topic is None:
            # Registered colour has the depth images' size and optical frame (RealSense's
            # aligned_depth_to_color is published in the colour camera's frame).
            cands = [t for t, m in firsts.items() if m.encoding in COLOR_ENCODINGS]
            same = sorted((t for t in cands if (int(firsts[t].width), int(firsts[t].height)) == size
                           and firsts[t].header.frame_id == first.header.frame_id),
                          key=lambda t: (-_common_prefix(t, depth_topic), t))
            if same:
                self.color_topic = same[0]
            elif cands:
                self.notes.append(f"colour topics {sorted(cands)} left out: not registered to the depth images (not "
                                  f"{size[0]}x{size[1]} in frame {first.header.frame_id!r}); color_topic= uses one "
                                  "of the same size anyway")
        elif color_topic is not False:
            self._pick_topic(color_topic, _IMAGE, "colour")
            m = firsts.get(color_topic)
            if m is None or m.encoding not in COLOR_ENCODINGS:
                raise self._error(f"colour topic {color_topic!r} has encoding {getattr(m, 'encoding', None)!r}; "
                                  f"colour must be one of {sorted(COLOR_ENCODINGS)}")
            if (int(m.width), int(m.height)) != size:
                raise self._error(f"colour topic {color_topic!r} has {m.width}x{m.height} images but the depth images "
                                  f"are {size[0]}x{size[1]}: colour must be registered to depth (e.g. RealSense "
                                  "aligned_depth_to_color)")
            self.color_topic = color_topic

        # Camera.
        self.camera_info_topic = None
        given, file_scale, _ = camera_argument(intrinsics)
        if given is None:
            if info_topic is not None:
                msg = self._first(self._pick_topic(info_topic, _INFO, "camera_info"))
                if msg is None:
                    raise self._error(f"camera_info topic {info_topic!r} has no messages")
            else:
                infos = self._topics(_INFO)
                sized = {t: m for t, c in infos.items()
                         if (m := self._first(c)) is not None and (int(m.width), int(m.height)) == size}
                if not sized:
                    raise self._error(f"no sensor_msgs/CameraInfo for the {size[0]}x{size[1]} depth images of "
                                      f"{depth_topic} (camera_info topics: {sorted(infos) or 'none'}); pass "
                                      "intrinsics= (a preset, a camera file or an Intrinsics)")
                info_topic = max(sorted(sized), key=lambda t: _common_prefix(t, depth_topic))
                msg = sized[info_topic]
            try:
                given, _ = camera_from_dict({"width": int(msg.width), "height": int(msg.height),
                                             "K": np.asarray(_field(msg, "k", "K"), dtype=np.float64),
                                             "D": np.asarray(_field(msg, "d", "D"), dtype=np.float64),
                                             "distortion_model": msg.distortion_model})
            except ValueError as e:
                raise self._error(f"camera_info topic {info_topic}: {e}") from None
            self.camera_info_topic = info_topic
        if (given.width, given.height) != size:
            raise self._error(f"depth images are {size[0]}x{size[1]} but the intrinsics are "
                              f"{given.width}x{given.height}")
        self.intrinsics = given

        # Depth scale: argument, camera file, RealSense's "Depth Units" option, 1 mm.
        scale = depth_scale if depth_scale is not None else file_scale
        if scale is not None:
            scale = check_number("depth_scale", scale, "in (0, 1] metres per unit", strict=True, high=1)
        else:
            units = sorted((c for t, c in self._topics(_FLOAT32).items() if t.lower().endswith("depth units/value")),
                           key=lambda c: -_common_prefix(c.topic, depth_topic))
            m = self._first(units[0]) if units else None
            if m is not None and math.isfinite(float(m.data)) and 0 < float(m.data) <= 1:
                # A float32 in the bag: its shortest decimal (1e-4, not 1.0000000475e-4).
                scale = float(np.format_float_positional(np.float32(m.data), unique=True))
                self.notes.append(f"depth_scale {scale:g} m from {units[0].topic}")
        self.depth_scale = 0.001 if scale is None else scale

        # Timestamps of every image (header stamps; bag time kept for random access).
        self._depth_conn, self._color_conn = images[depth_topic], images.get(self.color_topic)
        self._depth = self._stamps(self._depth_conn)  # not empty: the topic has a first message
        self._color = self._stamps(self._color_conn) if self._color_conn is not None else []
        d_ts = _seconds(np.array([s for s, _, _ in self._depth], dtype=np.int64))
        di, ci = np.arange(len(d_ts)), None
        if self._color:
            c_ts = _seconds(np.array([s for s, _, _ in self._color], dtype=np.int64))
            di, ci = pair_frames(d_ts, c_ts, max_dt, self.path, f" of {depth_topic} ({self.color_topic})").T
        self.dropped_depth_frames = int(len(d_ts) - len(di))
        keep = np.arange(len(di))[start::stride][:limit]
        self._frames = [(int(di[k]), None if ci is None else int(ci[k])) for k in keep]
        self.timestamps = d_ts[di[keep]]
        self.camera_frame = camera_frame or first.header.frame_id or None

    def _stamps(self, conn: Any) -> List[Tuple[int, int, int]]:
        """(header stamp ns, bag time ns, ordinal among the messages at that bag time), sorted
        by header stamp (bag order breaks ties)."""
        out, last, n = [], None, 0
        for c, t, raw in self._reader.messages(connections=[conn]):
            n = n + 1 if t == last else 0
            last = t
            out.append((_stamp_ns(self._deserialize(raw, c), t), t, n))
        if len({s for s, _, _ in out}) != len(out):
            raise self._error(f"topic {conn.topic}: two images with the same header timestamp")
        return sorted(out)

    def _read_joints(self, topic: Any, joint_names: Optional[Sequence[str]], t: np.ndarray,
                     max_gap: float) -> List[Optional[np.ndarray]]:
        """Per frame (header times ``t``, ns), the joints interpolated linearly, or None."""
        self.joint_states_topic, self.joint_names = None, None
        states = {} if topic is False else self._topics(_JOINTS)
        if topic is not None and topic is not False:
            conn = self._pick_topic(topic, _JOINTS, "joint_states")
        elif "/joint_states" in states or len(states) == 1:
            conn = states.get("/joint_states") or next(iter(states.values()))
        else:
            if states:
                self.notes.append(f"several JointState topics {sorted(states)}: none used; pass joint_states_topic=")
            return [None] * len(t)
        times, rows, names = [], [], None if joint_names is None else [str(n) for n in joint_names]
        for c, bag_t, raw in self._reader.messages(connections=[conn]):
            m = self._deserialize(raw, c)
            msg_names = [str(n) for n in m.name]
            if names is None:
                names = _order_joints(msg_names)
            if not all(n in msg_names for n in names):
                continue  # another publisher's joints (a gripper)
            pos = np.asarray(m.position, dtype=np.float64)
            if len(pos) != len(msg_names):
                raise self._error(f"topic {conn.topic}: a JointState with {len(msg_names)} names and {len(pos)} "
                                  "positions")
            times.append(_stamp_ns(m, bag_t))
            rows.append(pos[[msg_names.index(n) for n in names]])
        if not rows:
            self.notes.append(f"{conn.topic}: no joint states" + (f" with all of {names}" if names else ""))
            return [None] * len(t)
        self.joint_states_topic, self.joint_names = conn.topic, names
        order = np.argsort(np.array(times, dtype=np.int64), kind="stable")
        return interpolate(np.array(times, dtype=np.int64)[order], np.stack(rows)[order], t, max_gap)

    def _read_tf(self, base_frame: Optional[str], t: np.ndarray, max_gap: float) -> List[Optional[np.ndarray]]:
        """Per frame (header times ``t``, ns), ``T_base_camera`` along the tf chain (each moving
        link interpolated, a static one as last published), or None."""
        edges: Dict[str, Dict[str, Any]] = {}  # child -> {parent, static, samples [(t, tx ty tz qx qy qz qw)]}
        for topic, static in (("/tf_static", True), ("/tf", False)):
            conn = self._topics(_TF).get(topic)
            if conn is None:
                continue
            for c, bag_t, raw in self._reader.messages(connections=[conn]):
                for ts in self._deserialize(raw, c).transforms:
                    child, parent = ts.child_frame_id.lstrip("/"), ts.header.frame_id.lstrip("/")
                    e = edges.setdefault(child, {"parent": parent, "static": static, "samples": []})
                    if e["parent"] != parent:
                        raise self._error(f"{topic}: frame {child!r} has two parents, {e['parent']!r} and {parent!r}")
                    r, q = ts.transform.translation, ts.transform.rotation
                    e["samples"].append((_stamp_ns(ts, bag_t), (r.x, r.y, r.z, q.x, q.y, q.z, q.w)))
        if not edges or self.camera_frame is None:
            return [None] * len(t)
        camera = self.camera_frame.lstrip("/")
        chain, frame = [], camera
        while frame in edges and frame != base_frame and len(chain) <= len(edges):
            chain.append(frame)
            frame = edges[frame]["parent"]
        if base_frame is not None and frame != base_frame.lstrip("/"):
            raise self._error(f"tf: no chain from base_frame {base_frame!r} to the camera frame {camera!r}")
        if not chain:
            self.notes.append(f"tf: the camera frame {camera!r} is not in the tf tree: no poses")
            return [None] * len(t)
        self.base_frame = frame
        poses: List[Optional[np.ndarray]] = [np.eye(4)] * len(t)
        for child in reversed(chain):  # base -> camera
            s = sorted(edges[child]["samples"], key=lambda x: x[0])
            ns = np.array([x[0] for x in s], dtype=np.int64)
            P = Trajectory(_seconds(ns), pose_from_tum([x[1] for x in s])).poses  # checked finite
            # A tf_static link holds whatever was published last, at any time.
            links = [P[-1]] * len(t) if edges[child]["static"] else interpolate(ns, P, t, max_gap)
            poses = [None if T is None or E is None else T @ E for T, E in zip(poses, links)]
        return poses

    def _message(self, conn: Any, entry: Tuple[int, int, int]) -> Any:
        _, t, n = entry
        for k, (c, _, raw) in enumerate(self._reader.messages(connections=[conn], start=t, stop=t + 1)):
            if k == n:
                return self._deserialize(raw, c)
        raise self._error(f"topic {conn.topic}: message at bag time {t} ns not found")  # pragma: no cover

    def _image(self, msg: Any, topic: str, depth: bool) -> np.ndarray:
        enc = msg.encoding
        table = DEPTH_ENCODINGS if depth else COLOR_ENCODINGS
        where = f"topic {topic}, t={_seconds(_stamp_ns(msg)):.6f} s"
        if enc not in table:
            raise self._error(f"{where}: unknown {'depth' if depth else 'colour'} encoding {enc!r} (expected one of "
                              f"{sorted(table)})")
        w, h, step = int(msg.width), int(msg.height), int(msg.step)
        if (w, h) != (self.intrinsics.width, self.intrinsics.height):
            raise self._error(f"{where}: a {w}x{h} image, the camera is {self.intrinsics.width}x"
                              f"{self.intrinsics.height}")
        code, channels = (table[enc][0], 1) if depth else ("u1", table[enc][0])
        dtype = np.dtype((">" if msg.is_bigendian else "<") + code)
        row = w * channels * dtype.itemsize
        data = np.asarray(msg.data, dtype=np.uint8).reshape(-1)
        if step < row or data.size < step * h:
            raise self._error(f"{where}: image data of {data.size} bytes does not hold {h} rows of {w} {enc} pixels "
                              f"(step {step})")
        rows = data[: step * h].reshape(h, step)[:, :row]
        img = np.ascontiguousarray(rows).view(dtype).reshape((h, w) if channels == 1 else (h, w, channels))
        if depth:
            return img.astype(np.float32 if code == "f4" else np.uint16)
        rgb = img[..., :3]
        return np.ascontiguousarray(rgb[..., ::-1] if table[enc][1] else rgb)

    def __len__(self) -> int:
        return len(self._frames)

    def __getitem__(self, i: int) -> Frame:
        k = sequence_index(i, len(self), "BagSequence")
        if self._reader is None:
            raise ValueError(f"{self.path}: the bag is closed")
        d, c = self._frames[k]
        entry = self._depth[d]
        depth = self._image(self._message(self._depth_conn, entry), self.depth_topic, True)
        meta: Dict[str, Any] = {"bag": os.fspath(self.path), "depth_topic": self.depth_topic, "rgb_timestamp": None}
        rgb = None
        if c is not None:
            rgb = self._image(self._message(self._color_conn, self._color[c]), self.color_topic, False)
            meta["rgb_timestamp"] = _seconds(self._color[c][0])
        if self._joints[k] is not None:
            meta["joints"], meta["joint_names"] = self._joints[k].copy(), list(self.joint_names)
        pose = self._poses[k]
        return Frame(depth=depth, intrinsics=self.intrinsics, rgb=rgb, depth_scale=self.depth_scale,
                     timestamp=_seconds(entry[0]), T_base_camera=None if pose is None else pose.copy(), index=k,
                     meta=meta)

    def __iter__(self) -> Iterator[Frame]:
        for k in range(len(self)):
            yield self[k]

    def close(self) -> None:
        """Closes the bag (frames can no longer be read)."""
        reader, self._reader = getattr(self, "_reader", None), None  # None: construction failed early
        try:
            if reader is not None:
                reader.close()
        except Exception:  # pragma: no cover - closing a half-open reader
            pass

    def __enter__(self) -> "BagSequence":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    __del__ = close

    def __repr__(self) -> str:
        return (f"BagSequence({os.fspath(self.path)!r}, frames={len(self)}, depth={self.depth_topic}, "
                f"color={self.color_topic}, camera_info={self.camera_info_topic}, joints={self.joint_states_topic}, "
                f"tf={f'{self.base_frame}->{self.camera_frame}' if self.base_frame else None}, "
                f"intrinsics={self.intrinsics}, depth_scale={self.depth_scale})")


_NUMBER = re.compile(r"[-+]?(\d+(\.\d*)?|\.\d+)")


class ImageFolderSequence(ImageFileSequence):
    """RGB-D frames from a folder of images and a camera file::

        folder/
            camera.yaml        # a camera file (any layout of read_camera, distortion included),
                               #   or camera.json, intrinsics.yaml, ... (tum.CAMERA_FILE_NAMES)
            depth/*.png        # 16-bit depth, units of depth_scale m (0 = no measurement)
            rgb/*.png          # optional colour (or color/, colour/; PNG or JPEG), registered

    Timestamps are the file names when they are numbers (seconds, e.g. ``1700000000.033.png``;
    an integer above 1e15 is nanoseconds), else ``index / frame_rate``. Depth and colour are
    paired by timestamp (within ``max_time_difference``) when the names are numbers, else by
    equal names, else in name order when both folders hold the same number of images.

    Args:
        folder: the folder. intrinsics: overrides the camera file (an :class:`Intrinsics`,
            a preset name, a camera file). depth_scale: metres per depth unit, in (0, 1];
            default: the camera file's ``depth_scale``, else 0.001 (millimetres).
        frame_rate: frames per second when the names are not times.
        start, stride, limit: frame selection after pairing.

    Raises FileNotFoundError / ValueError (naming the file): no depth images, no camera file
    (or several), a malformed camera file, images that cannot be paired, a bad image.
    """

    def __init__(self, folder: PathLike, *, intrinsics: Any = None, depth_scale: Optional[float] = None,
                 max_time_difference: float = 0.02, frame_rate: float = 30.0, start: int = 0, stride: int = 1,
                 limit: Optional[int] = None) -> None:
        self.folder = Path(folder)
        if not is_image_folder(self.folder):
            raise FileNotFoundError(f"{self.folder}: no depth/ folder of PNG images")
        check_selection(start, stride, limit)
        check_number("frame_rate", frame_rate, "a positive number of frames per second", strict=True)
        self.intrinsics, self.depth_scale, self.camera_file = resolve_camera(self.folder, intrinsics, depth_scale,
                                                                             0.001, max_scale=1)
        depth = sorted(f for f in (self.folder / "depth").iterdir() if f.suffix.lower() == ".png")
        color_dir = next((self.folder / n for n in _COLOR_DIRS if (self.folder / n).is_dir()), None)
        color = [] if color_dir is None else sorted(
            f for f in color_dir.iterdir() if f.suffix.lower() in _IMAGE_SUFFIXES)
        d_t, c_t = self._times(depth, frame_rate), self._times(color, frame_rate)
        numeric = all(_NUMBER.fullmatch(f.stem) for f in depth + color)
        if numeric:
            od, oc = np.argsort(d_t, kind="stable"), np.argsort(c_t, kind="stable")
            depth, d_t = [depth[k] for k in od], d_t[od]
            color, c_t = [color[k] for k in oc], c_t[oc]
        pairs: List[Tuple[int, Optional[int]]] = [(k, None) for k in range(len(depth))]
        if color and numeric:
            pairs = [(int(a), int(b)) for a, b in pair_frames(d_t, c_t, float(max_time_difference), self.folder)]
        elif color and {f.stem for f in depth} == {f.stem for f in color}:
            by = {f.stem: k for k, f in enumerate(color)}
            pairs = [(k, by[f.stem]) for k, f in enumerate(depth)]
        elif color and len(depth) == len(color):
            pairs = [(k, k) for k in range(len(depth))]
        elif color:
            raise ValueError(f"{self.folder}: cannot pair {len(depth)} depth images with {len(color)} colour "
                             f"images in {color_dir.name}/ (name them by timestamp or with equal names)")
        self.dropped_depth_frames = len(depth) - len(pairs)
        pairs = pairs[start::stride][:limit]
        self.depth_files = [depth[a] for a, _ in pairs]
        self.rgb_files = [color[b] for _, b in pairs] if color else None
        self.timestamps = np.array([d_t[a] for a, _ in pairs], dtype=np.float64)

    @staticmethod
    def _times(files: List[Path], frame_rate: float) -> np.ndarray:
        if files and all(_NUMBER.fullmatch(f.stem) for f in files):
            return np.array([int(f.stem) * 1e-9 if "." not in f.stem and abs(int(f.stem)) > 10**15 else float(f.stem)
                             for f in files])
        return np.arange(len(files), dtype=np.float64) / frame_rate

    def __repr__(self) -> str:
        return (f"ImageFolderSequence({os.fspath(self.folder)!r}, frames={len(self)}, rgb={self.rgb_files is not None},"
                f" intrinsics={self.intrinsics}, depth_scale={self.depth_scale})")


def write_image_folder(folder: PathLike, frames: Sequence[Frame], depth_scale: Optional[float] = None,
                       **options: Any) -> str:
    """Writes frames as the folder :class:`ImageFolderSequence` reads (``depth/`` and ``rgb/`` PNGs
    named by timestamp, ``camera.json``; ``groundtruth.txt``, unread): :func:`~scanalign.datasets.tum.
    write_tum_sequence` without image lists, depth in units of ``depth_scale`` m (default: frame 0's)."""
    if not (frames := list(frames)):
        raise ValueError(f"{folder}: no frames to write")
    scale = frames[0].depth_scale if depth_scale is None else depth_scale
    return write_tum_sequence(folder, frames, depth_scale=scale, lists=False, **options)


def write_bag(path: PathLike, frames: Sequence[Frame]) -> str:
    """Writes frames as a ROS bag that :class:`BagSequence` reads back (needs ``rosbags``): a ROS 1 file when ``path``
    ends in ``.bag``, else a ROS 2 bag folder. Topics: ``/camera/depth/image_raw`` (16UC1 in units of frame 0's
    ``depth_scale``, stated as RealSense's ``Depth Units`` option), ``/camera/color/image_raw`` (rgb8, when the frames
    have colour), ``/camera/depth/camera_info``, ``/tf`` (``base_link`` -> ``camera``: ``T_base_camera``, when known)
    and ``/joint_states`` (``meta["joints"]``, when known), all stamped with the frames' timestamps (s). FileExistsError
    when ``path`` exists; ValueError for no frames or a depth beyond 16 bits."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    path, frames = Path(path), list(frames)
    if path.exists():
        raise FileExistsError(f"{path}: exists; write the bag to a new path")
    if not frames:
        raise ValueError(f"{path}: no frames to write")
    path.parent.mkdir(parents=True, exist_ok=True)
    ros1, K, scale, cam = path.suffix.lower() == ".bag", frames[0].intrinsics, float(frames[0].depth_scale), "camera"
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:  # Noetic's store lacks tf2_msgs
        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", _TF))
    ty, ser = store.types, store.serialize_ros1 if ros1 else store.serialize_cdr
    names = _UR_JOINTS if str(frames[0].meta.get("robot", "")).startswith("ur") else [f"joint_{k}" for k in range(1, 7)]

    def header(ns: int, frame_id: str) -> Any:
        return ty["std_msgs/msg/Header"](*(0,) * ros1, ty["builtin_interfaces/msg/Time"](*divmod(ns, 10**9)), frame_id)

    def image(ns: int, a: np.ndarray, encoding: str) -> Any:
        data = np.ascontiguousarray(a).view(np.uint8).reshape(-1)
        return ty[_IMAGE](header(ns, cam), a.shape[0], a.shape[1], encoding, 0, data.size // a.shape[0], data)

    with (Writer1(path) if ros1 else Writer2(path, version=9)) as w:
        conns: Dict[str, Any] = {}

        def put(topic: str, ns: int, msg: Any) -> None:
            if topic not in conns:  # a topic only when it has messages
                conns[topic] = w.add_connection(topic, msg.__msgtype__, typestore=store)
            w.write(conns[topic], ns, ser(msg, msg.__msgtype__))

        put("/camera/depth/option/Depth Units/value", 0, ty[_FLOAT32](scale))
        info = (K.height, K.width, "plumb_bob", np.array(K.distortion, float), K.K.reshape(-1), np.eye(3).reshape(-1),
                np.c_[K.K, np.zeros(3)].reshape(-1), 0, 0, ty["sensor_msgs/msg/RegionOfInterest"](0, 0, 0, 0, False))
        for k, f in enumerate(frames):
            ns = int(round(float(f.timestamp) * 1e9))
            put("/camera/depth/image_raw", ns, image(ns, depth_units(f, scale, f"frame {k}").astype("<u2"), "16UC1"))
            if f.rgb is not None:
                put("/camera/color/image_raw", ns, image(ns, np.asarray(f.rgb, np.uint8), "rgb8"))
            put("/camera/depth/camera_info", ns, ty[_INFO](header(ns, cam), *info))
            if f.T_base_camera is not None:
                r = Trajectory(np.zeros(1), np.asarray(f.T_base_camera)[None]).to_tum_rows()[0, 1:]
                tr = ty["geometry_msgs/msg/Transform"](ty["geometry_msgs/msg/Vector3"](*r[:3]),
                                                       ty["geometry_msgs/msg/Quaternion"](*r[3:]))
                put("/tf", ns, ty[_TF]([ty["geometry_msgs/msg/TransformStamped"](header(ns, "base_link"), cam, tr)]))
            if (q := f.meta.get("joints")) is not None:
                none = np.zeros(0)  # velocity, effort
                put("/joint_states", ns, ty[_JOINTS](header(ns, ""), names, np.asarray(q, float), none, none))
    return os.fspath(path)

"""Frame sources (scanalign.datasets.sources): ROS 1 / ROS 2 bags written with rosbags' own writers
from the synthetic scanner, PNG folders with ROS / OpenCV camera YAML, lens distortion in
the back-projection (against OpenCV), and malformed recordings."""

import dataclasses
import json
import shutil
import sys

import numpy as np
import pytest

from scanalign import reconstruction, synthetic
from scanalign.reconstruction import camera
from scanalign import datasets
from scanalign.datasets import sources
from scanalign.datasets import tum
from scanalign.reconstruction.camera import Intrinsics, intrinsics_from_dict, read_camera
from scanalign.pipelines.reconstruct import reconstruct

rosbags = pytest.importorskip("rosbags")
from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import StoragePlugin, Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

UR_ALPHABETICAL = ["elbow_joint", "shoulder_lift_joint", "shoulder_pan_joint", "wrist_1_joint", "wrist_2_joint",
                   "wrist_3_joint"]  # the order the UR ROS drivers publish
UR_KINEMATIC = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
                "wrist_3_joint"]
DISTORTION = (-0.28, 0.09, 1.2e-3, -6e-4, -0.015)  # a wide-angle webcam's Brown-Conrady coefficients


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A 6-frame synthetic UR5 scan (320x240) stored as a TUM folder in millimetres (what the
    bags and image folders below hold too), its frames as read back, and the scan's joints."""
    scan = synthetic.SyntheticConfig(n_frames=6, resolution_scale=0.5, noise="sr300", seed=3).build()
    folder = tmp_path_factory.mktemp("rec") / "tum"
    # Capture times since the epoch, as a recorder's header stamps are.
    tum.write_tum_sequence(folder, [dataclasses.replace(f, timestamp=1.7e9 + f.timestamp) for f in scan.frames],
                           depth_scale=0.001)
    frames = list(tum.TumSequence(folder))
    return {"scan": scan, "tum": folder, "frames": frames, "joints": np.stack([f.meta["joints"] for f in scan.frames]),
            "tum_base": _reconstruct(tum.TumSequence(folder)),
            "tum_camera": _reconstruct(tum.TumSequence(folder), model_frame="camera")}


#: The eye-in-hand paper's values (no depth filter, 5 mm normals, no box): the formats are compared on a 6-frame loop,
#: 60 deg a step, which these register and the library's defaults (made for real scan rates) do not.
PAPER = dict(filter_depth=False, normal_radius=0.005, icp=dict(box=None))
PAPER_FLAGS = ["--no-depth-filter", "--set", "frame_to_model.normal_radius=0.005", "--set", "frame_to_model.icp.box=null"]


def _reconstruct(frames, **kw):
    return reconstruct(frames, progress=False, pixel_stride=2, **PAPER, **kw)


# -- writing bags ------------------------------------------------------------------------------


def _ns(t):
    return int(round(t * 1e9))


def _stamp(store, t):
    Time = store.types["builtin_interfaces/msg/Time"]
    return Time(sec=_ns(t) // 10**9, nanosec=_ns(t) % 10**9)


def _header(store, ros1, t, frame_id):
    H = store.types["std_msgs/msg/Header"]
    return H(seq=0, stamp=_stamp(store, t), frame_id=frame_id) if ros1 else H(stamp=_stamp(store, t), frame_id=frame_id)


def _image(store, ros1, t, frame_id, array, encoding):
    a = np.ascontiguousarray(array)
    h, w = a.shape[:2]
    data = a.view(np.uint8).reshape(-1)
    return store.types["sensor_msgs/msg/Image"](header=_header(store, ros1, t, frame_id), height=h, width=w,
                                                encoding=encoding, is_bigendian=0, step=data.size // h, data=data)


def _camera_info(store, ros1, t, frame_id, K, distortion=(0.0,) * 5, model="plumb_bob"):
    T = store.types
    roi = T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
    P = np.zeros(12)
    P[[0, 2, 5, 6, 10]] = K.fx, K.cx, K.fy, K.cy, 1.0
    f = dict(D=np.array(distortion, dtype=np.float64), K=K.K.reshape(-1), R=np.eye(3).reshape(-1), P=P)
    f = f if ros1 else {k.lower(): v for k, v in f.items()}
    return T["sensor_msgs/msg/CameraInfo"](header=_header(store, ros1, t, frame_id), height=K.height, width=K.width,
                                           distortion_model=model, binning_x=0, binning_y=0, roi=roi, **f)


def _tf(store, ros1, t, parent, child, T_parent_child):
    from scanalign.evaluation.trajectory import quaternion_from_matrix

    ty = store.types
    q = quaternion_from_matrix(T_parent_child[:3, :3])
    tr = ty["geometry_msgs/msg/Transform"](translation=ty["geometry_msgs/msg/Vector3"](*T_parent_child[:3, 3]),
                                           rotation=ty["geometry_msgs/msg/Quaternion"](*q))
    ts = ty["geometry_msgs/msg/TransformStamped"](header=_header(store, ros1, t, parent), child_frame_id=child,
                                                  transform=tr)
    return ty["tf2_msgs/msg/TFMessage"](transforms=[ts])


def _store(ros1):
    """rosbags' typestore of ROS 1 Noetic / ROS 2 Humble with tf2_msgs/TFMessage added."""
    from rosbags.typesys import get_types_from_msg

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    return store


def write_bag(path, frames, *, ros1=True, storage=None, joints=None, depth_encoding="16UC1", color_encoding="rgb8",
              camera_info=True, distortion=(0.0,) * 5, depth=True, tf=True, extra=None):
    """Writes `frames` (uint16 mm depth) as a RealSense-style bag: aligned depth + colour +
    camera_info, /joint_states (UR driver order), /tf (base_link -> tool0 moving, tool0 ->
    camera_color_optical_frame static)."""
    store = _store(ros1)
    ser = store.serialize_ros1 if ros1 else store.serialize_cdr
    W = Writer1(path) if ros1 else Writer2(path, version=9, storage_plugin=storage or StoragePlugin.SQLITE3)
    cam = "camera_color_optical_frame"
    K = frames[0].intrinsics
    T_tool_cam = np.eye(4)
    T_tool_cam[:3, 3] = (0.01, -0.02, 0.05)
    with W as w:
        def conn(topic, typ):
            return w.add_connection(topic, typ, typestore=store)

        topics = {}
        if depth:
            topics["depth"] = conn("/camera/aligned_depth_to_color/image_raw", "sensor_msgs/msg/Image")
        topics["color"] = conn("/camera/color/image_raw", "sensor_msgs/msg/Image")
        if camera_info:
            topics["info"] = conn("/camera/aligned_depth_to_color/camera_info", "sensor_msgs/msg/CameraInfo")
            # A colour camera_info of another size, which must not be taken for the depth's.
            topics["info_big"] = conn("/camera/color/camera_info", "sensor_msgs/msg/CameraInfo")
        if joints is not None:
            topics["joints"] = conn("/joint_states", "sensor_msgs/msg/JointState")
        if tf:
            topics["tf"] = conn("/tf", "tf2_msgs/msg/TFMessage")
            topics["tf_static"] = conn("/tf_static", "tf2_msgs/msg/TFMessage")
            w.write(topics["tf_static"], _ns(frames[0].timestamp) - 1000,
                    ser(_tf(store, ros1, frames[0].timestamp, "tool0", cam, T_tool_cam), "tf2_msgs/msg/TFMessage"))
        for k, f in enumerate(frames):
            t, bag_t = f.timestamp, _ns(f.timestamp) + 5_000_000  # received 5 ms after capture
            if camera_info:
                w.write(topics["info"], bag_t, ser(_camera_info(store, ros1, t, cam, K, distortion),
                                                   "sensor_msgs/msg/CameraInfo"))
                w.write(topics["info_big"], bag_t, ser(_camera_info(store, ros1, t, cam, K.scaled(2.0)),
                                                       "sensor_msgs/msg/CameraInfo"))
            if depth:
                d = f.depth if depth_encoding in ("16UC1", "mono16") else (f.depth * 0.001).astype(np.float32)
                w.write(topics["depth"], bag_t, ser(_image(store, ros1, t, cam, d, depth_encoding),
                                                    "sensor_msgs/msg/Image"))
            rgb = f.rgb[..., ::-1] if color_encoding.startswith("bgr") else f.rgb
            if color_encoding.endswith("a8"):
                rgb = np.concatenate([rgb, np.full(rgb.shape[:2] + (1,), 255, np.uint8)], axis=2)
            # Colour captured 3 ms after depth: paired by header time.
            w.write(topics["color"], bag_t + 1, ser(_image(store, ros1, t + 0.003, cam, rgb, color_encoding),
                                                    "sensor_msgs/msg/Image"))
            if joints is not None:
                JS = store.types["sensor_msgs/msg/JointState"]
                q = joints[k][[UR_KINEMATIC.index(n) for n in UR_ALPHABETICAL]]
                w.write(topics["joints"], bag_t, ser(JS(header=_header(store, ros1, t, ""), name=UR_ALPHABETICAL,
                                                        position=q, velocity=np.zeros(0), effort=np.zeros(0)),
                                                     "sensor_msgs/msg/JointState"))
            if tf and f.T_base_camera is not None:
                T_base_tool = f.T_base_camera @ np.linalg.inv(T_tool_cam)
                w.write(topics["tf"], bag_t, ser(_tf(store, ros1, t, "base_link", "tool0", T_base_tool),
                                                 "tf2_msgs/msg/TFMessage"))
        if extra:
            extra(w, store, ser)
    return path


# -- bags --------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["ros1", "ros2_sqlite", "ros2_mcap"])
def test_bag_reconstructs_like_the_tum_folder(recording, tmp_path, kind):
    frames, joints = recording["frames"], recording["joints"]
    ros1 = kind == "ros1"
    path = tmp_path / ("scan.bag" if ros1 else "scan")
    storage = StoragePlugin.MCAP if kind == "ros2_mcap" else StoragePlugin.SQLITE3
    write_bag(path, frames, ros1=ros1, storage=storage, joints=joints)
    if kind == "ros2_mcap":  # also the bare storage file
        path = next(path.glob("*.mcap"))
    seq = datasets.open_source(path)
    assert isinstance(seq, sources.BagSequence) and len(seq) == len(frames)
    assert seq.depth_topic == "/camera/aligned_depth_to_color/image_raw"
    assert seq.color_topic == "/camera/color/image_raw"
    assert seq.camera_info_topic == "/camera/aligned_depth_to_color/camera_info"
    assert seq.intrinsics == frames[0].intrinsics and seq.depth_scale == 0.001
    assert seq.joint_names == UR_KINEMATIC and seq.base_frame == "base_link"
    for f, g, q in zip(frames, seq, joints):
        assert g.depth.dtype == np.uint16 and np.array_equal(g.depth, f.depth)
        assert np.array_equal(g.rgb, f.rgb)
        assert g.timestamp == pytest.approx(f.timestamp, abs=1e-9)
        assert np.array_equal(g.meta["joints"], q)  # joints read back equal, in kinematic order
        np.testing.assert_allclose(g.T_base_camera, f.T_base_camera, atol=1e-12)

    a, b = recording["tum_base"], _reconstruct(seq)
    assert [r.status for r in a.records] == [r.status for r in b.records] and all(r.merged for r in b.records)
    np.testing.assert_allclose(b.estimate.poses, a.estimate.poses, atol=1e-9)
    assert len(a.model) == len(b.model)
    np.testing.assert_allclose(b.model.points, a.model.points, atol=1e-6)
    assert b.joints is not None and np.array_equal(b.joints, joints)
    seq.close()
    with pytest.raises(ValueError, match="closed"):
        seq[0]


def test_bag_encodings_float_depth_bgr_and_distortion(recording, tmp_path):
    frames = recording["frames"][:2]
    path = write_bag(tmp_path / "f.bag", frames, depth_encoding="32FC1", color_encoding="bgra8", tf=False,
                     distortion=DISTORTION)
    with sources.BagSequence(path, joint_states_topic=False) as seq:
        assert seq.intrinsics.distortion == DISTORTION
        g = seq[0]
        assert g.depth.dtype == np.float32
        np.testing.assert_array_equal(g.depth, (frames[0].depth * 0.001).astype(np.float32))
        assert np.array_equal(g.rgb, frames[0].rgb) and g.T_base_camera is None and "joints" not in g.meta
        assert seq[-1].index == 1


def test_bag_topic_selection_and_pairing(recording, tmp_path):
    frames = recording["frames"][:3]
    path = write_bag(tmp_path / "s.bag", frames, tf=False)
    with sources.BagSequence(path, color_topic=False, start=1) as seq:  # depth only, from the 2nd frame
        assert seq.color_topic is None and len(seq) == 2 and seq[0].rgb is None
        assert seq[0].timestamp == pytest.approx(frames[1].timestamp, abs=1e-9)
    # Colour 3 ms after depth: outside a 1 ms pairing bound no frame remains.
    with pytest.raises(ValueError, match="s.bag.*no depth image.*colour"):
        sources.BagSequence(path, max_time_difference=0.001)
    with pytest.raises(ValueError, match=r"s\.bag.*depth topic '/camera/color/image_raw' has encoding 'rgb8'"):
        sources.BagSequence(path, depth_topic="/camera/color/image_raw")
    with pytest.raises(ValueError, match=r"s\.bag.*'/nope': no such topic"):
        sources.BagSequence(path, depth_topic="/nope")
    with pytest.raises(ValueError, match=r"s\.bag.*is a sensor_msgs/msg/CameraInfo"):
        sources.BagSequence(path, color_topic="/camera/color/camera_info")
    # Explicit intrinsics replace camera_info (the preset's size must match the images).
    with pytest.raises(ValueError, match="s.bag.*320x240.*640x480"):
        sources.BagSequence(path, intrinsics="sr300")


def test_realsense_viewer_layout(recording, tmp_path):
    """A realsense-viewer recording: per-sensor topics, depth units as an option topic,
    colour from another sensor (not registered to depth: left out)."""
    f = recording["frames"][0]
    store = _store(True)
    ser = store.serialize_ros1
    path = tmp_path / "rs.bag"
    with Writer1(path) as w:
        d = w.add_connection("/device_0/sensor_0/Depth_0/image/data", "sensor_msgs/msg/Image", typestore=store)
        i = w.add_connection("/device_0/sensor_0/Depth_0/info/camera_info", "sensor_msgs/msg/CameraInfo",
                             typestore=store)
        ci = w.add_connection("/device_0/sensor_1/Color_0/info/camera_info", "sensor_msgs/msg/CameraInfo",
                              typestore=store)
        c = w.add_connection("/device_0/sensor_1/Color_0/image/data", "sensor_msgs/msg/Image", typestore=store)
        u = w.add_connection("/device_0/sensor_0/option/Depth Units/value", "std_msgs/msg/Float32", typestore=store)
        w.write(u, 1, ser(store.types["std_msgs/msg/Float32"](data=np.float32(1e-4)), "std_msgs/msg/Float32"))
        t = f.timestamp
        w.write(ci, 2, ser(_camera_info(store, True, t, "1", f.intrinsics, (0.05, 0.0, 0.0, 0.0, 0.0),
                                        "Inverse Brown Conrady"), "sensor_msgs/msg/CameraInfo"))
        w.write(i, 2, ser(_camera_info(store, True, t, "0", f.intrinsics, model="Brown Conrady"),
                          "sensor_msgs/msg/CameraInfo"))
        w.write(d, 3, ser(_image(store, True, t, "0", f.depth, "mono16"), "sensor_msgs/msg/Image"))
        w.write(c, 3, ser(_image(store, True, t, "1", f.rgb, "rgb8"), "sensor_msgs/msg/Image"))
    seq = datasets.open_source(path)
    assert seq.depth_topic == "/device_0/sensor_0/Depth_0/image/data"
    assert seq.camera_info_topic == "/device_0/sensor_0/Depth_0/info/camera_info"
    assert seq.depth_scale == 1e-4 and seq.color_topic is None
    assert any("Color_0" in n for n in seq.notes) and seq[0].rgb is None
    assert np.array_equal(seq[0].depth, f.depth) and seq.intrinsics == f.intrinsics
    # Named anyway, the colour stream is used (same size).
    assert np.array_equal(datasets.open_source(path, color_topic="/device_0/sensor_1/Color_0/image/data")[0].rgb, f.rgb)


def test_malformed_bags_name_the_file(recording, tmp_path):
    frames = recording["frames"][:2]
    no_depth = write_bag(tmp_path / "nodepth.bag", frames, depth=False, tf=False)
    with pytest.raises(ValueError, match=r"nodepth\.bag: no depth images.*rgb8"):
        datasets.open_source(no_depth)
    no_info = write_bag(tmp_path / "noinfo", frames, ros1=False, camera_info=False, tf=False)
    with pytest.raises(ValueError, match=r"noinfo: no sensor_msgs/CameraInfo.*intrinsics="):
        datasets.open_source(no_info)
    seq = datasets.open_source(no_info, intrinsics=frames[0].intrinsics)  # ... which intrinsics= mends
    assert np.array_equal(seq[1].depth, frames[1].depth)

    def odd_encoding(w, store, ser):
        c = w.add_connection("/camera/ir/image_raw", "sensor_msgs/msg/Image", typestore=store)
        w.write(c, 10**9, ser(_image(store, True, 1.0, "ir", np.zeros((4, 4), np.uint8), "8UC1"),
                              "sensor_msgs/msg/Image"))

    odd = write_bag(tmp_path / "odd.bag", frames, tf=False, extra=odd_encoding)
    with pytest.raises(ValueError, match=r"odd\.bag.*encoding '8UC1'.*depth must be one of"):
        sources.BagSequence(odd, depth_topic="/camera/ir/image_raw")
    garbage = tmp_path / "garbage.bag"
    garbage.write_bytes(b"#ROSBAG V2.0\n" + b"\x00" * 64)
    with pytest.raises(ValueError, match=r"garbage\.bag: not a readable ROS bag"):
        datasets.open_source(garbage)


def test_unsupported_distortion_model_in_a_bag(recording, tmp_path):
    frames = recording["frames"][:1]
    store = _store(False)
    path = tmp_path / "fish"
    with Writer2(path, version=9) as w:
        c = w.add_connection("/depth/image", "sensor_msgs/msg/Image", typestore=store)
        i = w.add_connection("/depth/camera_info", "sensor_msgs/msg/CameraInfo", typestore=store)
        w.write(i, 1, store.serialize_cdr(_camera_info(store, False, 1.0, "cam", frames[0].intrinsics,
                                                       (0.1, 0.01, 0.0, 0.0, 0.0), "equidistant"),
                                          "sensor_msgs/msg/CameraInfo"))
        w.write(c, 2, store.serialize_cdr(_image(store, False, 1.0, "cam", frames[0].depth, "16UC1"),
                                          "sensor_msgs/msg/Image"))
    with pytest.raises(ValueError, match=r"fish: camera_info topic /depth/camera_info: distortion model "
                                         r"'equidistant' is not supported"):
        datasets.open_source(path)


def test_missing_rosbags_says_how_to_install(monkeypatch, tmp_path, recording):
    path = write_bag(tmp_path / "x.bag", recording["frames"][:1], tf=False)
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)
    with pytest.raises(ImportError, match=r"pip install 'scanalign\[ros\]'"):
        datasets.open_source(path)


# -- image folders and camera files -------------------------------------------------------------

ROS_YAML = """image_width: {w}
image_height: {h}
camera_name: depth
camera_matrix:
  rows: 3
  cols: 3
  data: [{fx}, 0, {cx}, 0, {fy}, {cy}, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [{d}]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [{fx}, 0, {cx}, 0, 0, {fy}, {cy}, 0, 0, 0, 1, 0]
"""

OPENCV_YAML = """%YAML:1.0
---
calibration_time: "Fri Nov 27 13:00:00 2026"
image_width: {w}
image_height: {h}
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ {fx}, 0., {cx}, 0., {fy}, {cy}, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ {d} ]
avg_reprojection_error: 2.1e-01
"""


def _yaml(template, K, distortion=(0.0,) * 5):
    return template.format(w=K.width, h=K.height, fx=repr(K.fx), fy=repr(K.fy), cx=repr(K.cx), cy=repr(K.cy),
                           d=", ".join(repr(float(x)) for x in distortion))


@pytest.mark.parametrize("flavour", ["ros", "opencv"])
def test_camera_yaml_flavours(tmp_path, flavour):
    K = Intrinsics(640, 480, 615.25, 614.75, 321.5, 238.25)
    path = tmp_path / "cam.yaml"
    path.write_text(_yaml(ROS_YAML if flavour == "ros" else OPENCV_YAML, K, DISTORTION))
    intr, scale = read_camera(path)
    assert intr == Intrinsics(640, 480, 615.25, 614.75, 321.5, 238.25, DISTORTION) and scale is None
    assert read_camera(path)[0] == intr
    d = camera.read_camera_file(path)
    if flavour == "opencv":
        assert d["camera_matrix"].shape == (3, 3) and d["avg_reprojection_error"] == 0.21
    # A distorted camera round-trips through scanalign's own camera.json (write_tum_sequence).
    assert intrinsics_from_dict(json.loads(json.dumps(intr.to_dict()))) == intr
    assert "distortion" not in K.to_dict() and repr(K).endswith("cy=238.25)")


def test_malformed_camera_yaml_names_the_file(tmp_path):
    K = Intrinsics(64, 48, 50.0, 50.0, 31.5, 23.5)
    cases = {
        "short.yaml": _yaml(OPENCV_YAML, K).replace("data: [ 50.0, 0., 31.5, 0., 50.0, 23.5, 0., 0., 1. ]",
                                                    "data: [ 50.0, 0., 31.5 ]"),
        "model.yaml": _yaml(ROS_YAML, K, DISTORTION).replace("plumb_bob", "equidistant"),
        "skew.yaml": _yaml(ROS_YAML, K).replace("data: [50.0, 0, 31.5", "data: [50.0, 0.5, 31.5"),
        "nosize.yaml": _yaml(ROS_YAML, K).replace("image_width: 64\n", ""),
        "eight.yaml": _yaml(ROS_YAML, K).replace("cols: 5\n  data: [0.0, 0.0, 0.0, 0.0, 0.0]",
                                                 "cols: 8\n  data: [0.1, 0, 0, 0, 0, 0.2, 0, 0]"),
        "text.yaml": "camera_matrix: !!opencv-matrix\n  rows: 3\n",
    }
    messages = {"short.yaml": "opencv-matrix", "model.yaml": "equidistant", "skew.yaml": "no skew",
                "nosize.yaml": "image size", "eight.yaml": "beyond k1 k2 p1 p2 k3", "text.yaml": "opencv-matrix"}
    for name, text in cases.items():
        (tmp_path / name).write_text(text)
        with pytest.raises(ValueError, match=rf"{name}.*{messages[name]}"):
            read_camera(tmp_path / name)
    with pytest.raises(ValueError, match="distortion must be 5 finite"):
        Intrinsics(64, 48, 50.0, 50.0, 31.5, 23.5, (0.1, 0.0, float("nan"), 0.0, 0.0))


def _image_folder(recording, folder, camera_text, names="time"):
    (folder / "depth").mkdir(parents=True)
    (folder / "color").mkdir()
    src = recording["tum"]
    for k, (d, c) in enumerate(zip(sorted((src / "depth").iterdir()), sorted((src / "rgb").iterdir()))):
        name = d.name if names == "time" else f"frame{k:04d}.png"
        shutil.copy(d, folder / "depth" / name)
        shutil.copy(c, folder / "color" / (c.name if names == "time" else name))
    (folder / "camera.yaml").write_text(camera_text)
    return folder


@pytest.mark.parametrize("flavour,names", [("ros", "time"), ("opencv", "index")])
def test_png_folder_reconstructs_like_the_tum_folder(recording, tmp_path, flavour, names):
    frames = recording["frames"]
    K = frames[0].intrinsics
    folder = _image_folder(recording, tmp_path / "pngs", _yaml(ROS_YAML if flavour == "ros" else OPENCV_YAML, K),
                           names)
    seq = datasets.open_source(folder)
    assert isinstance(seq, sources.ImageFolderSequence) and len(seq) == len(frames)
    assert seq.intrinsics == K and seq.depth_scale == 0.001
    for f, g in zip(frames, seq):
        assert np.array_equal(g.depth, f.depth) and np.array_equal(g.rgb, f.rgb)
        if names == "time":
            assert g.timestamp == pytest.approx(f.timestamp, abs=1e-9)
    a, b = recording["tum_camera"], _reconstruct(seq)
    np.testing.assert_allclose(b.estimate.poses, a.estimate.poses, atol=1e-9)
    assert len(a.model) == len(b.model)


def test_png_folder_errors(recording, tmp_path):
    K = recording["frames"][0].intrinsics
    folder = _image_folder(recording, tmp_path / "p", "width: 10\n")
    with pytest.raises(ValueError, match=r"camera\.yaml.*missing keys"):
        datasets.open_source(folder)
    (folder / "camera.yaml").write_text(_yaml(ROS_YAML, K.scaled(0.5)))
    with pytest.raises(ValueError, match=r"depth/.*\.png.*160x120"):
        datasets.open_source(folder)[0]
    (folder / "camera.yaml").unlink()
    with pytest.raises(ValueError, match="no camera file"):
        datasets.open_source(folder)
    assert len(datasets.open_source(folder, intrinsics=K, stride=2)) == 3
    with pytest.raises(ValueError, match="not a recording"):
        datasets.open_source(tmp_path)


# -- the command line --------------------------------------------------------------------------


def test_cli_reconstructs_a_bag_and_a_png_folder(recording, tmp_path):
    from scanalign import cli

    bag = write_bag(tmp_path / "c.bag", recording["frames"], joints=recording["joints"])
    assert cli.main(["reconstruct", str(bag), "--out", str(tmp_path / "out"), "--quiet", "--no-plots",
                     "--pixel-stride", "2", *PAPER_FLAGS]) == 0
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["summary"]["frames"] == 6 and report["summary"]["merged"] == 6
    assert (tmp_path / "out" / "joints.csv").is_file() and (tmp_path / "out" / "reference.txt").is_file()
    folder = _image_folder(recording, tmp_path / "pngs", _yaml(ROS_YAML, recording["frames"][0].intrinsics))
    assert cli.main(["reconstruct", str(folder), "--out", str(tmp_path / "out2"), "--quiet", "--no-plots",
                     "--limit", "3", "--pixel-stride", "2", *PAPER_FLAGS]) == 0
    assert (tmp_path / "out2" / "model.ply").is_file()


# -- lens distortion in the back-projection ----------------------------------------------------


def test_rays_equal_opencv_undistort_points():
    cv2 = pytest.importorskip("cv2")
    K = Intrinsics(320, 240, 260.5, 259.25, 161.3, 118.7, DISTORTION)
    rays = reconstruction.undistorted_rays(K)
    assert rays.shape == (240, 320, 2) and np.all(np.isfinite(rays))
    u, v = np.meshgrid(np.arange(320, dtype=np.float64), np.arange(240, dtype=np.float64))
    pix = np.stack([u, v], axis=-1).reshape(-1, 1, 2)
    ref = cv2.undistortPointsIter(pix, K.K, np.array(DISTORTION), None, None,
                                  (cv2.TERM_CRITERIA_COUNT, 100, 0.0)).reshape(240, 320, 2)
    assert np.abs(rays - ref).max() <= 1e-12
    # ... and they re-project onto their pixels through OpenCV's distortion model.
    obj = np.concatenate([rays.reshape(-1, 2), np.ones((rays.size // 2, 1))], axis=1)
    back, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), K.K, np.array(DISTORTION))
    assert np.abs(back.reshape(-1, 2) - pix.reshape(-1, 2)).max() < 1e-6
    # Pinhole rays for zero distortion.
    P = Intrinsics(320, 240, 260.5, 259.25, 161.3, 118.7)
    r0 = reconstruction.undistorted_rays(P)
    np.testing.assert_allclose(r0[..., 0], (u - P.cx) / P.fx, rtol=0, atol=1e-15)
    # OpenCV's default 5 iterations are not converged at the corners; ours are.
    five = cv2.undistortPoints(pix, K.K, np.array(DISTORTION)).reshape(240, 320, 2)
    assert np.abs(five - rays).max() > 1e-6


def test_depth_to_cloud_with_distortion():
    K = Intrinsics(320, 240, 260.5, 259.25, 161.3, 118.7, DISTORTION)
    rng = np.random.default_rng(1)
    depth = rng.uniform(0.3, 1.5, (240, 320)).astype(np.float32)
    depth[5, 7] = 0.0  # invalid
    rgb = rng.integers(0, 255, (240, 320, 3), dtype=np.uint8)
    p, c, pix = reconstruction.depth_to_cloud(depth, K, rgb=rgb, return_pixels=True)
    rays = reconstruction.undistorted_rays(K).reshape(-1, 2)
    z = depth.reshape(-1)[pix].astype(np.float64)
    expect = np.stack([z * rays[pix, 0], z * rays[pix, 1], z], axis=1).astype(np.float32)
    assert pix.size == 320 * 240 - 1 and np.array_equal(p, expect)
    assert np.array_equal(c, rgb.reshape(-1, 3)[pix])
    # uint16 with a stride: the same rays.
    mm = np.rint(depth * 1000).astype(np.uint16)
    p2, _, pix2 = reconstruction.depth_to_cloud(mm, K, stride=3, return_pixels=True)
    z2 = mm.reshape(-1)[pix2] * 0.001
    np.testing.assert_array_equal(p2[:, 0], (z2 * rays[pix2, 0]).astype(np.float32))


def test_zero_distortion_is_bit_identical_to_the_pinhole_formula():
    K = Intrinsics(64, 48, 50.5, 51.25, 31.7, 23.2)
    assert K == Intrinsics(64, 48, 50.5, 51.25, 31.7, 23.2, (0, 0, 0, 0, 0)) and not K.has_distortion
    rng = np.random.default_rng(2)
    depth = rng.integers(100, 2000, (48, 64)).astype(np.uint16)
    p, _, pix = reconstruction.depth_to_cloud(depth, K, return_pixels=True)
    u, v = pix % 64, pix // 64
    z = depth.reshape(-1)[pix] * 0.001
    expect = np.stack([z * (u - K.cx) * (1.0 / K.fx), z * (v - K.cy) * (1.0 / K.fy), z], axis=1).astype(np.float32)
    assert np.array_equal(p, expect)


def test_scaled_and_tum_round_trip_keep_distortion(recording, tmp_path):
    K = Intrinsics(320, 240, 260.5, 259.25, 161.3, 118.7, DISTORTION)
    assert K.scaled(0.5).distortion == DISTORTION
    f = recording["frames"][0]
    g = dataclasses.replace(f, intrinsics=Intrinsics(**{**f.intrinsics.to_dict(), "distortion": DISTORTION}))
    tum.write_tum_sequence(tmp_path / "d", [g])
    assert tum.TumSequence(tmp_path / "d").intrinsics.distortion == DISTORTION

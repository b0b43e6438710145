"""Every C++-bound class pickles (issue 18: settings, results and models cross process
boundaries) or refuses with a TypeError saying what to send instead.

Discovery walks scanalign._core, so a new class without pickle support fails here. Round
trips compare every public property (recursively) for protocols 2 and 5; settings have every
writable field changed first, so a field missing from the state is caught; results come from
real runs. A spawn-context process pool runs ICP on objects shipped to it."""

from __future__ import annotations

import concurrent.futures
import enum
import functools
import inspect
import math
import multiprocessing
import os
import pickle
import sys

import numpy as np
import pytest

from scanalign import _core, io, pose
from scanalign.pose import model_views as cad
from scanalign.data import parts
from scanalign import grasp as G
from scanalign import kinematics
from scanalign.evaluation.trajectory import Trajectory

PROTOCOLS = (2, 5)
# One OpenMP thread for the runs here: on a shared machine with more busy threads than cores,
# OpenMP's spinning workers made this file 50x slower.
THREADS = 1

# Engines whose state is not worth a format: pickling raises TypeError saying what to send.
REFUSED = {
    "evaluation.MeshDistanceIndex": "send the mesh",  # its BVH keeps triangles only
    "reconstruction.FrameToModel": "FrameToModelSettings",  # a live voxel model
}


def _classes():
    """'submodule.Class' -> class for every pybind11 class in scanalign._core."""
    out = {}
    for sub_name, sub in inspect.getmembers(_core, inspect.ismodule):
        for name, cls in inspect.getmembers(sub, inspect.isclass):
            if cls.__module__.startswith("scanalign._core") and not issubclass(cls, BaseException):
                out[f"{sub_name}.{name}"] = cls
    return out


# ----------------------------------------------------------------------------- comparison


# Properties an engine measures when it is rebuilt from its state: not part of the state.
REBUILT = {("Icp", "tree_build_seconds")}


def _properties(obj):
    return sorted(n for n, a in inspect.getmembers(type(obj))
                  if isinstance(a, property) and not n.startswith("_") and (type(obj).__name__, n) not in REBUILT)


def _assert_same(a, b, path):
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        assert a.dtype == b.dtype and a.shape == b.shape, (path, a.dtype, b.dtype, a.shape, b.shape)
        if a.dtype.kind in "fc":
            assert np.array_equal(a, b, equal_nan=True), path
        else:
            assert np.array_equal(a, b), path
    elif isinstance(a, float) and isinstance(b, float):
        assert a == b or (math.isnan(a) and math.isnan(b)), (path, a, b)
    elif isinstance(a, (list, tuple)):
        assert type(a) is type(b) and len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _assert_same(x, y, f"{path}[{i}]")
    elif isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            _assert_same(a[k], b[k], f"{path}[{k!r}]")
    elif _is_core_object(a):
        assert type(a) is type(b), path
        for name in _properties(a):
            _assert_same(getattr(a, name), getattr(b, name), f"{path}.{name}")
    else:
        assert type(a) is type(b) and a == b, (path, a, b)


def _is_core_object(x):
    return type(x).__module__.startswith("scanalign._core") and not hasattr(type(x), "__members__")


def _snapshot(x):
    """A plain copy of x's public state (nested objects as dicts), to compare before / after."""
    if _is_core_object(x):
        return {name: _snapshot(getattr(x, name)) for name in _properties(x)}
    if isinstance(x, (list, tuple)):
        return type(x)(_snapshot(v) for v in x)
    return np.array(x) if isinstance(x, np.ndarray) else x


def _round_trip(obj):
    for protocol in PROTOCOLS:
        copy = pickle.loads(pickle.dumps(obj, protocol=protocol))
        assert copy is not obj
        _assert_same(obj, copy, f"{type(obj).__name__}(protocol {protocol})")


# ----------------------------------------------------------------------------- settings

# A valid other value for fields where a generic change is not one (a choice among names,
# a rigid transform, an optional value that is None by default).
ROT = np.array([[0.0, -1.0, 0.0, 0.1], [1.0, 0.0, 0.0, 0.2], [0.0, 0.0, 1.0, 0.3], [0.0, 0.0, 0.0, 1.0]])
OTHER = {
    "estimator": "point_to_point", "robust_kernel": "huber", "search": "left_balanced_kdtree", "backend": "cuda", "detector": "orb",
    "shape": "capsule", "name": "changed", "method": "flags",
    "model_frame": "camera", "registration": "pcl_svd",
    "box": _core.registration.Box(-0.1, 0.1, -0.2, 0.2, 0.0, 1.0), "crop_box": _core.registration.Box(-1, 1, -1, 1, 0, 2),
    "center": np.array([0.01, 0.02, 0.03]), "viewpoint": np.array([0.0, 0.0, 0.5]), "T_model_grasp": ROT, "T_flange_tcp": ROT, "T_scene_model": ROT,
    "approach": np.array([1.0, 0.0, 0.0]), "axis": np.array([0.0, 1.0, 0.0]), "view": 3,
    "capsule_a": np.array([0.0, 0.0, 0.01]), "capsule_b": np.array([0.0, 0.0, 0.12]),
}

# Choices among names whose default may be any of them (PickSettings: motion model
# 'reference'): the first that differs.
CHOICES = {"motion_model": ("reference", "previous"), "views": ("all", "upper")}


def _other(name, value):
    if hasattr(type(value), "__members__"):  # pybind11 enum
        return next(m for m in type(value).__members__.values() if m != value)
    if isinstance(value, str) and name in CHOICES:
        return next(c for c in CHOICES[name] if c != value)
    if name in OTHER and (isinstance(OTHER[name], type(value)) or not type(value).__module__.startswith("scanalign._core")):
        return OTHER[name]  # a struct-valued field of the same name (AssemblySettings.view) is changed field by field
    if isinstance(value, bool):
        return not value
    if isinstance(value, int):
        return value + 1 if value < 2**62 else 7
    if isinstance(value, float):
        return 0.25 if value == 0 else 0.75 * value if math.isfinite(value) else 1e3
    if isinstance(value, np.ndarray):
        return np.where(np.isfinite(value), value + 0.25, 0.5) if value.dtype.kind == "f" else value + 1
    if isinstance(value, str):  # free text (names, messages); choices are in OTHER
        return value + "-changed"
    if type(value).__module__.startswith("scanalign._core"):
        return _changed(value)
    raise AssertionError(f"{name}: no other value for {value!r}")


def _changed(obj):
    """obj with every writable property set to another valid value (asserted to differ)."""
    for name, attr in inspect.getmembers(type(obj)):
        if isinstance(attr, property) and attr.fset is not None and not name.startswith("_"):
            before = _snapshot(getattr(obj, name))
            setattr(obj, name, _other(name, getattr(obj, name)))
            with pytest.raises(AssertionError):
                _assert_same(before, _snapshot(getattr(obj, name)), f"{type(obj).__name__}.{name} unchanged")
    return obj


# Classes the test builds itself: default-constructible ones are changed field by field;
# read-only ones are built with non-default arguments.
def _sensor_noise():
    return _core.synthetic.SensorNoise(name="n", axial_sigma_ref=0.001, z_ref=0.7, depth_unit=1e-4, min_range=0.2,
                                       max_range=3.0, grazing_cos=0.1, edge_threshold=0.05, edge_width=2, dropout=0.01)


def _with_valid_clusters(s):
    """``s`` (changed field by field) with max_cluster_size set back above min_cluster_size, which the generic change
    makes invalid; validated."""
    p = s.find_parts
    t = p.table
    t.max_cluster_size = 100000
    p.table, s.find_parts = t, p
    s.validate()
    return s


def _pick_settings():
    """PickSettings validates when unpickled (validate() is a member): every field changed,
    then the two combinations the generic change makes invalid set back (a robust kernel
    needs the point-to-plane estimator; max_cluster_size at least min_cluster_size)."""
    s = _changed(_core.grasp.PickSettings())
    r = s.reconstruction
    f = r.frame_to_model
    icp = f.icp
    icp.robust_kernel = "none"
    f.icp, r.frame_to_model, s.reconstruction = icp, f, r
    return _with_valid_clusters(s)


def _assembly_settings():
    """AssemblySettings, as PickSettings."""
    return _with_valid_clusters(_changed(_core.grasp.AssemblySettings()))


# ----------------------------------------------------------------------------- real runs


def _surface(n=40, shift=(0.0, 0.0, 0.0)):
    """A smooth bumpy patch (m) and its unit normals."""
    u, v = np.meshgrid(np.linspace(-0.1, 0.1, n), np.linspace(-0.1, 0.1, n))
    z = 0.02 * np.sin(20 * u) * np.cos(15 * v)
    p = np.c_[u.ravel(), v.ravel(), z.ravel()]
    dz_du = 0.4 * np.cos(20 * u) * np.cos(15 * v)
    dz_dv = -0.3 * np.sin(20 * u) * np.sin(15 * v)
    nrm = np.c_[-dz_du.ravel(), -dz_dv.ravel(), np.ones(n * n)]
    return p + shift, nrm / np.linalg.norm(nrm, axis=1, keepdims=True)


def _small_motion():
    a = 0.02
    T = np.eye(4)
    T[:3, :3] = [[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]]
    T[:3, 3] = [0.004, -0.003, 0.002]
    return T


def _icp_inputs():
    target, normals = _surface()
    T = _small_motion()
    source = (target - T[:3, 3]) @ T[:3, :3]  # T_target_source = T
    return source, target, normals


@functools.lru_cache(maxsize=None)
def _views():
    """The bracket's model views with their CBD features cached (describe_model_views)."""
    views = cad.render_views(parts.builtin_mesh(name="bracket"), resolution=60, num_threads=THREADS)
    return views, _core.pose.describe_model_views(views, _pose_settings())


def _pose_settings():
    s = _core.pose.PoseSettings()
    s.num_threads = THREADS
    return s


@functools.lru_cache(maxsize=None)
def _pose_run():
    """estimate_pose of the bracket in one of its own views, moved: PoseResult with candidates."""
    views, described = _views()
    T = _small_motion()
    obj = described[5].points @ T[:3, :3].T + T[:3, 3]
    return _core.pose.estimate_pose(list(described[:8]), obj, _pose_settings())


def _results():
    """One instance (or several) of every result class, from real runs on small inputs."""
    out = {}
    source, target, normals = _icp_inputs()
    icp = _core.registration.Icp(target, normals, _icp_settings())
    out["registration.Icp"] = [icp, _core.registration.Icp(target.astype(np.float32), None, _settings_p2p())]
    out["registration.IcpResult"] = icp.align(source, np.eye(4))
    cloud = np.vstack([target, [[np.nan, 0, 0]], target[:5] + 1.0])  # a NaN row: left out of the trees
    out["registration.KdTree"] = [_core.registration.KdTree(cloud), _core.registration.KdTree(cloud.astype(np.float32))]
    out["registration.BucketKdTree32"] = _core.registration.BucketKdTree32(cloud.astype(np.float32), 4)
    out["registration.BucketKdTree64"] = _core.registration.BucketKdTree64(cloud, 8)
    out["registration.Box"] = _core.registration.Box(-0.1, 0.2, -0.3, 0.4, 0.05, 1.5)

    robot = kinematics.ur5()
    T = robot.fk([0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    out["kinematics.Robot"] = robot
    out["kinematics.IKResult"] = robot.ik(T)
    out["kinematics.IKSolution"] = robot.ik_closest(T, [0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    out["kinematics.IKBatchResult"] = robot.ik_batch(np.stack([T, T]), num_threads=THREADS)
    out["kinematics.JointTrajectoryResult"] = robot.ik_trajectory(np.stack([T, T]), [0.3, -1.2, 1.4, -0.5, 1.1, 0.2])
    out["kinematics.IKConstruction"] = robot.ik_construction(T, 1, 1, 1)

    rng = np.random.default_rng(1)
    d = rng.normal(size=(60, 3))
    sphere = 0.05 * d / np.linalg.norm(d, axis=1, keepdims=True) + [0.1, 0.2, 0.3]
    out["fitting.SphereFitResult"] = _core.fitting.fit_sphere(sphere, None)
    out["fitting.SphereFitBatchResult"] = _core.fitting.fit_spheres(sphere, np.array([0, 30, 60]), num_threads=THREADS)
    t = np.linspace(0, 6, 20)
    out["fitting.CircleFitResult"] = _core.fitting.fit_circle_2d(np.c_[0.1 + 0.2 * np.cos(t), 0.2 * np.sin(t)])

    table = np.c_[rng.uniform(-0.3, 0.3, (3000, 2)), np.zeros(3000)]
    box = rng.uniform([0.0, 0.0, 0.005], [0.04, 0.04, 0.04], (400, 3))
    scene = np.vstack([table, box, box + [0.15, 0.1, 0.0]])
    out["segmentation.PlaneResult"] = _core.segmentation.ransac_plane(scene, 0.002, num_threads=THREADS)
    out["segmentation.SphereResult"] = _core.segmentation.ransac_sphere(sphere, 0.001, num_threads=THREADS)
    phi = rng.uniform(0, np.pi, 800)
    mantle = np.c_[0.03 * np.cos(phi), 0.03 * np.sin(phi), rng.uniform(0, 0.1, 800)]
    out["segmentation.CylinderResult"] = _core.segmentation.ransac_cylinder(
        mantle, 0.001, normals=np.c_[np.cos(phi), np.sin(phi), np.zeros(800)], num_threads=THREADS)
    out["segmentation.TableSegmentationResult"] = _core.segmentation.segment_table_full(
        scene, threshold=0.002, up=(0, 0, 1), cluster_tolerance=0.01, min_cluster_size=50, num_threads=THREADS)

    poses = [robot.fk(q) for q in rng.uniform(-1, 1, (6, 6))]
    X = _small_motion()
    Z = np.linalg.inv(ROT)
    world_camera = np.stack([np.linalg.inv(Z) @ A @ X for A in poses])
    out["calibration.HandEyeResult"] = _core.calibration.calibrate_hand_eye(np.stack(poses), world_camera,
                                                                            _core.calibration.HandEyeSettings())

    cell_robot = kinematics.ur5()
    T_base_model = np.eye(4)
    T_base_model[:3, 3] = [0.45, 0.1, 0.0]
    top = np.diag([1.0, -1.0, -1.0, 1.0])
    top[2, 3] = 0.03
    plan = G.plan_grasp(cell_robot, T_base_model, [G.Grasp("top", top)], symmetry=G.PartSymmetry(order=2),
                        q_current=[0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0])
    assert plan.candidates
    out["grasp.GraspPlanResult"] = plan
    out["grasp.GraspCandidate"] = list(plan.candidates[:3])
    view = G.plan_camera_view(cell_robot, T_base_model, 0.025, camera_mount=G.hand_camera_mount(np.eye(4)),
                              q_current=[0, -math.pi / 2, math.pi / 2, -math.pi / 2, -math.pi / 2, 0])
    assert view.found
    out["grasp.ViewPlan"] = view
    label_geometry = _core.pose.ReferenceImageGeometry(width=300, height=200, origin_pixel=(149.5, 99.5),
                                                       top_height=0.025)
    camera = np.asarray(view.T_base_camera)
    H = _core.pose.homography_of_part(label_geometry, _core.reconstruction.PinholeIntrinsics(
        1280, 720, 900.0, 900.0, 639.5, 359.5), camera, T_base_model)
    out["pose.HomographyPose"] = _core.pose.planar_pose_from_homography(
        H, label_geometry, _core.reconstruction.PinholeIntrinsics(1280, 720, 900.0, 900.0, 639.5, 359.5), camera,
        T_base_model)

    f2m_settings = _core.reconstruction.FrameToModelSettings()
    f2m_settings.num_threads = THREADS
    f2m = _core.reconstruction.FrameToModel(f2m_settings)
    frame = target.astype(np.float32)
    reports = [f2m.integrate(frame, None, None, "scanalign"), f2m.integrate(frame + np.float32(0.001), None, None,
                                                                            "scanalign")]
    out["reconstruction.FrameResult"] = reports
    out["reconstruction.PreparedFrame"] = f2m.prepare(frame, None)
    out["reconstruction.FrameToModel"] = f2m

    errors = rng.normal(size=50)
    out["evaluation.ErrorStats"] = _core.evaluation.ErrorStats.from_errors(errors)
    mesh = parts.builtin_mesh(name="bracket")
    index = _core.evaluation.MeshDistanceIndex(mesh.vertices, mesh.faces)
    out["evaluation.MeshDistanceIndex"] = index
    out["evaluation.MeshDistanceStats"] = index.stats(mesh.vertices[:50] + 0.001, num_threads=THREADS)

    header = b"VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2 3\n"
    out["io.PcdHeader"] = _core.io.parse_pcd(header)[0]
    out["io.PcdField"] = list(out["io.PcdHeader"].fields)

    views, described = _views()
    out["pose.ModelView"] = [views[0], described[0], described[3]]
    out["pose.CbdFeatures"] = described[0].cbd
    pr = _pose_run()
    out["pose.PoseResult"] = pr
    out["pose.PoseCandidate"] = list(pr.candidates[:3])
    src, dst = described[0].points[:200], described[0].points[:200] @ ROT[:3, :3].T + ROT[:3, 3]
    out["pose.MotorEstimationResult"] = _core.pose.estimate_motor(src, dst)
    pairs = np.c_[np.arange(200), np.arange(200)]
    out["pose.CorrespondenceRansacResult"] = _core.pose.ransac_rigid_motion(
        src, dst, pairs, _core.pose.CorrespondenceRansacSettings())
    moved = described[3].points @ ROT[:3, :3].T + ROT[:3, 3]
    cbd = _core.pose.CbdAlignmentSettings()
    cbd.cbd.num_threads = cbd.ransac.num_threads = THREADS
    out["pose.CbdAlignmentResult"] = _core.pose.align_cbd(described[3].points, moved, cbd)
    nrm = described[3].normals
    out["pose.NormalLineFlag"] = _core.pose.normal_line_flag(described[3].points, nrm)
    out["pose.FlagAlignmentResult"] = _core.pose.align_flags(described[3].points, nrm, moved, nrm @ ROT[:3, :3].T,
                                                             _core.pose.FlagAlignmentSettings())
    cga = _core.cga
    out["cga.Sphere"] = cga.Sphere([0.1, 0.2, 0.3], 0.05)
    out["cga.Plane"] = cga.Plane([0.0, 0.6, 0.8], 0.2)
    out["cga.Line"] = cga.Line([0.1, 0.0, 0.0], [0.0, 0.0, 1.0])
    out["cga.Point"] = cga.Point([0.1, -0.2, 0.3])
    out["cga.Circle"] = cga.Circle([0.1, 0.2, 0.3], [0.0, 0.0, 1.0], 0.04)
    out["cga.PointPair"] = cga.PointPair.from_points([0.1, 0.0, 0.0], [0.0, 0.2, 0.0])
    out["cga.FlatPoint"] = cga.FlatPoint.at([0.1, 0.2, 0.3])
    out["cga.Motor"] = cga.Motor.from_matrix(ROT)
    out["cga.Multivector"] = cga.Multivector.e1() * cga.Multivector.e2() + cga.Multivector(0.5)

    table_scene = _table_scene()
    found = pose.find_parts([list(described[:8])], table_scene, up=(0, 0, 1), table_threshold=0.002,
                            cluster_tolerance=0.01, num_threads=THREADS)
    assert found.detections
    out["pose.FindPartsResult"] = found
    out["pose.PartDetection"] = list(found.detections)
    out["pose.FindObjectsResult"] = pose.find_objects(list(described[:8]), table_scene, up=(0, 0, 1), table_threshold=0.002,
                                                cluster_tolerance=0.01, num_threads=THREADS)
    pcl = _core.pose.thesis_pcl_preset(_core.pose.PclDescriptor.fpfh, _core.pose.PclMatcher.prerejective)
    pcl.voxel_size, pcl.max_iterations, pcl.num_threads = 0.004, 200, THREADS
    out["pose.PclFeatureAlignmentResult"] = _core.pose.pcl_feature_alignment(
        described[3].points.astype(np.float32), moved.astype(np.float32), pcl)
    return out


def _table_scene():
    """A 30 x 30 cm table (z = 0, 3 mm grid) with the bracket's view 5 standing on it."""
    _, described = _views()
    u, v = np.meshgrid(np.arange(-0.15, 0.15, 0.003), np.arange(-0.15, 0.15, 0.003))
    table = np.c_[u.ravel(), v.ravel(), np.zeros(u.size)]
    obj = described[5].points
    return np.vstack([table, obj - [*obj[:, :2].mean(axis=0), obj[:, 2].min() - 0.004]])


def _icp_settings():
    s = _core.registration.IcpSettings()
    s.num_threads = THREADS
    return s


def _settings_p2p():
    s = _icp_settings()
    s.estimator = "point_to_point"
    return s


# Classes whose instances come from _results() only (no default constructor, or a default
# instance would hide fields that stay at their defaults).
def _all_instances():
    instances = {}
    for key, value in _results().items():
        instances[key] = value if isinstance(value, list) else [value]
    for key, cls in _classes().items():
        if key in REFUSED or hasattr(cls, "__members__"):
            continue
        try:
            default = cls()
        except TypeError:
            continue
        instances.setdefault(key, []).append(_changed(default))
    instances["synthetic.SensorNoise"] = [_sensor_noise()]
    instances["grasp.PickSettings"] = [_pick_settings()]
    instances["grasp.AssemblySettings"] = [_assembly_settings()]
    instances["reconstruction.PinholeIntrinsics"] = [_core.reconstruction.PinholeIntrinsics(64, 48, 50.5, 51.5, 31.2, 23.9)]
    return instances


@pytest.fixture(scope="module")
def instances():
    return _all_instances()


def test_every_bound_class_round_trips_or_refuses(instances):
    classes = _classes()
    enums = {k for k, c in classes.items() if hasattr(c, "__members__")}
    missing = sorted(set(classes) - set(instances) - set(REFUSED) - enums)
    assert not missing, f"no pickle test instance for {missing}"
    for key in sorted(set(instances) - set(REFUSED)):
        assert key in classes, key
        for obj in instances[key]:
            assert isinstance(obj, classes[key]), key
            _round_trip(obj)
    for key, advice in REFUSED.items():
        for obj in instances[key]:
            for protocol in PROTOCOLS:
                with pytest.raises(TypeError, match=f"{key.split('.')[1]} cannot be pickled: .*{advice}"):
                    pickle.dumps(obj, protocol=protocol)


def test_enums_pickle_as_their_members():
    for key, cls in _classes().items():
        if hasattr(cls, "__members__"):
            for member in cls.__members__.values():
                for protocol in PROTOCOLS:
                    assert pickle.loads(pickle.dumps(member, protocol=protocol)) == member, key


def test_changed_settings_keep_every_field():
    """A field missing from the state would come back at its default: compare against it."""
    for cls in (_core.registration.IcpSettings, _core.reconstruction.FrameToModelSettings, _core.pose.FindPartsSettings,
                _core.grasp.GraspPlannerSettings):
        changed = _changed(cls())
        copy = pickle.loads(pickle.dumps(changed))
        _assert_same(changed, copy, cls.__name__)
        with pytest.raises(AssertionError):
            _assert_same(cls(), copy, cls.__name__)


def test_engines_rebuilt_from_their_state_answer_the_same():
    source, target, normals = _icp_inputs()
    for dtype, n in ((np.float64, normals), (np.float32, None)):
        s = _icp_settings() if n is not None else _settings_p2p()
        icp = _core.registration.Icp(target.astype(dtype), n, s)
        copy = pickle.loads(pickle.dumps(icp, protocol=5))
        assert copy.dtype == icp.dtype and copy.target_size == icp.target_size
        a, b = icp.align(source, np.eye(4)), copy.align(source, np.eye(4))
        np.testing.assert_array_equal(a.T_target_source, b.T_target_source)
        if n is not None:  # point-to-plane on the exact pair: the true motion
            assert np.abs(a.T_target_source - _small_motion()).max() < 1e-6
    from scanalign import registration

    wrapped = registration.Icp(target, normals, max_correspondence_distance=0.02, num_threads=THREADS)  # the package's subclass
    copy = pickle.loads(pickle.dumps(wrapped, protocol=5))
    assert type(copy) is registration.Icp and copy.settings.max_correspondence_distance == 0.02
    np.testing.assert_array_equal(copy.align(source).T_target_source, wrapped.align(source).T_target_source)
    cloud = np.vstack([target, [[np.nan, 0, 0]], target[:5] + 1.0])
    queries = target[::7] + 0.003
    for tree in (_core.registration.KdTree(cloud), _core.registration.BucketKdTree64(cloud, 8),
                 _core.registration.BucketKdTree32(cloud.astype(np.float32), 4)):
        copy = pickle.loads(pickle.dumps(tree))
        q = queries.astype(np.float32) if isinstance(tree, _core.registration.BucketKdTree32) else queries
        args = (q,) if isinstance(tree, _core.registration.KdTree) else (q, math.inf)
        got, want = copy.nearest(*args), tree.nearest(*args)
        for x, y in zip(got, want):
            np.testing.assert_array_equal(x, y)
        brute = np.nanargmin(((cloud[None, :, :] - queries[:, None, :]) ** 2).sum(-1), axis=1)  # NaN row left out
        np.testing.assert_array_equal(got[0], brute)


def test_model_view_state_is_flat_and_survives_npz(tmp_path):
    """The part library's rule: arrays and scalars only, loaded by np.load(allow_pickle=False)."""
    _, described = _views()
    view = described[2]
    state = view.__getstate__()
    assert state["has_cbd"] and any(k.startswith("cbd/") for k in state)
    for k, v in state.items():
        assert isinstance(v, (np.ndarray, bool, int, float, str)), (k, type(v))
    np.savez(tmp_path / "v.npz", **state)
    with np.load(tmp_path / "v.npz", allow_pickle=False) as f:
        loaded = {k: (f[k].item() if f[k].ndim == 0 else f[k]) for k in f.files}
    copy = _core.pose.ModelView.__new__(_core.pose.ModelView)
    copy.__setstate__(loaded)
    _assert_same(view, copy, "ModelView")
    assert copy.cbd_settings.radius == view.cbd_settings.radius
    plain = _views()[0][2]
    assert plain.cbd is None and not plain.__getstate__()["has_cbd"]
    assert not any(k.startswith("cbd/") for k in plain.__getstate__())


def test_pose_from_unpickled_views_equals_the_original():
    _, described = _views()
    copies = pickle.loads(pickle.dumps(list(described[:8]), protocol=5))
    T = _small_motion()
    obj = described[5].points @ T[:3, :3].T + T[:3, 3]
    a = _pose_run()
    b = _core.pose.estimate_pose(copies, obj, _pose_settings())
    np.testing.assert_array_equal(a.T_scene_model, b.T_scene_model)
    assert a.found and np.abs(a.T_scene_model - T).max() < 1e-3  # the bracket found where it was moved to


def _corrupt(obj, mutate):
    state = obj.__getstate__()
    mutate(state)
    fresh = type(obj).__new__(type(obj))
    fresh.__setstate__(state)


@pytest.mark.parametrize("key", ["registration.IcpSettings", "registration.IcpResult", "pose.ModelView",
                                 "pose.CbdFeatures", "grasp.GraspPlanResult", "kinematics.IKSolution",
                                 "segmentation.TableSegmentationResult", "registration.Icp", "registration.BucketKdTree64",
                                 "kinematics.Robot"])
def test_corrupt_state_is_a_clear_error(instances, key):
    obj = instances[key][-1]
    state = obj.__getstate__()
    name = key.split(".")[1]
    first = next(iter(state))
    with pytest.raises(ValueError, match=f"{name}.*'{first}'"):
        _corrupt(obj, lambda s: s.pop(first))
    with pytest.raises((TypeError, ValueError), match=name):
        _corrupt(obj, lambda s: s.__setitem__(first, object()))
    with pytest.raises(TypeError):
        type(obj).__new__(type(obj)).__setstate__(["not", "a", "dict"])
    if key not in ("registration.Icp", "registration.BucketKdTree64"):
        with pytest.raises(ValueError, match="unknown key 'extra'"):
            _corrupt(obj, lambda s: s.__setitem__("extra", 1))


def test_robot_loads_the_tuple_state_of_earlier_pickles():
    robot = kinematics.kuka_kr6_r900_sixx()
    state = robot.__getstate__()
    old = tuple(state[k] for k in ("name", "a", "alpha", "d", "theta_offset", "limits", "T_base_dh0", "T_flange_tool"))
    copy = _core.kinematics.Robot.__new__(_core.kinematics.Robot)
    copy.__setstate__(old)
    _assert_same(robot, copy, "Robot")
    with pytest.raises(ValueError, match="non-finite|finite"):
        _corrupt(robot, lambda s: s.__setitem__("a", np.full(6, np.nan)))


def test_corrupt_arrays_are_refused_not_read_out_of_bounds(instances):
    view = instances["pose.ModelView"][1]
    with pytest.raises(ValueError, match="differ in length"):
        _corrupt(view, lambda s: s.__setitem__("face_id", s["face_id"][:-1]))
    with pytest.raises(ValueError, match="differ in length"):
        _corrupt(view, lambda s: s.__setitem__("cbd/scalar", s["cbd/scalar"][:-1]))
    with pytest.raises(TypeError, match="dtype"):
        _corrupt(view, lambda s: s.__setitem__("cbd/keypoints", s["cbd/keypoints"].astype(np.float64)))
    with pytest.raises(ValueError, match="past the view"):
        _corrupt(view, lambda s: s.__setitem__("cbd/keypoints", s["cbd/keypoints"] + np.uint32(10**6)))
    with pytest.raises(ValueError, match="chosen"):
        _corrupt(instances["grasp.GraspPlanResult"][0], lambda s: s.__setitem__("chosen", 10**6))
    with pytest.raises(ValueError, match="shape"):
        _corrupt(instances["kinematics.IKBatchResult"][0], lambda s: s.__setitem__("status", s["status"][:, :3]))
    with pytest.raises(ValueError, match="dropout"):  # validated after loading, as the constructor does
        _corrupt(_sensor_noise(), lambda s: s.__setitem__("dropout", 2.0))
    with pytest.raises(ValueError, match="unknown value 'sideways'"):
        _corrupt(instances["registration.IcpSettings"][0], lambda s: s.__setitem__("estimator", "sideways"))


def test_python_records_holding_core_objects_pickle(instances):
    """The package's dataclasses cross process boundaries once the C++ objects they hold do."""
    from scanalign import reconstruction
    from scanalign.pipelines import pick
    from scanalign.pipelines import reconstruct as pipeline

    mesh = parts.builtin_mesh(name="bracket")
    plan = instances["grasp.GraspPlanResult"][0]
    trajectory = Trajectory(np.array([0.0, 1.0]), np.stack([np.eye(4), ROT]))
    grasps = G.PartGrasps(name="bracket", mesh=mesh, grasps=[G.Grasp("top", ROT)], symmetry=G.PartSymmetry(order=3))
    part_pick = pick.PartPick(part="bracket", status="picked", T_base_model=ROT, plan=plan)
    model = reconstruction.Model(mesh.vertices, mesh.vertices * 0, None)
    run = pipeline.ReconstructionResult(model=model, records=instances["reconstruction.FrameResult"],
                                        estimate=trajectory, reference=None, T_model_camera0=ROT,
                                        settings=_changed(_core.reconstruction.ReconstructionSettings()),
                                        seconds=1.5)
    records = [
        mesh, trajectory, grasps, pick.PickSettings(planner=G.GraspPlannerSettings(min_wrist_angle=0.1)), part_pick, model, run,
        pick.PickResult(picks=[part_pick], points=mesh.vertices, detections=instances["pose.FindPartsResult"][0],
                        robot=kinematics.ur5(), q_current=np.zeros(6), parts=[grasps], reconstruction=run),
    ]
    for record in records:
        _assert_same(_plain(record), _plain(pickle.loads(pickle.dumps(record, protocol=5))), type(record).__name__)


def _plain(x):
    """A Python record as nested dicts (dataclasses by their fields, bound objects by properties)."""
    if hasattr(x, "__dataclass_fields__"):
        return {name: _plain(getattr(x, name)) for name in x.__dataclass_fields__}
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return type(x)(_plain(v) for v in x)
    if type(x).__name__ == "Robot":
        return pickle.dumps(x)  # its state is its DH table, limits and transforms
    return _snapshot(x)


def _worker_icp(settings, robot, source, target, normals):
    """Runs in a spawned process: everything it gets and returns went through pickle."""
    from scanalign import _core as core

    icp = core.registration.Icp(target, normals, settings)
    return icp.align(source, robot.fk([0.0] * 6) @ np.linalg.inv(robot.fk([0.0] * 6))), robot.name


def test_objects_cross_a_spawned_process_pool():
    source, target, normals = _icp_inputs()
    settings = _icp_settings()
    settings.max_iterations = 40
    robot = kinematics.ur5()
    want = _core.registration.Icp(target, normals, settings).align(source, np.eye(4))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    ctx = multiprocessing.get_context("spawn")
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = env["PYTHONPATH"]
    try:
        with concurrent.futures.ProcessPoolExecutor(max_workers=1, mp_context=ctx) as pool:
            got, name = pool.submit(_worker_icp, settings, robot, source, target, normals).result(timeout=120)
    finally:
        if old is None:
            os.environ.pop("PYTHONPATH")
        else:
            os.environ["PYTHONPATH"] = old
    assert name == robot.name
    assert isinstance(got, _core.registration.IcpResult) and got.status == want.status
    np.testing.assert_array_equal(got.T_target_source, want.T_target_source)
    assert np.abs(got.T_target_source - _small_motion()).max() < 1e-6

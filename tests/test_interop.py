"""Open3D, trimesh and evo objects as inputs and outputs (scanalign.io.interop, scanalign.common.arrays,
Trajectory's KITTI / EuRoC / evo conversions): the same results as the NumPy arrays."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from scanalign import features, fitting, io, registration, segmentation
from scanalign.pose import model_views as cad
from scanalign.io import interop
from scanalign.evaluation import mesh_distance as mesh_metrics
from scanalign.data import parts
from scanalign.reconstruction import voxel_grid
from scanalign.evaluation.trajectory import Trajectory, TumFormatError, matrix_from_quaternion


@pytest.fixture(scope="module")
def surface():
    """A wavy 20 x 20 cm surface 40 cm in front of the camera, its normals, and a source
    moved by a few mm and 2 degrees (the README's example, smaller)."""
    u, v = np.meshgrid(np.linspace(-0.1, 0.1, 70), np.linspace(-0.1, 0.1, 70))
    model = np.c_[u.ravel(), v.ravel(), 0.4 + 0.01 * np.sin(30 * u.ravel()) * np.cos(20 * v.ravel())]
    normals = features.estimate_normals(model, radius=0.01)
    c, s = np.cos(np.radians(2)), np.sin(np.radians(2))
    T = np.array([[c, -s, 0, 0.004], [s, c, 0, -0.002], [0, 0, 1, 0.003], [0, 0, 0, 1]])
    source = (model - T[:3, 3]) @ T[:3, :3]
    return model, normals, source


def _o3d():
    return pytest.importorskip("open3d")


def _tensor_cloud(points, normals=None):
    o3d = _o3d()
    t = o3d.t.geometry.PointCloud(o3d.core.Tensor(np.ascontiguousarray(points)))
    if normals is not None:
        t.point.normals = o3d.core.Tensor(np.ascontiguousarray(normals))
    return t


def _foreign_clouds(points, normals=None):
    """The same cloud as Open3D legacy, Open3D tensor (dtype kept) and trimesh objects."""
    o3d, trimesh = _o3d(), pytest.importorskip("trimesh")
    return {"open3d": interop.to_open3d(points, normals), "open3d.t": _tensor_cloud(points, normals),
            "trimesh": trimesh.PointCloud(points)}


# --- inputs -------------------------------------------------------------------------------

def test_icp_takes_foreign_clouds(surface):
    model, normals, source = surface
    expected = registration.icp(source, model, normals, max_correspondence_distance=0.02)
    assert expected.converged
    np.testing.assert_array_equal(expected.transformation, expected.T_target_source)  # Open3D's name
    src, tgt = _foreign_clouds(source), _foreign_clouds(model, normals)
    for kind in src:
        got = registration.icp(src[kind], tgt[kind], normals, max_correspondence_distance=0.02)
        np.testing.assert_array_equal(got.T_target_source, expected.T_target_source, err_msg=kind)
    for kind in ("open3d", "open3d.t"):  # the target cloud's own normals when none are given
        got = registration.icp(src[kind], tgt[kind], max_correspondence_distance=0.02)
        np.testing.assert_array_equal(got.T_target_source, expected.T_target_source, err_msg=kind)
    with pytest.raises(ValueError):  # a trimesh cloud has no normals: point-to-plane still needs them
        registration.icp(src["trimesh"], tgt["trimesh"], max_correspondence_distance=0.02)
    engine = registration.Icp(tgt["open3d"], max_correspondence_distance=0.02)  # the reusable engine too
    np.testing.assert_array_equal(engine.align(src["open3d.t"]).T_target_source, expected.T_target_source)


def test_float32_tensor_cloud_keeps_its_dtype(surface):
    model, normals, _ = surface
    m32 = model.astype(np.float32)
    got = features.estimate_normals(_tensor_cloud(m32), radius=0.01)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got, features.estimate_normals(m32, radius=0.01))


def test_normals_and_voxel_grid_take_foreign_clouds(surface):
    model, normals, _ = surface
    expected_n = features.estimate_normals(model, radius=0.01, viewpoint=(0, 0, 0))
    expected_v = voxel_grid(model, 0.01, normals=normals)
    for kind, cloud in _foreign_clouds(model).items():
        np.testing.assert_array_equal(features.estimate_normals(cloud, radius=0.01), expected_n, err_msg=kind)
        got = voxel_grid(cloud, 0.01, normals=normals)
        np.testing.assert_array_equal(got.points, expected_v.points, err_msg=kind)
        np.testing.assert_array_equal(got.normals, expected_v.normals, err_msg=kind)
    o3d_cloud = interop.to_open3d(model, normals)  # an Open3D vector as an attribute array
    np.testing.assert_array_equal(voxel_grid(o3d_cloud, 0.01, normals=o3d_cloud.normals).normals, expected_v.normals)


def test_bound_functions_take_foreign_clouds(surface):
    """Functions bound straight from C++ (fitting, segmentation) convert through the same helper."""
    model = surface[0]
    expected_fit = fitting.fit_sphere(model)
    expected_plane = segmentation.ransac_plane(model, 0.002)
    for kind, cloud in _foreign_clouds(model).items():
        got = fitting.fit_sphere(cloud)
        np.testing.assert_array_equal(np.asarray(got.dual), np.asarray(expected_fit.dual), err_msg=kind)
        plane = segmentation.ransac_plane(cloud, 0.002)
        np.testing.assert_array_equal(plane.inliers, expected_plane.inliers, err_msg=kind)


def test_mesh_functions_take_foreign_meshes():
    o3d, trimesh = _o3d(), pytest.importorskip("trimesh")
    mesh = parts.builtin_mesh(segments=24)
    meshes = {"open3d": interop.to_open3d(mesh), "trimesh": interop.to_trimesh(mesh)}
    meshes["open3d.t"] = o3d.t.geometry.TriangleMesh.from_legacy(meshes["open3d"], vertex_dtype=o3d.core.float64)
    expected_views = cad.render_views(mesh, resolution=40, level=0)
    expected_sample = parts.sample_mesh(mesh, 500, seed=1)
    points = expected_sample[0] + 0.003
    expected_d = mesh_metrics.point_to_mesh_distance(points, mesh.vertices, mesh.faces)
    for kind, m in meshes.items():
        views = cad.render_views(m, resolution=40, level=0)
        assert len(views) == len(expected_views) == 12
        for a, b in zip(views, expected_views):
            np.testing.assert_array_equal(a.points, b.points, err_msg=kind)
        np.testing.assert_array_equal(parts.sample_mesh(m, 500, seed=1)[0], expected_sample[0], err_msg=kind)
    # (vertices, faces) parameters take the mesh's own arrays (Open3D vectors included)
    d = mesh_metrics.point_to_mesh_distance(interop.to_open3d(points), meshes["open3d"].vertices,
                                            meshes["open3d"].triangles)
    np.testing.assert_array_equal(d, expected_d)
    tm = meshes["trimesh"]
    np.testing.assert_array_equal(mesh_metrics.point_to_mesh_distance(points, tm.vertices, tm.faces), expected_d)
    from scanalign.evaluation import evaluate_reconstruction

    traj = _trajectory(10)
    expected_e = evaluate_reconstruction(traj, traj, points=points, mesh=(mesh.vertices, mesh.faces))
    for kind, m in meshes.items():
        got = evaluate_reconstruction(traj, traj, points=interop.to_open3d(points), mesh=m)
        assert got["cloud_to_mesh_m"] == expected_e["cloud_to_mesh_m"], kind


def test_pose_takes_foreign_clouds():
    """estimate_pose: an Open3D cloud as the model, a trimesh cloud as the scene."""
    _o3d(), pytest.importorskip("trimesh")
    from scanalign import pose

    model = cad.render_views(parts.builtin_mesh(segments=24), resolution=60)[3].points
    scene = model + np.array([0.002, 0.001, 0.0])
    expected = pose.estimate_pose(model, scene)
    assert expected.found
    got = pose.estimate_pose(interop.to_open3d(model), interop.to_trimesh(scene))
    np.testing.assert_array_equal(got.T_scene_model, expected.T_scene_model)
    np.testing.assert_array_equal(got.transformation, got.T_scene_model)  # Open3D's name: model onto scene
    assert np.abs(got.transformation[:3, 3] - [0.002, 0.001, 0.0]).max() < 1e-3
    coarse = pose.align_cbd(model, scene, min_neighbors=0)
    np.testing.assert_array_equal(coarse.transformation, coarse.T_target_source)


def test_pick_scene_takes_a_foreign_cloud(surface):
    from scanalign.pipelines.pick import scan_model

    points, rec = scan_model(interop.to_trimesh(surface[0]))
    assert rec is None
    np.testing.assert_array_equal(points, surface[0])


def test_wrong_foreign_objects_are_named():
    o3d = _o3d()
    lines = o3d.geometry.LineSet()
    with pytest.raises(TypeError, match="source: expected points, got open3d.*LineSet"):
        registration.icp(lines, np.zeros((3, 3)), estimator="point_to_point")
    with pytest.raises(TypeError, match="points: expected points, got open3d.*LineSet"):
        features.estimate_normals(lines)


def test_foreign_types_are_not_imported_for_arrays(surface):
    """Plain NumPy input never imports Open3D or trimesh (checked in a fresh interpreter)."""
    import subprocess

    code = ("import sys, numpy as np; from scanalign import features, registration; from scanalign.io import interop; "
            "p = np.random.default_rng(0).random((200, 3)); features.estimate_normals(p, radius=0.2); "
            "print('open3d' in sys.modules, 'trimesh' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]


# --- conversions --------------------------------------------------------------------------

def test_open3d_round_trips(surface):
    o3d = _o3d()
    model, normals, _ = surface
    colors = (np.arange(len(model) * 3).reshape(-1, 3) % 256).astype(np.uint8)
    pcd = interop.to_open3d(model, normals, colors)
    assert isinstance(pcd, o3d.geometry.PointCloud)
    back = interop.from_open3d(pcd)
    np.testing.assert_array_equal(back.points, model)
    np.testing.assert_array_equal(back.normals, normals)
    np.testing.assert_allclose(back.colors * 255, colors, atol=1e-9)
    t = interop.from_open3d(o3d.t.geometry.PointCloud.from_legacy(pcd, o3d.core.float64))
    np.testing.assert_array_equal(t.points, model)
    np.testing.assert_array_equal(t.normals, normals)
    bare = interop.from_open3d(interop.to_open3d(model))
    assert bare.normals is None and bare.colors is None
    mesh = parts.builtin_mesh(segments=24)
    om = interop.to_open3d(mesh)
    assert isinstance(om, o3d.geometry.TriangleMesh)
    for m in (interop.from_open3d(om), interop.from_open3d(o3d.t.geometry.TriangleMesh.from_legacy(om))):
        assert isinstance(m, io.Mesh)
        np.testing.assert_allclose(m.vertices, mesh.vertices, rtol=0, atol=1e-6)  # the tensor mesh is float32
        np.testing.assert_array_equal(m.faces, mesh.faces)
    np.testing.assert_array_equal(interop.from_open3d(om).vertices, mesh.vertices)
    with pytest.raises(TypeError, match="Open3D PointCloud or TriangleMesh"):
        interop.from_open3d(model)


def test_trimesh_round_trips(surface):
    trimesh = pytest.importorskip("trimesh")
    mesh = parts.builtin_mesh(segments=24)
    tm = interop.to_trimesh(mesh)
    assert isinstance(tm, trimesh.Trimesh)
    back = interop.from_trimesh(tm)
    np.testing.assert_array_equal(back.vertices, mesh.vertices)
    np.testing.assert_array_equal(back.faces, mesh.faces)
    np.testing.assert_array_equal(interop.to_trimesh((mesh.vertices, mesh.faces)).faces, mesh.faces)
    model = surface[0]
    colors = np.full((len(model), 3), 200, np.uint8)
    cloud = interop.from_trimesh(interop.to_trimesh(model, colors=colors))
    np.testing.assert_array_equal(cloud.points, model)
    np.testing.assert_array_equal(cloud.colors, colors)
    _o3d()
    np.testing.assert_array_equal(interop.from_trimesh(interop.to_trimesh(interop.to_open3d(mesh))).faces, mesh.faces)


def test_missing_packages_are_named(monkeypatch):
    monkeypatch.setitem(sys.modules, "open3d", None)
    monkeypatch.setitem(sys.modules, "trimesh", None)
    with pytest.raises(ImportError, match="pip install open3d"):
        interop.to_open3d(np.zeros((3, 3)))
    with pytest.raises(ImportError, match="pip install trimesh"):
        interop.to_trimesh(parts.builtin_mesh(segments=24))


# --- trajectories -------------------------------------------------------------------------

def _trajectory(n=40, seed=0, t0=1403636579.763555584):
    rng = np.random.default_rng(seed)
    T = np.tile(np.eye(4), (n, 1, 1))
    T[:, :3, :3] = matrix_from_quaternion(rng.normal(size=(n, 4)))
    T[:, :3, 3] = np.cumsum(rng.normal(scale=0.05, size=(n, 3)), axis=0)
    return Trajectory(t0 + 0.05 * np.arange(n), T)


def test_kitti_round_trip(tmp_path):
    traj = _trajectory()
    traj.write_kitti(tmp_path / "poses.txt", tmp_path / "times.txt")
    assert len((tmp_path / "poses.txt").read_text().splitlines()[0].split()) == 12
    back = Trajectory.read_kitti(tmp_path / "poses.txt", tmp_path / "times.txt")
    np.testing.assert_array_equal(back.poses, traj.poses)
    np.testing.assert_array_equal(back.timestamps, traj.timestamps)
    np.testing.assert_array_equal(Trajectory.read_kitti(tmp_path / "poses.txt").timestamps, np.arange(len(traj)))
    (tmp_path / "short.txt").write_text("0.0\n")
    with pytest.raises(TumFormatError, match="1 times for 40 poses"):
        Trajectory.read_kitti(tmp_path / "poses.txt", tmp_path / "short.txt")
    (tmp_path / "bad.txt").write_text("1 0 0 0 0 1 0 0 0 0 1\n")
    with pytest.raises(TumFormatError, match=r"bad.txt:1: expected 12 values"):
        Trajectory.read_kitti(tmp_path / "bad.txt")


def test_euroc_round_trip(tmp_path):
    traj = _trajectory()
    traj.write_euroc(tmp_path / "data.csv")
    lines = (tmp_path / "data.csv").read_text().splitlines()
    assert lines[0] == "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []"
    assert lines[1].split(",")[0] == "1403636579763555527"  # integer nanoseconds (of the float64 time)
    back = Trajectory.read_euroc(tmp_path / "data.csv")
    np.testing.assert_allclose(back.poses, traj.poses, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(back.timestamps, traj.timestamps)
    # the ground-truth estimate's 17 columns (velocities and biases ignored), quaternion w first
    (tmp_path / "gt.csv").write_text("#timestamp,p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],"
                                     "q_RS_z [],v_RS_R_x [m s^-1],...\n"
                                     "1403636580838555648,4.688,-1.786,0.783,0.0,0.0,0.0,1.0" + ",0.1" * 9 + "\n")
    gt = Trajectory.read_euroc(tmp_path / "gt.csv")
    np.testing.assert_allclose(gt.poses[0], [[-1, 0, 0, 4.688], [0, -1, 0, -1.786], [0, 0, 1, 0.783], [0, 0, 0, 1]],
                               atol=1e-15)
    assert gt.timestamps[0] == 1403636580.838555648
    (tmp_path / "bad.csv").write_text("#timestamp\n1,2,3\n")
    with pytest.raises(TumFormatError, match="bad.csv:2: expected timestamp"):
        Trajectory.read_euroc(tmp_path / "bad.csv")


def test_evo_round_trip_and_metrics():
    pytest.importorskip("evo")
    from evo.core import metrics
    from evo.core.trajectory import PosePath3D, PoseTrajectory3D

    from scanalign.evaluation import absolute_trajectory_error, relative_pose_error

    ref = _trajectory(60, seed=1)
    est = Trajectory(ref.timestamps, ref.poses.copy())
    est.poses[:, :3, 3] += np.random.default_rng(2).normal(scale=0.01, size=(len(ref), 3))
    e_ref, e_est = ref.to_evo(), est.to_evo()
    assert isinstance(e_ref, PoseTrajectory3D)
    back = Trajectory.from_evo(e_ref)
    np.testing.assert_array_equal(back.poses, ref.poses)
    np.testing.assert_array_equal(back.timestamps, ref.timestamps)
    path = Trajectory.from_evo(PosePath3D(poses_se3=list(ref.poses)))
    np.testing.assert_array_equal(path.timestamps, np.arange(len(ref)))
    # evo's own metrics on the converted trajectories equal scanalign's
    ate = absolute_trajectory_error(est, ref)
    e_est.align(e_ref)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((e_ref, e_est))
    np.testing.assert_allclose(ape.error, ate.translation.errors, rtol=0, atol=1e-12)
    assert abs(ape.get_statistic(metrics.StatisticsType.rmse) - ate.translation.rmse) < 1e-12
    rpe = relative_pose_error(est, ref, delta=1)
    e_rpe = metrics.RPE(metrics.PoseRelation.translation_part, delta=1, delta_unit=metrics.Unit.frames)
    e_rpe.process_data((ref.to_evo(), est.to_evo()))
    np.testing.assert_allclose(e_rpe.error, rpe.translation.errors, rtol=0, atol=1e-12)

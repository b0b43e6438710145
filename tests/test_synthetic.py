"""Synthetic eye-in-hand scans against independent truth: analytic ray casting, exact poses,
the sensor models' own constants, and determinism."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from helpers import rigid
from scanalign import io as sio
from scanalign.data import parts
from scanalign.reconstruction import rendering
from scanalign import synthetic as syn
from scanalign.reconstruction.camera import Frame, Intrinsics, intrinsics_preset, read_camera
from scanalign.evaluation.trajectory import Trajectory

K_SR300 = intrinsics_preset("sr300")


# --------------------------------------------------------------------------- helpers


def rays(K: Intrinsics) -> np.ndarray:
    """(H, W, 3) un-normalised pixel rays (x/z, y/z, 1) through pixel centres."""
    v, u = np.mgrid[0 : K.height, 0 : K.width].astype(np.float64)
    return np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones_like(u)], axis=-1)


def quad(center, normal, size: float):
    """Two triangles forming a square of side `size` (m) centred at `center`, wound so that
    their right-hand normal is `normal`."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    a = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    c = np.asarray(center, float)
    h = size / 2
    v = np.array([c - h * a - h * b, c + h * a - h * b, c + h * a + h * b, c - h * a + h * b])
    f = np.array([[0, 1, 2], [0, 2, 3]])
    if np.dot(np.cross(v[1] - v[0], v[2] - v[0]), n) < 0:
        f = f[:, ::-1]
    return v, f


def uv_sphere(center, radius: float, rings: int, segments: int):
    th = np.pi * np.arange(1, rings) / rings
    ph = 2 * np.pi * np.arange(segments) / segments
    T, P = np.meshgrid(th, ph, indexing="ij")
    ring_pts = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    v = np.vstack([[0, 0, 1], ring_pts, [0, 0, -1]]) * radius + np.asarray(center)
    idx = lambda k, s: 1 + (k - 1) * segments + (s % segments)  # noqa: E731
    faces = [[0, idx(1, s), idx(1, s + 1)] for s in range(segments)]
    for k in range(1, rings - 1):
        for s in range(segments):
            faces += [[idx(k, s), idx(k + 1, s), idx(k + 1, s + 1)], [idx(k, s), idx(k + 1, s + 1), idx(k, s + 1)]]
    south = len(v) - 1
    faces += [[south, idx(rings - 1, s + 1), idx(rings - 1, s)] for s in range(segments)]
    return v, np.array(faces)


def downward_camera(height: float, x: float = 0.5, y: float = 0.0) -> np.ndarray:
    """T_base_camera looking straight down at (x, y, 0) from `height` m (camera x = base x)."""
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T[:3, 3] = [x, y, height]
    return T


def table_only(size: float = 3.0) -> syn.Scene:
    return syn.Scene(table_size=(size, size), table_center=(0.5, 0.0))


@pytest.fixture(scope="module")
def exact_scan() -> syn.SyntheticScan:
    """The built-in part, noise-free, float32 depth, with ground-truth face ids (8 frames)."""
    cfg = syn.SyntheticConfig(n_frames=8, noise="none", depth_unit=0.0)
    return cfg.build(keep_ground_truth=True)


# --------------------------------------------------------------------------- renderer


def test_plane_depth_equals_analytic_depth():
    # A tilted square 2 m wide, seen from a general pose.
    n_world = np.array([0.2, -0.3, 1.0]) / np.linalg.norm([0.2, -0.3, 1.0])
    p0 = np.array([0.4, 0.1, 0.02])
    v, f = quad(p0, n_world, 2.0)
    # Camera 0.5 m above the plane, shifted sideways, looking at p0 (built here, not with
    # the code under test), then rolled by 0.4 rad about its optical axis.
    eye = p0 + 0.5 * n_world + np.array([0.1, 0.05, 0.0])
    z = (p0 - eye) / np.linalg.norm(p0 - eye)
    x = np.cross(z, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    T_world_camera = np.eye(4)
    T_world_camera[:3, :3] = np.column_stack([x, np.cross(z, x), z]) @ rigid((0, 0, 1), 0.4, (0, 0, 0))[:3, :3]
    T_world_camera[:3, 3] = eye
    T_camera_world = np.linalg.inv(T_world_camera)
    r = rendering.render_depth(v, f, K_SR300, T_camera_world)
    n_c = T_camera_world[:3, :3] @ n_world
    d_c = n_c @ (T_camera_world[:3, :3] @ p0 + T_camera_world[:3, 3])
    R = rays(K_SR300)
    z_true = d_c / (R @ n_c)
    assert r.depth.dtype == np.float32 and r.face_id.dtype == np.int32 and r.depth.shape == K_SR300.shape
    assert np.all(r.hit), "the plane fills the image: no holes on the diagonal"
    assert np.abs(r.depth - z_true).max() < 1e-6
    cos_true = np.abs(R @ n_c) / np.linalg.norm(R, axis=-1)
    assert np.abs(np.abs(r.cos_incidence) - cos_true).max() < 1e-6
    # Back-projected pixels lie on the plane.
    pts = R * r.depth[..., None].astype(np.float64)
    assert np.abs(pts @ n_c - d_c).max() < 1e-6


def test_backprojected_pixels_lie_on_their_faces(exact_scan):
    mesh = exact_scan.mesh
    K = exact_scan.intrinsics
    R = rays(K)
    on_object = 0
    for frame in exact_scan.frames[::2]:
        fid = frame.meta["face_id"]
        hit = fid >= 0
        z = frame.depth.astype(np.float64)
        assert np.array_equal(np.isfinite(z), hit)  # noise "none": every hit is a measurement
        p_cam = R[hit] * z[hit][:, None]
        T = frame.T_base_camera
        p = p_cam @ T[:3, :3].T + T[:3, 3]
        tri = mesh.vertices[mesh.faces[fid[hit]]]  # (N, 3, 3)
        e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        n = np.cross(e1, e2)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        dist = np.abs(np.einsum("ij,ij->i", p - tri[:, 0], n))
        assert dist.max() < 1e-5, dist.max()
        # ... and inside their triangle (barycentric coordinates, up to float32 depth rounding).
        w = p - tri[:, 0]
        d00, d01, d11 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
        d20, d21 = (w * e1).sum(1), (w * e2).sum(1)
        den = d00 * d11 - d01 * d01
        b1 = (d11 * d20 - d01 * d21) / den
        b2 = (d00 * d21 - d01 * d20) / den
        edge_len = np.sqrt(np.maximum(d00, d11))
        slack = 1e-6 / edge_len  # 1 um relative to the triangle's size
        assert np.all(b1 >= -slack) and np.all(b2 >= -slack) and np.all(b1 + b2 <= 1 + slack)
        on_object += int(np.sum(exact_scan.scene.face_object[fid[hit]] >= 0))
    assert on_object > 4 * 3000  # the part is seen in every frame


def test_sphere_silhouette_and_depth_match_ray_casting():
    c = np.array([0.03, -0.02, 0.5])
    radius = 0.1
    rings, segments = 90, 180
    v, f = uv_sphere(c, radius, rings, segments)
    r = rendering.render_depth(v, f, K_SR300, np.eye(4))
    d = rays(K_SR300)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    bq = d @ c
    disc = bq**2 - (c @ c - radius**2)
    inside = disc >= 0
    assert not np.any(r.hit & ~inside), "the inscribed mesh never covers pixels outside the sphere"
    t = bq - np.sqrt(np.where(inside, disc, 0.0))
    z_true = t * d[..., 2]
    cos_true = -np.einsum("hwk,hwk->hw", d, (t[..., None] * d - c) / radius)
    # Silhouette: every pixel clearly inside the sphere's outline is hit (the polygonal
    # outline is inset by at most the sagitta, a small fraction of a pixel here).
    assert np.all(r.hit[inside & (cos_true > 0.1)])
    sagitta = radius * (1 - math.cos(math.pi / rings) * math.cos(math.pi / segments))
    m = r.hit & (cos_true > 0.2)
    err = r.depth[m] - z_true[m]
    assert err.min() > -1e-6  # never in front of the sphere
    assert np.all(err <= sagitta / (cos_true[m] - 0.04) * d[..., 2][m] + 1e-6)
    assert abs(int(r.hit.sum()) - int(inside.sum())) < 0.01 * inside.sum()


def test_render_depth_near_plane_clips_and_far_limits():
    # A floor below the camera reaching behind it: only what lies beyond `near` is drawn.
    v = np.array([[-3.0, 0.1, -1.0], [3.0, 0.1, -1.0], [3.0, 0.1, 5.0], [-3.0, 0.1, 5.0]])
    f = np.array([[0, 1, 2], [0, 2, 3]])
    R = rays(K_SR300)
    with np.errstate(divide="ignore"):
        z_true = np.where(R[..., 1] > 0, 0.1 / R[..., 1], np.inf)
    r = rendering.render_depth(v, f, K_SR300, np.eye(4), near=0.3, far=4.0)
    clear = (z_true > 0.31) & (z_true < 3.9) & (np.abs(R[..., 0] * z_true) < 2.9)
    assert np.all(r.hit[clear])
    assert np.abs(r.depth[clear] - z_true[clear]).max() < 1e-5
    assert not np.any(r.hit & ((z_true < 0.29) | (z_true > 4.1)))


def test_render_depth_rejects_bad_input():
    v, f = quad((0, 0, 1), (0, 0, -1), 1.0)
    with pytest.raises(TypeError):
        rendering.render_depth(v.astype(np.int64), f, K_SR300, np.eye(4))
    with pytest.raises(TypeError):
        rendering.render_depth(v, f.astype(float), K_SR300, np.eye(4))
    with pytest.raises(TypeError):
        rendering.render_depth(v, f, (640, 480, 500, 500, 320, 240), np.eye(4))
    distorted = Intrinsics(**{**K_SR300.to_dict(), "distortion": (0.1, 0, 0, 0, 0)})
    with pytest.raises(ValueError, match="pinhole"):
        rendering.render_depth(v, f, distorted, np.eye(4))
    with pytest.raises(ValueError, match="faces"):
        rendering.render_depth(v, f + 2, K_SR300, np.eye(4))
    with pytest.raises(ValueError, match="faces"):
        rendering.render_depth(v, f - 1, K_SR300, np.eye(4))
    with pytest.raises(ValueError):
        rendering.render_depth(v[:, :2], f, K_SR300, np.eye(4))
    with pytest.raises(ValueError):
        rendering.render_depth(v, f, K_SR300, np.eye(3))
    T = np.eye(4)
    T[0, 3] = np.nan
    with pytest.raises(ValueError):
        rendering.render_depth(v, f, K_SR300, T)
    with pytest.raises(ValueError, match="orthonormal"):
        rendering.render_depth(v, f, K_SR300, np.diag([2.0, 1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="bottom row"):
        rendering.render_depth(v, f, K_SR300, np.eye(4) + np.eye(4, k=-3))
    with pytest.raises(ValueError, match="near"):
        rendering.render_depth(v, f, K_SR300, np.eye(4), near=0.0)
    with pytest.raises(ValueError, match="far"):
        rendering.render_depth(v, f, K_SR300, np.eye(4), near=1.0, far=0.5)
    with pytest.raises(ValueError):
        rendering.render_depth(v, f, "no_such_camera", np.eye(4))
    # The compiled core's own checks: a C++ std::invalid_argument arrives as ValueError.
    from scanalign import _core

    with pytest.raises(ValueError):
        _core.reconstruction.render_depth(v, f.astype(np.int32) + 5, Intrinsics(64, 48, 50.0, 50.0, 32.0, 24.0),
                                          np.eye(4), _core.reconstruction.DepthRenderSettings())
    with pytest.raises(ValueError):
        _core.reconstruction.render_depth(v, f.astype(np.int32), Intrinsics(64, 48, -50.0, 50.0, 32.0, 24.0),
                                          np.eye(4), _core.reconstruction.DepthRenderSettings())
    # An empty mesh is fine: nothing is hit.
    r = rendering.render_depth(v, np.zeros((0, 3), np.int32), K_SR300, np.eye(4))
    assert not r.hit.any() and np.isnan(r.depth).all()


def test_production_modules_do_not_import_the_simulator_or_the_downloader():
    import os
    import subprocess
    import sys

    code = ("import sys, scanalign.reconstruction.rendering, scanalign.data.parts; "
            "print(sorted(m for m in sys.modules if m.startswith(('scanalign.synthetic', 'scanalign.data.downloads'))))")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}  # the scanalign under test
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True, env=env).stdout
    assert out.strip() == "[]"
    # The simulator's names are the production ones, re-exported.
    assert syn.render_depth is rendering.render_depth and syn.look_at is rendering.look_at
    assert syn.builtin_mesh is parts.builtin_mesh and syn.normalize_mesh is parts.normalize_mesh


# --------------------------------------------------------------------------- meshes and scene


def test_builtin_mesh_is_a_closed_part_on_the_analytic_surfaces():
    m = parts.builtin_mesh()
    assert 2000 <= len(m.faces) <= 6000
    # Watertight and consistently wound: every directed edge appears once, its reverse once.
    e = np.concatenate([m.faces[:, [0, 1]], m.faces[:, [1, 2]], m.faces[:, [2, 0]]])
    directed = {tuple(x) for x in e.tolist()}
    assert len(directed) == len(e)
    assert all((b, a) in directed for a, b in directed)
    c = m.vertices[m.faces]
    volume = np.einsum("ij,ij->i", c[:, 0], np.cross(c[:, 1], c[:, 2])).sum() / 6
    h, R = 0.006, 0.015
    analytic = 0.08 * 0.05 * 0.03 + math.pi * 0.012**2 * 0.015 + math.pi * h * h * (3 * R - h) / 3
    assert volume == pytest.approx(analytic, rel=2e-3)  # outward winding: positive volume
    np.testing.assert_allclose(m.vertices.min(0), [-0.04, -0.025, -0.015], atol=1e-12)
    np.testing.assert_allclose(m.vertices.max(0), [0.04, 0.025, 0.030], atol=1e-12)
    # Every vertex lies on one of the part's analytic surfaces (documented in scanalign.data.parts).
    p = m.vertices
    on_box = (np.isclose(np.abs(p[:, 0]), 0.04, atol=1e-12) | np.isclose(np.abs(p[:, 1]), 0.025, atol=1e-12)
              | np.isclose(np.abs(p[:, 2]), 0.015, atol=1e-12)) & np.all(np.abs(p) <= [0.04, 0.025, 0.015 + 1e-12], 1)
    boss_r = np.hypot(p[:, 0] + 0.015, p[:, 1])
    on_boss = ((np.isclose(boss_r, 0.012, atol=1e-12) & (p[:, 2] >= 0.015 - 1e-12))
               | (np.isclose(p[:, 2], 0.030, atol=1e-12) & (boss_r <= 0.012 + 1e-12)))
    on_cap = (np.isclose(np.linalg.norm(p - [0.020, 0.006, 0.006], axis=1), 0.015, atol=1e-12)
              & (p[:, 2] >= 0.015 - 1e-12))
    assert np.all(on_box | on_boss | on_cap)


def test_scene_places_objects_on_the_table_and_exposes_the_mesh():
    scene = syn.Scene(table_size=(0.6, 0.4), table_center=(0.5, 0.1))
    part = parts.builtin_mesh()
    obj = scene.add_object(part, position=(0.45, 0.05), yaw=0.7, color=(0.2, 0.4, 0.9))
    om = scene.object_mesh
    assert om.vertices[:, 2].min() == pytest.approx(0.0, abs=1e-12)  # standing on the table
    lo, hi = om.vertices.min(0), om.vertices.max(0)
    np.testing.assert_allclose((lo[:2] + hi[:2]) / 2, [0.45, 0.05], atol=1e-12)
    # The base-frame mesh is the object mesh moved by T_base_object (same vertex set).
    moved = part.vertices @ obj.T_base_object[:3, :3].T + obj.T_base_object[:3, 3]
    assert np.allclose(np.sort(moved, axis=0), np.sort(om.vertices, axis=0), atol=1e-12)
    full = scene.mesh
    assert len(full.faces) == len(part.faces) + 2
    owner = scene.face_object
    assert np.sum(owner == -1) == 2 and np.all(owner[: len(part.faces)] == 0)
    # face_source maps the reordered faces back to the part's own faces.
    src = scene.face_source[: len(part.faces)]
    back = full.vertices[full.faces[: len(part.faces)]]
    ref = moved[part.faces[src]]
    np.testing.assert_allclose(back, ref, atol=1e-12)
    np.testing.assert_allclose(scene.center, [0.45, 0.05, 0.0], atol=1e-12)
    with pytest.raises(TypeError):
        scene.add_object((part.vertices, part.faces))
    with pytest.raises(ValueError):
        scene.add_object(part, np.eye(4), position=(0.0, 0.0))
    with pytest.raises(ValueError):
        scene.add_object(part, color=(2.0, 0.0, 0.0))
    with pytest.raises(ValueError):
        syn.Scene(table_size=(0.0, 1.0))


def test_normalize_mesh_scales_and_sets_on_the_table():
    v = np.array([[10.0, 20.0, 30.0], [110.0, 20.0, 30.0], [10.0, 70.0, 30.0], [10.0, 20.0, 80.0]])
    m = parts.normalize_mesh(sio.Mesh(v, [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]), 0.15)
    np.testing.assert_allclose(np.ptp(m.vertices, axis=0), [0.15, 0.075, 0.075])
    np.testing.assert_allclose(m.vertices.min(0), [-0.075, -0.0375, 0.0])
    with pytest.raises(ValueError):
        parts.normalize_mesh(m, -1.0)


def test_rgb_is_registered_shaded_colour():
    scan = syn.SyntheticConfig(n_frames=2, noise="none").build(keep_ground_truth=True)
    frame = scan.frames[0]
    fid = frame.meta["face_id"]
    owner = scan.scene.face_object
    rgb = frame.rgb.astype(int)
    assert frame.rgb.dtype == np.uint8 and frame.rgb.shape == (480, 640, 3)
    obj = np.zeros(fid.shape, bool)
    obj[fid >= 0] = owner[fid[fid >= 0]] >= 0
    table = (fid >= 0) & ~obj
    assert obj.sum() > 3000 and table.sum() > 100000
    # The part is orange (r > g > b), the table grey (channels within a few levels), the void black.
    assert np.all(rgb[obj][:, 0] > rgb[obj][:, 1]) and np.all(rgb[obj][:, 1] > rgb[obj][:, 2])
    assert np.ptp(rgb[table], axis=1).max() < 0.15 * 255
    assert np.all(rgb[fid < 0] == 0)
    # The checker has both colours on the table.
    brightness = rgb[table].mean(axis=1)
    assert brightness.max() - brightness.min() > 50


# --------------------------------------------------------------------------- trajectories


def optical_axis_distance(T_base_camera: np.ndarray, point: np.ndarray) -> float:
    """Distance (m) from `point` to the camera's optical axis (ray along camera z)."""
    o, z = T_base_camera[:3, 3], T_base_camera[:3, 2]
    w = point - o
    assert w @ z > 0, "target behind the camera"
    return float(np.linalg.norm(w - (w @ z) * z))


def test_loop_trajectory_circles_and_looks_at_the_object():
    center = np.array([0.52, -0.03, 0.0])
    traj = syn.loop_trajectory(24, center=center, height=0.40, radius=0.20, start_angle=0.5)
    T = traj.T_base_camera
    assert T.shape == (24, 4, 4) and len(traj) == 24
    pos = T[:, :3, 3]
    np.testing.assert_allclose(pos[:, 2], 0.40, atol=1e-12)  # 40 cm above the table
    rel = pos[:, :2] - center[:2]
    np.testing.assert_allclose(np.linalg.norm(rel, axis=1), 0.20, atol=1e-12)
    az = np.unwrap(np.arctan2(rel[:, 1], rel[:, 0]))
    np.testing.assert_allclose(np.diff(az), 2 * np.pi / 24, atol=1e-12)  # a full loop, evenly spaced
    assert az[0] == pytest.approx(0.5)
    for Tk in T:
        assert optical_axis_distance(Tk, center) < 1e-9
        R = Tk[:3, :3]
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
        assert np.linalg.det(R) == pytest.approx(1.0)
        assert -R[2, 1] > 0  # image up (camera -y) points upwards: no upside-down frames
    # Tilt towards the object: angle from the vertical = atan(radius / height).
    tilt = np.arccos(-T[:, 2, 2])
    np.testing.assert_allclose(tilt, math.atan2(0.20, 0.40), atol=1e-12)
    np.testing.assert_allclose(traj.timestamps, np.arange(24) * 0.1)  # 10 Hz
    ref = traj.reference
    assert isinstance(ref, Trajectory) and np.allclose(ref.poses, T)


def test_hand_eye_composition():
    T_flange_camera = rigid((0.2, -1.0, 0.5), 0.3, (0.02, -0.04, 0.08))
    center = np.array([0.5, 0.0, 0.0])
    traj = syn.loop_trajectory(6, center=center, T_flange_camera=T_flange_camera)
    np.testing.assert_allclose(traj.T_flange_camera, T_flange_camera)
    for Tbf, Tbc in zip(traj.T_base_flange, traj.T_base_camera):
        np.testing.assert_allclose(Tbf @ T_flange_camera, Tbc, atol=1e-12)
        # It is the camera, not the flange, that looks at the object.
        assert optical_axis_distance(Tbc, center) < 1e-9
        assert np.linalg.norm(Tbf[:3, 3] - Tbc[:3, 3]) == pytest.approx(np.linalg.norm(T_flange_camera[:3, 3]))
    scene = table_only()
    scene.add_object(parts.builtin_mesh(), position=(0.5, 0.0))
    scan = syn.render_scan(scene, traj, "sr300", "none", depth_unit=None, keep_ground_truth=True)
    np.testing.assert_allclose(scan.T_flange_camera, T_flange_camera)
    for k, frame in enumerate(scan.frames):
        np.testing.assert_allclose(frame.meta["T_base_flange"] @ T_flange_camera, frame.T_base_camera, atol=1e-12)
        np.testing.assert_array_equal(frame.T_base_camera, scan.reference.poses[k])
    # The frame really is rendered from T_base_flange @ T_flange_camera.
    again = scene.render(traj.T_base_flange[2] @ T_flange_camera, "sr300")
    np.testing.assert_array_equal(again.face_id, scan.frames[2].meta["face_id"])
    # Default hand-eye: camera 5 cm in front of the flange, rotated by a few degrees only.
    D = syn.DEFAULT_T_FLANGE_CAMERA
    assert D[2, 3] == pytest.approx(0.05)
    angle = math.degrees(math.acos((np.trace(D[:3, :3]) - 1) / 2))
    assert 1.0 < angle < 6.0


def test_hemisphere_trajectory_rings():
    center = np.array([0.5, 0.1, 0.0])
    elev = np.radians([30.0, 50.0, 70.0])
    traj = syn.hemisphere_trajectory(40, center=center, distance=0.45, elevations=elev)
    T = traj.T_base_camera
    assert len(T) == 40
    rel = T[:, :3, 3] - center
    np.testing.assert_allclose(np.linalg.norm(rel, axis=1), 0.45, atol=1e-12)
    e = np.arcsin(rel[:, 2] / 0.45)
    rings = [np.isclose(e, x, atol=1e-9) for x in elev]
    assert np.all(np.sum(rings, axis=0) == 1)  # every pose on one of the rings
    counts = [int(r.sum()) for r in rings]
    assert counts[0] > counts[1] > counts[2] >= 1 and sum(counts) == 40  # more frames on wider rings
    for Tk in T:
        assert optical_axis_distance(Tk, center) < 1e-9
    # One continuous path: no jump larger than the widest ring's step plus the ring spacing.
    step = np.linalg.norm(np.diff(T[:, :3, 3], axis=0), axis=1)
    assert step.max() < 0.45 * (2 * np.pi / counts[0]) + 0.45 * np.radians(20.0) + 1e-9
    with pytest.raises(ValueError):
        syn.hemisphere_trajectory(2, elevations=elev)
    with pytest.raises(ValueError):
        syn.hemisphere_trajectory(10, elevations=[0.0])


def test_look_at_and_trajectory_errors():
    T = rendering.look_at([0.0, 0.0, 1.0], [1.0, 0.0, 1.0])
    np.testing.assert_allclose(T[:3, 2], [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(T[:3, 1], [0, 0, -1], atol=1e-15)  # image down = world down
    with pytest.raises(ValueError):
        rendering.look_at([0, 0, 0], [0, 0, 0])
    with pytest.raises(ValueError):
        rendering.look_at([0, 0, 1], [0, 0, 0])  # straight down with up = +z: roll undefined
    with pytest.raises(ValueError):
        syn.loop_trajectory(0)
    with pytest.raises(ValueError):
        syn.loop_trajectory(10, height=-0.1)
    with pytest.raises(ValueError):
        syn.loop_trajectory(10, T_flange_camera=np.diag([1.0, 1.0, 2.0, 1.0]))
    straight_down = syn.loop_trajectory(3, radius=0.0)  # the azimuth fixes the roll
    assert np.allclose(straight_down.T_base_camera[:, :3, 2], [0, 0, -1])


# --------------------------------------------------------------------------- sensor noise


@pytest.mark.parametrize("preset", ["sr300", "d435", "zivid"])
def test_noise_std_at_known_depth_matches_preset(preset):
    model = syn.NOISE_PRESETS[preset]
    z0 = 0.5
    scan = syn.render_scan(table_only(), downward_camera(z0), "sr300", preset, seed=3)
    z = scan.frames[0].depth_metres().astype(np.float64)
    ok = np.isfinite(z)
    assert ok.mean() > 0.95
    residual = z[ok] - z0  # the table is exactly z0 below the camera everywhere
    expected = float(model.sigma(z0))
    assert np.std(residual) == pytest.approx(expected, rel=0.2)
    assert abs(np.mean(residual)) < 0.1 * expected + model.depth_unit
    if model.depth_unit > 0:  # reported on the sensor's grid
        q = np.round(z[ok] / model.depth_unit) * model.depth_unit
        assert np.abs(z[ok] - q).max() < 1e-7  # float32 rounding of depth_metres()
    # The documented constants: SR300 ~1 mm at 0.4 m, D435 a few mm at 0.5 m, Zivid ~0.1 mm.
    assert {"sr300": 1.0e-3, "d435": 1.95e-3, "zivid": 1.0e-4}[preset] == pytest.approx(
        float(model.sigma({"sr300": 0.4, "d435": 0.5, "zivid": 0.5}[preset])))


def test_noise_sigma_grows_with_the_square_of_depth():
    model = syn.NOISE_PRESETS["d435"]
    stds = []
    for z0 in (0.4, 0.8):
        scan = syn.render_scan(table_only(), downward_camera(z0), "sr300", "d435", seed=11)
        z = scan.frames[0].depth_metres().astype(np.float64)
        stds.append(np.nanstd(z - z0))
    assert stds[1] / stds[0] == pytest.approx(4.0, rel=0.15)
    assert float(model.sigma(0.8)) / float(model.sigma(0.4)) == pytest.approx(4.0)


def test_dropout_at_grazing_angles():
    # A camera 0.12 m above the table looking at a point 0.6 m away: the incidence goes from
    # moderate (bottom rows) to grazing (top rows).
    T = rendering.look_at([0.0, 0.0, 0.12], [0.6, 0.0, 0.0])
    scene = table_only(4.0)
    model = syn.NOISE_PRESETS["sr300"]
    scan = syn.render_scan(scene, T, "sr300", "sr300", seed=5, keep_ground_truth=True)
    frame = scan.frames[0]
    truth = frame.meta["depth_true"].astype(np.float64)
    measured = np.isfinite(frame.depth_metres())
    # Analytic incidence on the table: normal +z in the base frame, seen along each pixel ray.
    R = rays(frame.intrinsics)
    d_base = R @ T[:3, :3].T
    cos_true = np.abs(d_base[..., 2]) / np.linalg.norm(d_base, axis=-1)
    seen = np.isfinite(truth) & (truth > model.min_range * 1.1) & (truth < model.max_range * 0.9)
    grazing = seen & (cos_true < model.grazing_cos - 0.005)
    frontal = seen & (cos_true > model.grazing_cos + 0.05)
    assert grazing.sum() > 1000 and frontal.sum() > 1000
    assert not measured[grazing].any()
    assert measured[frontal].mean() > 0.98  # only random dropout and edges elsewhere
    clean = syn.render_scan(scene, T, "sr300", "none", keep_ground_truth=True).frames[0]
    assert np.isfinite(clean.depth_metres())[grazing].all()  # it is the noise model that drops them


def test_depth_range_is_clipped():
    for preset, inside, outside in [("sr300", 1.2, [0.15, 1.7]), ("zivid", 0.6, [0.25, 1.3])]:
        model = syn.NOISE_PRESETS[preset]
        assert model.min_range < inside < model.max_range
        frame = syn.render_scan(table_only(6.0), downward_camera(inside), "sr300", preset).frames[0]
        assert np.isfinite(frame.depth_metres()).mean() > 0.95
        for z0 in outside:
            frame = syn.render_scan(table_only(6.0), downward_camera(z0), "sr300", preset).frames[0]
            assert not np.isfinite(frame.depth_metres()).any(), (preset, z0)


def test_depth_edges_drop_pixels_on_both_sides():
    scene = table_only()
    scene.add_object(parts.builtin_mesh(), position=(0.5, 0.0))
    T = downward_camera(0.45)
    model = syn.NOISE_PRESETS["d435"]
    frame = syn.render_scan(scene, T, "sr300", model, keep_ground_truth=True).frames[0]
    truth = frame.meta["depth_true"]
    measured = np.isfinite(frame.depth_metres())
    # The box's top face (0.42 m) borders the table (0.45 m): a 7 % jump. Pixels next to
    # the jump, on both sides, are gone; pixels 5 px away mostly remain.
    jump = np.zeros(truth.shape, bool)
    dz = np.abs(np.diff(truth, axis=1)) > 0.05 * truth[:, 1:]
    jump[:, 1:] |= dz
    jump[:, :-1] |= dz
    assert jump.sum() > 100
    assert not measured[jump].any()
    far = np.zeros_like(jump)
    for s in (5, -5):
        far |= np.roll(jump, s, axis=1)
    far &= ~jump & np.isfinite(truth)
    assert measured[far].mean() > 0.9


def test_same_seed_gives_identical_frames_and_other_seeds_differ():
    cfg = syn.SyntheticConfig(n_frames=3, noise="d435", seed=7, resolution_scale=0.5)
    a, b = cfg.build(), cfg.build()
    for fa, fb in zip(a.frames, b.frames):
        assert fa.depth.tobytes() == fb.depth.tobytes()
        assert fa.rgb.tobytes() == fb.rgb.tobytes()
    c = syn.SyntheticConfig(n_frames=3, noise="d435", seed=8, resolution_scale=0.5).build()
    for fa, fc in zip(a.frames, c.frames):
        assert not np.array_equal(fa.depth, fc.depth)
    # A frame does not depend on how many frames are rendered, nor on the worker count.
    scene = a.scene
    poses = a.reference.poses
    one = syn.render_scan(scene, poses[:1], a.intrinsics, "d435", seed=7, num_threads=1)
    assert one.frames[0].depth.tobytes() == a.frames[0].depth.tobytes()


def test_frames_of_one_scan_draw_independent_noise():
    # The same pose twice in one scan: same clean depth, different noise realisations.
    T = downward_camera(0.5)
    scan = syn.render_scan(table_only(), np.stack([T, T]), "sr300", "sr300", seed=1, depth_unit=None)
    a, b = (f.depth.astype(np.float64) for f in scan.frames)
    both = np.isfinite(a) & np.isfinite(b)
    corr = np.corrcoef(a[both] - 0.5, b[both] - 0.5)[0, 1]
    assert abs(corr) < 0.02


def test_sensor_noise_validation():
    with pytest.raises(ValueError):
        syn.SensorNoise(axial_sigma_ref=-1.0)
    with pytest.raises(ValueError):
        syn.SensorNoise(min_range=1.0, max_range=0.5)
    with pytest.raises(ValueError):
        syn.SensorNoise(dropout=1.0)
    with pytest.raises(ValueError):
        syn.render_scan(table_only(), downward_camera(0.5), "sr300", "kinect")
    with pytest.raises(TypeError):
        syn.render_scan(table_only(), downward_camera(0.5), "sr300", 3)


# --------------------------------------------------------------------------- scans and config


def test_scan_frames_and_reference():
    scan = syn.builtin_scan(n_frames=12, noise="sr300", seed=1)
    assert len(scan) == 12 and len(scan.reference) == 12
    for k, frame in enumerate(scan.frames):
        assert isinstance(frame, Frame)
        assert frame.depth.dtype == np.uint16 and frame.depth.shape == (480, 640)
        assert frame.depth_scale == pytest.approx(0.000125)  # the SR300 preset's own unit
        assert frame.rgb.shape == (480, 640, 3)
        assert frame.index == k and frame.timestamp == pytest.approx(0.1 * k)
        np.testing.assert_array_equal(frame.T_base_camera, scan.reference.poses[k])
        z = frame.depth_metres()
        assert 0.7 < np.isfinite(z).mean() < 1.0
        assert 0.3 < np.nanmin(z) and np.nanmax(z) < 0.8
    # Points in the base frame land on the scene's surfaces: near z = 0 (table) or on the part.
    p = scan.points(0, in_base=True)
    assert np.all(p[:, 2] > -0.01) and np.all(p[:, 2] < 0.055)  # the part is 45 mm tall with its boss
    assert scan.T_flange_camera is not None and scan.T_base_flange.shape == (12, 4, 4)
    assert len(scan.object_mesh.faces) == len(parts.builtin_mesh().faces)


def test_depth_storage_float_and_uint16_agree():
    scene = table_only()
    T = downward_camera(0.5123456)
    f32 = syn.render_scan(scene, T, "sr300", "none", depth_unit=None).frames[0]
    u16 = syn.render_scan(scene, T, "sr300", "none", depth_unit=1e-4).frames[0]
    assert f32.depth.dtype == np.float32 and u16.depth.dtype == np.uint16
    assert np.nanmax(np.abs(f32.depth - 0.5123456)) < 1e-6
    assert np.nanmax(np.abs(u16.depth_metres() - f32.depth)) <= 0.5e-4 + 1e-7
    with pytest.raises(ValueError):
        syn.render_scan(scene, T, "sr300", "none", depth_unit=0.0)
    with pytest.raises(ValueError):
        syn.render_scan(scene, np.eye(3), "sr300", "none")
    with pytest.raises(TypeError):
        syn.render_scan("scene", T, "sr300", "none")


def test_config_files_roundtrip_and_build(tmp_path):
    cfg = syn.SyntheticConfig(n_frames=5, trajectory="hemisphere", rings=2, noise="zivid", seed=4,
                              resolution_scale=0.5, object_yaw=0.1)
    path = tmp_path / "scan.json"
    cfg.to_json(path)
    assert json.loads(path.read_text())["trajectory"] == "hemisphere"
    again = syn.SyntheticConfig.from_file(path)
    assert again == cfg
    yaml = tmp_path / "scan.yaml"
    yaml.write_text("# synthetic scan\nmesh: builtin\nn_frames: 4\ntrajectory: loop\nheight: 0.35\n"
                    "radius: 0.15\nintrinsics: d435\nresolution_scale: 0.5\nnoise: d435\nseed: 2\n"
                    "object_size: null\n")
    y = syn.SyntheticConfig.from_file(yaml)
    assert (y.n_frames, y.height, y.intrinsics, y.noise, y.object_size) == (4, 0.35, "d435", "d435", None)
    scan = y.build()
    assert len(scan.frames) == 4 and scan.frames[0].depth.shape == (240, 320)
    np.testing.assert_allclose(scan.reference.poses[:, 2, 3], 0.35, atol=1e-12)
    assert scan.noise.name == "d435" and scan.seed == 2
    with pytest.raises(ValueError, match="unknown synthetic config keys"):
        syn.SyntheticConfig.from_dict({"n_frame": 3})
    with pytest.raises(ValueError):
        syn.SyntheticConfig(trajectory="spiral")
    with pytest.raises(ValueError):
        syn.SyntheticConfig(noise="kinect")
    with pytest.raises(ValueError):
        syn.SyntheticConfig(n_frames=0)
    with pytest.raises(FileNotFoundError):
        syn.SyntheticConfig(mesh="no/such/file.ply").load_mesh()


def test_config_reads_a_mesh_file(tmp_path):
    # An OFF file in millimetres (a 40 x 20 x 10 box), scaled to 0.1 m and put on the table.
    v = np.array([[x, y, z] for z in (0, 10) for y in (0, 20) for x in (0, 40)], float)
    faces = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    path = tmp_path / "box.off"
    path.write_text("OFF\n8 6 0\n" + "".join(f"{a} {b} {c}\n" for a, b, c in v)
                    + "".join("4 " + " ".join(map(str, f)) + "\n" for f in faces))
    cfg = syn.SyntheticConfig(mesh=str(path), object_size=0.1, n_frames=2, noise="none", resolution_scale=0.5)
    scan = cfg.build()
    ext = np.ptp(scan.scene.objects[0].mesh.vertices, axis=0)  # in the object's own frame
    np.testing.assert_allclose(np.sort(ext), [0.025, 0.05, 0.1], atol=1e-12)
    assert scan.object_mesh.vertices[:, 2].min() == pytest.approx(0.0, abs=1e-12)


def test_camera_files_json_and_yaml(tmp_path):
    from scanalign.reconstruction.camera import read_camera_file

    # OpenCV writes a "%YAML:1.0" first line (a directive YAML parsers reject); YAML 1.1 reads
    # "1e-3" without a dot as text: both are handled.
    (tmp_path / "cv.yaml").write_text("%YAML:1.0\n---\n# camera\nwidth: 640\nheight: 480\nfx: 5.25e2\n"
                                      "fy: 525\ncx: 319.5\ncy: 239.5\ndepth_scale: 1e-3\nname: 'sr300'\n")
    d = read_camera_file(tmp_path / "cv.yaml")
    assert d == {"width": 640, "height": 480, "fx": 525.0, "fy": 525, "cx": 319.5, "cy": 239.5,
                 "depth_scale": 1e-3, "name": "sr300"}
    assert read_camera(tmp_path / "cv.yaml")[0] == Intrinsics(640, 480, 525.0, 525.0, 319.5, 239.5)
    (tmp_path / "cam.json").write_text(json.dumps({"width": 64, "height": 48, "fx": 50, "fy": 50, "cx": 31.5,
                                                   "cy": 23.5}))
    assert read_camera(tmp_path / "cam.json")[0].shape == (48, 64)
    for name, text in (("list.yaml", "- 1\n- 2\n"), ("bad.yaml", "a: [1\n"), ("bad.json", "{\"a\": 1,}")):
        (tmp_path / name).write_text(text)
        with pytest.raises(ValueError, match=name):
            read_camera_file(tmp_path / name)
    with pytest.raises(ValueError, match="focal length"):
        Intrinsics(64, 48, 0.0, 50.0, 31.5, 23.5)


def test_sensor_noise_is_read_only_and_validated():
    sr300 = syn.NOISE_PRESETS["sr300"]
    with pytest.raises(AttributeError):
        sr300.axial_sigma_ref = 0.0  # the presets are shared
    custom = syn.SensorNoise(name="mine", axial_sigma_ref=0.002, z_ref=0.5, edge_width=2)
    assert (custom.name, custom.axial_sigma_ref, custom.edge_width, custom.max_range) == ("mine", 0.002, 2, math.inf)
    np.testing.assert_allclose(custom.sigma([0.5, 1.0]), [0.002, 0.008])
    for field, value in (("z_ref", 0.0), ("grazing_cos", 1.0), ("edge_width", -1), ("depth_unit", math.nan)):
        with pytest.raises(ValueError, match=field):
            syn.SensorNoise(**{field: value})


@pytest.mark.data
@pytest.mark.parametrize("name", ["bunny00", "fandisk"])
def test_cgal_mesh_scene(name, dataset_cache):
    cfg = syn.SyntheticConfig(mesh=name, object_size=0.15, n_frames=3, noise="none", depth_unit=0.0)
    scan = cfg.build(keep_ground_truth=True)
    om = scan.object_mesh
    assert np.ptp(scan.scene.objects[0].mesh.vertices, axis=0).max() == pytest.approx(0.15)
    assert om.vertices[:, 2].min() == pytest.approx(0.0, abs=1e-12)
    owner = scan.scene.face_object
    for frame in scan.frames:
        fid = frame.meta["face_id"]
        assert np.sum(owner[fid[fid >= 0]] >= 0) > 10000  # a 15 cm object at ~0.45 m
    # Back-projected object pixels lie on the visible face's plane.
    frame = scan.frames[1]
    fid = frame.meta["face_id"]
    hit = fid >= 0
    p_cam = rays(scan.intrinsics)[hit] * frame.depth.astype(np.float64)[hit][:, None]
    T = frame.T_base_camera
    p = p_cam @ T[:3, :3].T + T[:3, 3]
    tri = scan.mesh.vertices[scan.mesh.faces[fid[hit]]]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    assert np.abs(np.einsum("ij,ij->i", p - tri[:, 0], n)).max() < 1e-5


def test_demo_scan_is_fast():
    import time

    parts.builtin_mesh()  # built once per process
    t = time.perf_counter()
    scan = syn.builtin_scan(n_frames=36, noise="sr300", seed=0)
    elapsed = time.perf_counter() - t
    assert len(scan.frames) == 36
    assert elapsed < 10.0, f"36 frames took {elapsed:.1f} s"  # ~1 s on the 2-core dev machine

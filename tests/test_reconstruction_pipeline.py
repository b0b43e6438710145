"""Frame-to-model reconstruction: depth -> cloud, the Reconstructor, bad input.

The scene here is ray-cast exactly in the test (a table with spheres), independent of
the library's renderer; end-to-end runs on the synthetic scanner are in
test_reconstruction_synthetic.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from scanalign.reconstruction.camera import Frame, Intrinsics
from scanalign.reconstruction import (
    Reconstructor,
    depth_to_cloud,
    frame_to_cloud,
    make_reconstruction_settings,
)

K = Intrinsics(320, 240, 240.0, 242.0, 159.5, 119.5)
SPHERES = [((0.0, 0.0, 0.03), 0.03), ((0.04, 0.01, 0.02), 0.02), ((-0.02, 0.04, 0.015), 0.015),
           ((0.01, -0.045, 0.025), 0.018)]


def look_at(eye, target=(0.0, 0.0, 0.02)) -> np.ndarray:
    eye = np.asarray(eye, float)
    z = np.asarray(target, float) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(z, x), z, eye
    return T


def loop_pose(i: int, n: int) -> np.ndarray:
    a = 2 * np.pi * i / n
    return look_at([0.25 * np.cos(a), 0.25 * np.sin(a), 0.35])


def ray_cast(T_world_camera: np.ndarray, intr: Intrinsics = K) -> tuple:
    """Exact depth (m, 0 = miss) and a colour image: the table is grey, spheres red."""
    v, u = np.mgrid[0:intr.height, 0:intr.width]
    d = np.stack([(u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy, np.ones(u.shape)], -1).reshape(-1, 3)
    dw = d @ T_world_camera[:3, :3].T
    o = T_world_camera[:3, 3]
    best = np.full(len(d), np.inf)
    t = -o[2] / dw[:, 2]
    hit = o + t[:, None] * dw
    on_table = (t > 0) & (np.abs(hit[:, 0]) < 0.15) & (np.abs(hit[:, 1]) < 0.15)
    best[on_table] = t[on_table]
    sphere = np.zeros(len(d), bool)
    for c, r in SPHERES:
        oc = o - np.asarray(c)
        b = dw @ oc
        cc = oc @ oc - r * r
        a = np.einsum("ij,ij->i", dw, dw)
        disc = b * b - a * cc
        ts = np.full(len(d), np.inf)
        m = disc > 0
        ts[m] = (-b[m] - np.sqrt(disc[m])) / a[m]
        closer = (ts > 0) & (ts < best)
        best[closer] = ts[closer]
        sphere |= closer
    depth = np.where(np.isfinite(best), best, 0.0).reshape(intr.height, intr.width).astype(np.float32)
    rgb = np.where(sphere[:, None], [200, 30, 30], [120, 120, 120]).reshape(intr.height, intr.width, 3).astype(np.uint8)
    return depth, rgb


def frames(n: int, noise: float = 0.0, seed: int = 0, with_rgb: bool = True) -> list:
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        T = loop_pose(i, n)
        depth, rgb = ray_cast(T)
        if noise:
            depth = np.where(depth > 0, depth + rng.normal(0, noise, depth.shape), 0).astype(np.float32)
        out.append(Frame(depth, K, rgb=rgb if with_rgb else None, timestamp=0.1 * i, T_base_camera=T, index=i))
    return out


# ---------------------------------------------------------------------------------------
# depth -> cloud
# ---------------------------------------------------------------------------------------


def test_depth_to_cloud_matches_pinhole_back_projection_for_both_dtypes():
    rng = np.random.default_rng(1)
    intr = Intrinsics(64, 48, 50.0, 52.0, 31.2, 24.7)
    mm = rng.integers(0, 3000, size=(48, 64)).astype(np.uint16)
    rgb = rng.integers(0, 255, size=(48, 64, 3)).astype(np.uint8)
    pts, cols, pix = depth_to_cloud(mm, intr, rgb=rgb, depth_scale=0.001, min_depth=0.2, max_depth=2.5,
                                    return_pixels=True)
    z = mm.astype(np.float64) * 0.001
    valid = (mm > 0) & (z >= 0.2) & (z <= 2.5)
    assert len(pts) == valid.sum()
    v, u = np.divmod(pix, 64)
    np.testing.assert_allclose(pts[:, 2], z[v, u], atol=1e-7)
    np.testing.assert_allclose(pts[:, 0], z[v, u] * (u - 31.2) / 50.0, atol=1e-6)
    np.testing.assert_allclose(pts[:, 1], z[v, u] * (v - 24.7) / 52.0, atol=1e-6)
    np.testing.assert_array_equal(cols, rgb[v, u])
    # Float metres give the same cloud; NaN is invalid.
    f = np.where(mm > 0, z, np.nan).astype(np.float32)
    pts_f, _ = depth_to_cloud(f, intr, min_depth=0.2, max_depth=2.5)
    np.testing.assert_allclose(pts_f, pts, atol=1e-6)
    # TUM scale: 5000 units per metre.
    pts_t, _ = depth_to_cloud(mm, intr, depth_scale=1 / 5000, min_depth=0.0, max_depth=10.0)
    assert np.isclose(pts_t[:, 2].max(), mm.max() / 5000, atol=1e-6)


def test_depth_to_cloud_rejects_bad_images():
    d = np.ones((48, 64), np.float32)
    intr = Intrinsics(64, 48, 50.0, 50.0, 32.0, 24.0)
    with pytest.raises(ValueError, match="64x48"):
        depth_to_cloud(np.ones((48, 63), np.float32), intr)
    with pytest.raises(ValueError, match="2-D"):
        depth_to_cloud(np.ones((48, 64, 1), np.float32), intr)
    with pytest.raises(TypeError):
        depth_to_cloud(d.astype(bool), intr)
    with pytest.raises(ValueError, match="rgb"):
        depth_to_cloud(d, intr, rgb=np.zeros((48, 64), np.uint8))
    with pytest.raises(TypeError, match="uint8"):
        depth_to_cloud(d, intr, rgb=np.zeros((48, 64, 3), np.float32))
    with pytest.raises(ValueError, match="min_depth"):
        depth_to_cloud(d, intr, min_depth=2.0, max_depth=1.0)
    with pytest.raises(ValueError, match="stride"):
        depth_to_cloud(d, intr, stride=0)
    with pytest.raises(ValueError, match="uint16"):
        depth_to_cloud(np.full((48, 64), 70000, np.int64), intr)
    # All-invalid depth is not an error: it is an empty cloud.
    pts, cols = depth_to_cloud(np.zeros((48, 64), np.uint16), intr)
    assert pts.shape == (0, 3) and cols is None


# ---------------------------------------------------------------------------------------
# Reconstructor
# ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def loop36():
    return frames(36, noise=0.0003, seed=3)


def _translation_errors(rec: Reconstructor, fr: list) -> np.ndarray:
    by_index = {r.index: r for r in rec.records}
    return np.array([np.linalg.norm(by_index[i].T_model_camera[:3, 3] - f.T_base_camera[:3, 3])
                     for i, f in enumerate(fr) if by_index[i].merged])


def test_reconstructor_tracks_a_loop_in_the_base_frame(loop36):
    rec = Reconstructor(T_model_camera0=loop36[0].T_base_camera)
    sizes = []
    for f in loop36:
        r = rec.integrate(f)
        assert r.merged, (r.index, r.status)
        sizes.append(r.model_points)
    err = _translation_errors(rec, loop36)
    assert err.max() < 0.002, err.max()  # 0.3 mm depth noise, 10 degree steps, no drift correction
    traj = rec.trajectory
    assert len(traj) == 36 and np.allclose(traj.timestamps, [f.timestamp for f in loop36])
    # Bounded model: the last 12 frames (a third of the loop) add under 15 % to it.
    assert sizes[-1] < 1.15 * sizes[23]
    # Colour survives the merge: model points near the spheres' surfaces are red, table grey.
    m = rec.model
    assert m.colors is not None and m.colors.dtype == np.uint8 and len(m.colors) == len(m)
    on_sphere = np.zeros(len(m), bool)
    for c, r in SPHERES:
        on_sphere |= np.abs(np.linalg.norm(m.points - np.asarray(c), axis=1) - r) < 0.0007
    on_table = (np.abs(m.points[:, 2]) < 0.0007) & ~on_sphere
    red = (m.colors[:, 0] > 150) & (m.colors[:, 1] < 80)
    assert red[on_sphere].mean() > 0.9 and red[on_table].mean() < 0.02
    # Normals are unit length and the table's point up (towards the cameras).
    n = m.normals[on_table]
    assert np.nanmean(n[:, 2]) > 0.95


def test_skipped_frames_do_not_change_the_model(loop36):
    rec = Reconstructor(T_model_camera0=loop36[0].T_base_camera)
    rec.integrate(loop36[0])
    rec.integrate(loop36[1])
    before = rec.model
    pose_before = rec.last_pose
    empty = Frame(np.zeros(K.shape, np.uint16), K, timestamp=9.0)
    nan = Frame(np.full(K.shape, np.nan, np.float32), K, timestamp=9.1)
    # A frame of a different scene far away: nothing within the correspondence distance.
    wall = Frame(np.full(K.shape, 0.6, np.float32), K, timestamp=9.2)
    statuses = [rec.integrate(f).status for f in (empty, nan, wall)]
    assert statuses[:2] == ["skipped_empty", "skipped_empty"]
    assert statuses[2] in ("skipped_too_few_correspondences", "skipped_low_fitness", "skipped_motion")
    after = rec.model
    np.testing.assert_array_equal(after.points, before.points)
    np.testing.assert_array_equal(after.colors, before.colors)
    np.testing.assert_array_equal(rec.last_pose, pose_before)
    assert [r.merged for r in rec.records] == [True, True, False, False, False]
    # Tracking continues after the skipped frames.
    r = rec.integrate(loop36[2])
    assert r.merged and np.linalg.norm(r.T_model_camera[:3, 3] - loop36[2].T_base_camera[:3, 3]) < 0.002


def test_frames_that_cannot_register_are_skipped_with_a_status(loop36):
    rec = Reconstructor(T_model_camera0=loop36[0].T_base_camera, icp=dict(max_iterations=2))
    rec.integrate(loop36[0])
    before = rec.model
    # A guess half a metre off: no model point within the correspondence distance.
    far = loop36[1].T_base_camera.copy()
    far[:3, 3] += [0.5, 0.0, 0.0]
    r1 = rec.integrate(loop36[1], guess=far)
    # Two iterations cannot converge on a 10-degree move: rejected, not merged.
    r2 = rec.integrate(loop36[2])
    assert (r1.status, r2.status) == ("skipped_too_few_correspondences", "skipped_not_converged")
    assert r2.iterations == 2 and not r2.converged and r2.icp_status == "max_iterations"
    np.testing.assert_array_equal(rec.model.points, before.points)
    # The same frame is accepted when a fixed iteration budget is allowed (eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929), Figs. 6/9).
    rec2 = Reconstructor(T_model_camera0=loop36[0].T_base_camera, icp=dict(max_iterations=2),
                         require_convergence=False)
    rec2.integrate(loop36[0])
    assert rec2.integrate(loop36[1]).merged


def test_wrong_frames_raise_clear_errors():
    rec = Reconstructor()
    with pytest.raises(ValueError, match="intrinsics"):
        rec.integrate(Frame(np.ones((100, 100), np.float32), K))
    with pytest.raises(TypeError):
        rec.integrate(np.zeros((10, 3)))  # a cloud goes to integrate_points
    with pytest.raises(ValueError):
        rec.integrate_points(np.zeros((10, 2), np.float32))
    with pytest.raises(ValueError, match="colors"):
        rec.integrate_points(np.zeros((10, 3), np.float32), np.zeros((9, 3), np.uint8))
    with pytest.raises(ValueError, match="rigid"):
        rec.integrate_points(np.zeros((10, 3), np.float32), guess=np.diag([2.0, 1, 1, 1]))
    with pytest.raises(ValueError):
        Reconstructor(T_model_camera0=np.diag([1.0, 1, -1, 1]))
    with pytest.raises(ValueError):
        Reconstructor(registration="open3d")
    with pytest.raises(TypeError, match="unknown reconstruction setting"):
        Reconstructor(voxel=0.001)
    with pytest.raises(ValueError, match="model_voxel_size"):
        Reconstructor(model_voxel_size=0.0)
    with pytest.raises(ValueError):
        make_reconstruction_settings(icp=dict(max_iterations=-1))
    assert rec.records == [] and rec.model_size == 0


def test_dual_quaternion_estimator_registers_frames_as_point_to_point():
    # The reconstructor's engine with Walker et al. (1991)'s dual-quaternion estimator: each iteration the SVD's
    # least-squares answer, so the same poses (the known-pose check: test_registration.py, on the bunny).
    views = [Frame(ray_cast(loop_pose(i, 72))[0], K, T_base_camera=loop_pose(i, 72)) for i in range(3)]
    poses = {}
    for est in ("dual_quaternion", "point_to_point"):
        rec = Reconstructor(registration="scanalign", icp=dict(estimator=est), T_model_camera0=views[0].T_base_camera)
        assert rec.settings.icp.estimator == est
        results = [rec.integrate(f) for f in views]
        assert all(r.merged and r.converged for r in results), [r.status for r in results]
        poses[est] = np.array([r.T_model_camera for r in results])
    assert sum(r.iterations for r in results) > 2
    np.testing.assert_allclose(poses["dual_quaternion"], poses["point_to_point"], rtol=0, atol=1e-9)


def test_settings_overrides_and_crop_box():
    s = make_reconstruction_settings(icp=dict(max_iterations=7), min_fitness=0.5, crop_box=(-0.1, 0.1, -0.1, 0.1, 0, 1))
    e = s.frame_to_model  # the engine's fields, given for short
    assert e.icp.max_iterations == 7 and e.min_fitness == 0.5 and e.crop_box.as_tuple() == (-0.1, 0.1, -0.1, 0.1, 0, 1)
    assert e.normal_radius == 0.01 and e.model_voxel_size == 0.001  # the job's defaults (the paper's: 5 mm, 1 mm)
    # The crop box (camera frame) bounds what is merged.
    f = frames(1)[0]
    rec = Reconstructor(s)
    rec.integrate(f)
    full = Reconstructor()
    full.integrate(f)
    pts = rec.model.points
    assert 0 < len(pts) < len(full.model.points)
    assert np.all(np.abs(pts[:, :2]) <= 0.1 + 1e-6)


def test_pcl_baseline_runs_in_the_same_pipeline(loop36):
    rec = Reconstructor(T_model_camera0=loop36[0].T_base_camera, registration="pcl_point_to_plane_lls")
    for f in loop36[:3]:
        r = rec.integrate(f)
        assert r.merged, r.status
    assert _translation_errors(rec, loop36[:3]).max() < 0.002


def test_frame_to_cloud_uses_the_frames_scale():
    d = np.full(K.shape, 2000, np.uint16)  # 0.4 m at the TUM scale
    pts, cols = frame_to_cloud(Frame(d, K, depth_scale=1 / 5000))
    assert np.allclose(pts[:, 2], 0.4) and cols is None and len(pts) == K.width * K.height


def test_bilateral_filter_smooths_noise_and_keeps_edges():
    from scanalign.reconstruction import BilateralFilterSettings, bilateral_filter_depth

    rng = np.random.default_rng(5)
    v, u = np.mgrid[0:60, 0:80]
    ramp = 0.4 + 0.001 * u + 0.0005 * v  # a tilted plane: linear depth is reproduced exactly
    step = np.where(u < 40, ramp, ramp + 0.05)  # a 5 cm depth edge
    out = bilateral_filter_depth(step.astype(np.float32))
    interior = (u >= 2) & (u < 38) & (v >= 2) & (v < 58)
    np.testing.assert_allclose(out[interior], step[interior], atol=2e-6)
    far = (u >= 42) & (u < 78) & (v >= 2) & (v < 58)  # the far side is not pulled across the edge
    np.testing.assert_allclose(out[far], step[far], atol=2e-6)
    noisy = step + rng.normal(0, 0.001, step.shape)
    noisy[10, 10] = np.nan
    f = bilateral_filter_depth(noisy.astype(np.float32), BilateralFilterSettings(radius=2, sigma_space=1.5, sigma_depth=0.003))
    assert np.isnan(f[10, 10]) and np.isfinite(f[10, 11])
    assert np.nanstd((f - step)[interior]) < 0.5 * np.nanstd((noisy - step)[interior])
    # uint16 input is scaled like the frame's depth; zero stays invalid.
    mm = np.full((4, 4), 500, np.uint16)
    mm[0, 0] = 0
    g = bilateral_filter_depth(mm, depth_scale=0.001)
    assert np.isnan(g[0, 0]) and np.allclose(g[1:, 1:], 0.5)
    with pytest.raises(ValueError, match="radius"):
        bilateral_filter_depth(mm, BilateralFilterSettings(radius=-1))
    with pytest.raises(ValueError):
        bilateral_filter_depth(np.zeros((4, 4, 2), np.float32))


def test_reference_guided_guess_tracks_steps_that_previous_pose_cannot(loop36):
    from scanalign.pipelines.reconstruct import reconstruct

    big_steps = loop36[::4]  # 40 degrees per frame: beyond ICP's reach from the last pose
    previous_only = reconstruct(big_steps, progress=False)
    guided = reconstruct(big_steps, progress=False, initial_guess="reference")
    assert previous_only.summary()["merged"] < len(big_steps) or previous_only.summary()["ate_m"]["rmse"] > 0.01
    assert guided.summary()["merged"] == len(big_steps)
    assert guided.summary()["ate_m"]["rmse"] < 0.002
    # The model frame is the base frame (the first frame's reference pose), so the
    # estimates are directly the robot's poses.
    np.testing.assert_allclose(guided.estimate.poses[0], big_steps[0].T_base_camera, atol=1e-12)
    no_ref = [Frame(f.depth, K) for f in big_steps]
    with pytest.raises(ValueError, match="reference"):
        reconstruct(no_ref, progress=False, model_frame="base")
    with pytest.raises(ValueError, match="T_base_camera"):
        reconstruct(no_ref, progress=False, initial_guess="reference")
    with pytest.raises(ValueError, match="no frames"):
        reconstruct([], progress=False)

"""Reconstruction, depth images, voxel grid, renderer and the synthetic scanner on bad input
(issue 16): no lost data, no refused valid input, no wrong answers, no unbounded allocation.

Every refusal is a ValueError/TypeError naming the argument, raised before anything is
allocated: the huge images are zero-stride broadcast views that claim gigabytes but hold one
value, so a regression would try to allocate them (run in a subprocess with a memory limit
where a regression could take the process down)."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from scanalign import _core, synthetic
from scanalign.pipelines import reconstruct as pipeline
from scanalign.reconstruction.camera import Frame, Intrinsics
from scanalign.viz.reports import save_report
from scanalign.reconstruction import BilateralFilterSettings, Reconstructor, bilateral_filter_depth, depth_to_cloud, voxel_grid
from scanalign.reconstruction.rendering import render_depth

K = Intrinsics(64, 48, 60.0, 60.0, 31.5, 23.5)


def _wavy(n=6000, seed=0, z=0.4):
    """A wavy 10 x 10 cm patch in front of the camera (camera frame, metres)."""
    u, v = np.random.default_rng(seed).uniform(-0.05, 0.05, (2, n))
    return np.c_[u, v, z + 0.01 * np.sin(60 * u) * np.cos(40 * v)].astype(np.float32)


def _state(rec: Reconstructor):
    core = rec._core
    return (core.model_points(), core.model_normals(), core.model_colors(), core.model_size, core.frames_seen,
            core.frames_merged, np.array(core.last_pose), np.array(core.predicted_pose), len(rec.records))


def _assert_same_state(a, b):
    for x, y in zip(a, b):
        if isinstance(x, np.ndarray) or x is None:
            assert (x is None and y is None) or (x.dtype == y.dtype and np.array_equal(x, y, equal_nan=True)
                                                 and x.tobytes() == y.tobytes())
        else:
            assert x == y


@pytest.fixture()
def rec():
    r = Reconstructor(motion_model="constant_velocity")
    p = _wavy()
    assert r.integrate_points(p, np.full(p.shape, 100, np.uint8)).status == "initialized"
    T = np.eye(4)
    T[:3, 3] = (0.002, -0.001, 0.0)
    moved = (p - T[:3, 3]).astype(np.float32)  # the camera moved by T: the scene seen from there
    assert r.integrate_points(moved, np.full(p.shape, 200, np.uint8)).status == "registered"
    return r


# --- 1. No lost data: a frame that raises leaves the model bit-identical -------------------


def test_a_frame_that_raises_leaves_the_model_bit_identical(rec):
    before = _state(rec)
    p = _wavy(seed=1)
    nan_guess, scaled = np.eye(4), np.eye(4)
    nan_guess[0, 3] = np.nan
    scaled[:3, :3] *= 2.0
    bad_calls = [
        (ValueError, lambda: rec.integrate_points(p, guess=nan_guess)),            # NaN pose
        (ValueError, lambda: rec.integrate_points(p, guess=scaled)),               # non-rigid guess
        (ValueError, lambda: rec.integrate_points(p[:, :2])),                      # wrong shape
        (ValueError, lambda: rec.integrate_points(p, np.zeros((5, 3), np.uint8))),  # colours of another cloud
        (TypeError, lambda: rec.integrate_points(p.astype(complex))),
        (ValueError, lambda: rec._core.integrate(p, None, scaled, "scanalign")),
        (ValueError, lambda: rec._core.integrate(p, None, None, "pcl_bogus")),
        (ValueError, lambda: rec._core.integrate(p, None, scaled, "pcl_svd")),
        (ValueError, lambda: rec.integrate(Frame(np.zeros((3, 3), np.uint16), K))),  # image not matching K
        (ValueError, lambda: rec._core.merge(rec._core.prepare(p, None), scaled)),
    ]
    for error, call in bad_calls:
        with pytest.raises(error):
            call()
        _assert_same_state(_state(rec), before)


def test_skipped_frames_leave_the_model_bit_identical(rec):
    before = _state(rec)[:3]
    far_away = _wavy(seed=2, z=3.0)  # no overlap with the model: not registrable
    for points, status in ((np.zeros((0, 3), np.float32), "skipped_empty"),
                           (np.full((50, 3), np.nan, np.float32), "skipped_empty"),
                           (np.c_[np.mgrid[0:10, 0:10].reshape(2, -1).T * 0.001, np.full(100, 0.4)].astype(
                               np.float32), "skipped_too_few_points")):  # a 1 cm patch: normals, but 100 points
        assert rec.integrate_points(points).status == status
    assert rec.integrate_points(far_away).status in ("skipped_too_few_correspondences", "skipped_low_fitness")
    _assert_same_state(_state(rec)[:3], before)


def test_an_interrupt_during_the_registration_leaves_the_model_bit_identical(tmp_path):
    """Ctrl-C (SIGINT) while the ICP runs: KeyboardInterrupt, and the model exactly as
    before. The signal is sent from another thread after the registration has started (a
    slow 1-thread registration of a big frame with zero tolerances); run in a subprocess so
    that a stray signal cannot reach the test runner."""
    script = textwrap.dedent("""
        import os, signal, threading, time
        import numpy as np
        from scanalign import _core
        from scanalign.reconstruction import make_reconstruction_settings
        # A runner started in the background (CI under `cmd &`) passes SIGINT on as ignored,
        # and Python then installs no handler: put the default one back.
        signal.signal(signal.SIGINT, signal.default_int_handler)
        rng = np.random.default_rng(0)
        u, v = rng.uniform(-0.1, 0.1, (2, 200000))
        p = np.c_[u, v, 0.4 + 0.01 * np.sin(60 * u) * np.cos(40 * v)].astype(np.float32)
        s = make_reconstruction_settings(frame_voxel_size=0.0, num_threads=1, require_convergence=False,
                                         icp=dict(max_iterations=100000, transformation_epsilon=0.0,
                                                  transformation_rotation_epsilon=0.0, fitness_epsilon=0.0,
                                                  absolute_mse_epsilon=0.0))
        f = _core.reconstruction.FrameToModel(s.frame_to_model)
        f.reset(np.eye(4))
        assert f.integrate(p, None, None, "scanalign").status == "initialized"
        before = [f.model_points(), f.model_normals(), f.frames_seen, f.frames_merged, np.array(f.last_pose)]
        guess = np.eye(4); guess[0, 3] = 0.001
        threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
        t0 = time.time()
        try:
            f.integrate(p, None, guess, "scanalign")
            print("NOT INTERRUPTED", time.time() - t0)
        except KeyboardInterrupt:
            after = [f.model_points(), f.model_normals(), f.frames_seen, f.frames_merged, np.array(f.last_pose)]
            same = all(np.array_equal(a, b, equal_nan=True) for a, b in zip(before, after))
            print("INTERRUPTED", "SAME" if same else "CHANGED", round(time.time() - t0, 1))
    """)
    if not (Path(__file__).parents[1] / "cpp/include/scanalign/common/interrupt.hpp").exists():
        pytest.skip("this build has no interrupt support")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.startswith("INTERRUPTED SAME"), out.stdout + out.stderr[-2000:]


# --- 2. Valid input that used to be refused --------------------------------------------------


def test_a_far_point_is_dropped_and_counted_not_the_frame_refused():
    """One stray reading 1e6 m away (or 1e30) used to refuse the whole frame (the frame's
    voxel grid spanned more than 2**21 voxels); now it is dropped and counted, and the model
    is the one of the frame without it."""
    p = _wavy()
    far = np.r_[p, [[1e6, 0.0, 0.4], [0.0, -1e30, 0.4]]].astype(np.float32)
    a, b = Reconstructor(), Reconstructor()
    ra, rb = a.integrate_points(far), b.integrate_points(p)
    assert ra.status == "initialized" and ra.far_points == 2 and rb.far_points == 0
    _assert_same_state(_state(a)[:3], _state(b)[:3])
    assert ra.to_dict()["far_points"] == 2
    # Registered frames too, through both the engine and a PCL baseline.
    for method in ("scanalign", "pcl_point_to_plane_lls"):
        r = Reconstructor(registration=method)
        r.integrate_points(p)
        rep = r.integrate_points(far)
        assert rep.merged and rep.far_points == 2, (method, rep)
        np.testing.assert_allclose(rep.T_model_camera, np.eye(4), atol=1e-6)


def test_an_empty_depth_image_filters_to_an_empty_image():
    for shape, dtype in (((0, 0), np.uint16), ((0, 7), np.float32), ((5, 0), np.uint16)):
        out = bilateral_filter_depth(np.zeros(shape, dtype))
        assert out.shape == shape and out.dtype == np.float32


def test_reconstruct_keeps_the_reconstruction_when_the_evaluation_fails(tmp_path):
    """Reference poses that never move cannot be aligned (the ATE's Umeyama fit is
    undetermined): the evaluation used to raise after every frame had been processed,
    throwing the reconstruction away. Now it is a note in the metrics, and save() writes
    every file."""
    scan = synthetic.builtin_scan(n_frames=3, noise="none", resolution_scale=0.25, robot="none")
    T = scan.frames[0].T_base_camera.copy()
    frames = [Frame(scan.frames[0].depth, scan.intrinsics, depth_scale=scan.frames[0].depth_scale,
                    timestamp=float(k), T_base_camera=T) for k in range(3)]  # the camera stands still
    res = pipeline.reconstruct(frames, progress=False)
    assert [r.status for r in res.records] == ["initialized", "registered", "registered"]
    assert len(res.model) > 100 and "ate_m" not in res.metrics
    assert "degenerate" in res.metrics["evaluation_error"]
    for r in res.records:  # the model frame is the base frame: every estimate at the true pose
        np.testing.assert_allclose(r.T_model_camera, T, atol=1e-6)
    paths = save_report(res, tmp_path)
    for key in ("model", "trajectory", "reference", "frames", "report", "trajectory_png"):
        assert paths[key].stat().st_size > 0, key
    assert "evaluation_error" in (tmp_path / "report.json").read_text()


# --- 3. Wrong answers and unbounded allocations ----------------------------------------------


def test_depth_to_cloud_refuses_absurd_scales_and_intrinsics_and_never_returns_non_finite_points():
    d = np.full(K.shape, 1000, np.uint16)
    for scale in (1e300, 2.0, 0.0, -1e-3, math.nan, math.inf):
        with pytest.raises(ValueError, match="depth_scale"):
            depth_to_cloud(d, K, depth_scale=scale, max_depth=math.inf)
    with pytest.raises(ValueError, match="depth_scale"):  # used to return infinite depths
        Frame(d, K, depth_scale=1e300).depth_metres()
    np.testing.assert_allclose(Frame(d, K, depth_scale=1 / 5000).depth_metres(), 0.2, rtol=1e-6)
    for bad in (dict(fx=0.0), dict(fx=-1.0), dict(fy=math.nan), dict(fx=1e-300), dict(cx=1e300), dict(width=0)):
        with pytest.raises(ValueError, match="intrinsics"):
            Intrinsics(**{**K.to_dict(), **bad})
    # Float depths at the edge of float32 with no range limit (a wide-angle camera: rays up
    # to 3.15 wide): the pixels whose point overflows float32 are invalid, the rest exact.
    wide = Intrinsics(64, 48, 10.0, 10.0, 31.5, 23.5)
    z = np.full(wide.shape, 0.5, np.float32)
    z[0, :5] = 3e38  # x = z (u - cx) / fx is about 9e38 there: beyond float32
    pts, _, pix = depth_to_cloud(z, wide, max_depth=math.inf, return_pixels=True)
    assert np.isfinite(pts).all()
    assert pts.shape[0] == wide.width * wide.height - 5 and not np.isin(np.arange(5), pix).any()
    u, v = pix % wide.width, pix // wide.width
    np.testing.assert_allclose(pts, np.c_[0.5 * (u - wide.cx) / wide.fx, 0.5 * (v - wide.cy) / wide.fy,
                                          np.full(u.shape, 0.5)], rtol=1e-6)


def test_the_bilateral_filter_checks_the_memory_it_would_need_and_its_parameters():
    huge = np.broadcast_to(np.uint16(1000), (200_000, 200_000))  # 80 GB claimed, 2 bytes held
    with pytest.raises(ValueError, match="134217728 pixels"):
        bilateral_filter_depth(huge)
    with pytest.raises(ValueError, match="radius"):
        _core.reconstruction.bilateral_filter_depth(np.ones((3, 3), np.float32), 1_000_000, 1.5, 0.003, 1.0, 0)
    for space, depth, name in ((1e-200, 0.003, "sigma_space"), (1.5, 1e-30, "sigma_depth"),
                               (math.nan, 0.003, "sigma_space"), (1.5, math.inf, "sigma_depth")):
        with pytest.raises(ValueError, match=name):  # 1e-200 squared underflows: weights 0/0 = NaN
            _core.reconstruction.bilateral_filter_depth(np.ones((3, 3), np.float32), 2, space, depth, 1.0, 0)
    with pytest.raises(ValueError, match="depth_scale"):  # 1000 units of 1e300 m: infinite in float32
        bilateral_filter_depth(np.full((3, 3), 1000, np.uint16), depth_scale=1e300)
    with pytest.raises(ValueError, match="num_threads"):  # not pybind11's signature dump
        bilateral_filter_depth(np.ones((3, 3), np.float32), num_threads=2**40)
    # Depths at float's maximum overflow the weighted sums: invalid (NaN), never infinite.
    out = bilateral_filter_depth(np.full((4, 4), 3e38, np.float32))
    assert not np.isinf(out).any()
    # Huge sigmas are a plain average: a constant image stays exactly constant.
    flat = np.full((9, 9), 0.7, np.float32)
    np.testing.assert_allclose(bilateral_filter_depth(flat, BilateralFilterSettings(radius=2, sigma_space=1e300, sigma_depth=1e300)), flat, rtol=1e-6)


def test_voxel_grid_refuses_non_real_attributes_and_absurd_leaves():
    p = _wavy(500)
    for name in ("normals", "colors"):
        for bad in (np.full((500, 3), "1"), np.ones((500, 3), complex), np.ones((500, 3), object)):
            with pytest.raises(TypeError, match=name) as error:
                voxel_grid(p, 0.01, **{name: bad})
            assert isinstance(error.value, ValueError)  # as before: callers catching ValueError still do
    for bad in (np.full((500, 3), "1"), np.ones((500, 3), complex)):
        with pytest.raises(TypeError, match="attributes"):
            _core.reconstruction.voxel_grid(p, 0.01, bad, 1)
    # Integer attributes are real numbers: accepted (and averaged exactly).
    _, means, _ = _core.reconstruction.voxel_grid(p, 1.0, np.full((500, 3), 3, np.int64), 1)
    assert means.shape[1] == 3 and np.all(means == 3.0)
    with pytest.raises(ValueError, match="min_points_per_voxel"):  # not pybind11's signature dump
        voxel_grid(p, 0.01, min_points_per_voxel=2**40)
    for leaf in (0.0, -0.001, math.nan, math.inf, 1e-30, 1e-9):  # 1e-9: over 2**21 voxels along an axis
        with pytest.raises(ValueError, match="leaf_size"):
            voxel_grid(p, leaf)


def test_the_renderer_refuses_huge_and_empty_images_before_allocating():
    V = np.array([[-1.0, -1.0, 2.0], [1.0, -1.0, 2.0], [0.0, 1.0, 2.0]])
    F = np.array([[0, 1, 2]])
    for w, h in ((32768, 32768), (20000, 20000), (0, 10), (10, -1)):
        with pytest.raises(ValueError, match="width, height"):
            _core.reconstruction.render_depth(V, F, _core.reconstruction.PinholeIntrinsics(w, h, 100.0, 100.0, 5.0, 5.0),
                                              np.eye(4), _core.reconstruction.DepthRenderSettings())
    with pytest.raises(ValueError):
        render_depth(V, F, Intrinsics(16384, 16384, 100.0, 100.0, 5.0, 5.0), np.eye(4))
    with pytest.raises(ValueError, match="134217728 pixels"):
        Intrinsics(1_000_000, 1_000_000, 100.0, 100.0, 5.0, 5.0)


# --- 4. The synthetic scanner and its paths --------------------------------------------------


@pytest.mark.parametrize("n", [0, -1, 10**9, 2**40, 2.5, math.nan, "3", None, True])
def test_scan_paths_refuse_absurd_frame_counts_naming_them(n):
    for make in (synthetic.loop_trajectory, synthetic.hemisphere_trajectory):
        with pytest.raises((ValueError, TypeError), match="n_frames"):
            make(n)
    with pytest.raises((ValueError, TypeError), match="n_frames"):
        synthetic.SyntheticConfig(n_frames=n)


def test_scan_paths_accept_integral_counts_and_refuse_absurd_lengths():
    assert len(synthetic.loop_trajectory(4.0)) == 4 and len(synthetic.loop_trajectory(np.int64(5))) == 5
    assert len(synthetic.loop_trajectory(3, radius=0.0)) == 3  # straight down: allowed
    for bad, name in ((dict(radius=-1.0), "radius"), (dict(height=0.0), "height"), (dict(height=1e300), "height"),
                      (dict(radius=math.nan), "radius"), (dict(center=(1e300, 0, 0)), "center")):
        with pytest.raises(ValueError, match=name):
            synthetic.loop_trajectory(4, **bad)
    for d in (0.0, -1.0, 1e300):
        with pytest.raises(ValueError, match="distance"):
            synthetic.hemisphere_trajectory(6, distance=d)
    with pytest.raises(ValueError, match="segments"):
        _core.synthetic.builtin_part_mesh(10**9)


def test_the_synthetic_scanner_refuses_absurd_parameters_naming_them():
    for field, value in (("axial_sigma_ref", math.nan), ("axial_sigma_ref", -1.0), ("dropout", math.nan),
                         ("dropout", 1.0), ("z_ref", 0.0), ("edge_width", -1), ("depth_unit", -1e-3)):
        with pytest.raises(ValueError, match=field):
            synthetic.SensorNoise(**{field: value})
    for bad, name in ((dict(resolution_scale=0.0), "resolution_scale"), (dict(resolution_scale=math.nan),
                                                                          "resolution_scale"),
                      (dict(radius=-0.1), "radius"), (dict(height=math.inf), "height")):
        with pytest.raises(ValueError, match=name):
            synthetic.SyntheticConfig(**bad)
    for wh in ((0, 10), (10**6, 10**6)):  # refused by the constructor, before anything is built
        with pytest.raises(ValueError, match="intrinsics"):
            synthetic.SyntheticConfig(intrinsics=dict(width=wh[0], height=wh[1], fx=100, fy=100, cx=5, cy=5))
    with pytest.raises(ValueError, match="134217728 pixels"):
        synthetic.SyntheticConfig(resolution_scale=1e4)
    huge = np.broadcast_to(np.float32(1.0), (100_000, 100_000))
    with pytest.raises(ValueError, match="134217728 pixels"):
        _core.synthetic.apply_sensor_noise(synthetic.NOISE_PRESETS["sr300"], huge, huge, 0)


def test_the_sensor_model_never_reports_an_infinite_depth_and_a_huge_edge_width_does_not_hang():
    z = np.full((40, 50), 0.5, np.float32)
    z[:, 25:] = 0.8  # a depth edge down the middle
    c = np.ones_like(z)
    wild = synthetic.SensorNoise(axial_sigma_ref=1e300)
    out = _core.synthetic.apply_sensor_noise(wild, z, c, 7)
    assert not np.isinf(out).any() and not (out <= 0).any()
    # Edge dropout dilated 1e9 pixels: the whole image (every pixel is connected to the
    # edge), in the time of w + h steps rather than forever.
    wide = synthetic.SensorNoise(edge_threshold=0.1, edge_width=10**9)
    assert np.isnan(_core.synthetic.apply_sensor_noise(wide, z, c, 0)).all()
    narrow = synthetic.SensorNoise(edge_threshold=0.1, edge_width=2)
    out = _core.synthetic.apply_sensor_noise(narrow, z, c, 0)
    assert np.isnan(out[:, 23:27]).all() and np.array_equal(out[:, :23], z[:, :23])


def test_a_scan_that_cannot_fit_in_memory_is_refused_before_rendering():
    """100,000 SR300 frames are 143 GiB: the scanner used to start rendering them (and be
    killed by the OOM killer); it now refuses before the first frame, naming the size."""
    from scanalign import synthetic

    with pytest.raises(ValueError, match=r"100000 frames of 640x480 need 14\d\.\d GiB"):
        synthetic.builtin_scan(100000)
    assert len(synthetic.builtin_scan(2).frames) == 2

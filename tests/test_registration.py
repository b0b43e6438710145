"""ICP engine, PCL plug-ins and baselines on real surface data with known motions."""

from __future__ import annotations

import numpy as np
import pytest

from helpers import apply, pose_error, rigid
from scanalign import registration as reg
from scanalign.features import estimate_normals

pytestmark = pytest.mark.data

T_TRUE = rigid((0.3, 1.0, -0.4), np.deg2rad(5.0), (0.006, -0.004, 0.005))


def make_source(points: np.ndarray, T_target_source: np.ndarray, noise: float = 0.0, seed: int = 0) -> np.ndarray:
    """The target seen from a camera displaced by T_target_source, plus Gaussian noise (m)."""
    src = apply(np.linalg.inv(T_target_source), points)
    return src + np.random.default_rng(seed).normal(0.0, noise, src.shape) if noise else src


@pytest.mark.parametrize("surface", ["bunny", "fandisk"])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_recovers_known_motion_noise_free(surface, dtype, request):
    pts, nrm = request.getfixturevalue(surface)
    src = make_source(pts, T_TRUE).astype(dtype)
    r = reg.icp(src, pts.astype(dtype), nrm.astype(dtype))
    rot, trans = pose_error(r.T_target_source, T_TRUE)
    assert r.converged, r
    assert rot < 1e-5 and trans < 1e-5, (rot, trans)
    assert r.fitness == 1.0 and r.inlier_rmse < 1e-5 and r.exact_search and not r.degenerate


def test_point_to_point_estimator_recovers_motion(bunny):
    pts, _ = bunny
    r = reg.icp(make_source(pts, T_TRUE), pts, estimator="point_to_point", max_iterations=500)
    rot, trans = pose_error(r.T_target_source, T_TRUE)
    assert rot < 1e-4 and trans < 1e-4, (rot, trans, r)


def test_dual_quaternion_estimator_recovers_motion_as_the_svd_does(bunny):
    # Walker, Shao & Volz (1991)'s dual quaternions solve each iteration's point-to-point least squares in closed
    # form, as the SVD does: the same steps, the same pose (the eye-in-hand paper's variant (b)).
    pts, _ = bunny
    src = make_source(pts, T_TRUE)
    r = reg.icp(src, pts, estimator="dual_quaternion", max_iterations=500)
    svd = reg.icp(src, pts, estimator="point_to_point", max_iterations=500)
    assert r.converged and max(pose_error(r.T_target_source, T_TRUE)) < 1e-4, (pose_error(r.T_target_source, T_TRUE), r)
    assert np.abs(r.T_target_source - svd.T_target_source).max() < 1e-9
    assert reg.make_settings(estimator="dual_quaternion").estimator == "dual_quaternion"


@pytest.mark.parametrize("noise", [0.0005, 0.001])
def test_noise_gives_error_at_noise_level(bunny, noise):
    pts, _ = bunny
    # Normals estimated from the (noise-free) model at the 5 mm radius of the eye-in-hand paper
    # (Comput. Electron. Agric. 180 (2021) 105929), as in use.
    nrm = estimate_normals(pts, radius=0.005, viewpoint=(0, 0, 0))
    src = make_source(pts, T_TRUE, noise=noise, seed=3)
    r = reg.icp(src, pts, nrm, max_correspondence_distance=0.02)
    rot, trans = pose_error(r.T_target_source, T_TRUE)
    assert r.converged
    assert trans < noise and rot < noise / 0.075, (rot, trans)  # 0.075 m: the object's radius
    assert noise * 0.5 < r.inlier_rmse < noise * 3


def test_partial_overlap_with_box_and_distance_rejection(bunny):
    # A frame-to-frame motion of an eye-in-hand scan (2 deg, 5.8 mm); the camera sees
    # only part of the bunny, plus a wall of clutter 3-5 cm behind it that is not in the
    # model -- close enough to the model to be matched within the default 5 cm.
    pts, nrm = bunny
    T = rigid((0.3, 1.0, -0.4), np.deg2rad(2.0), (0.004, -0.003, 0.003))
    src_all = make_source(pts, T)
    src = src_all[src_all[:, 0] > 0.0]
    rng = np.random.default_rng(4)
    clutter = np.c_[rng.uniform(-0.15, 0.15, (8000, 2)), rng.uniform(0.58, 0.60, 8000)]
    frame = np.vstack([src, clutter])
    box = (-0.3, 0.3, -0.3, 0.3, 1e-4, 0.575)  # camera frame: stops in front of the wall
    r = reg.icp(frame, pts, nrm, box=box)
    rot, trans = pose_error(r.T_target_source, T)
    assert r.converged and rot < 1e-5 and trans < 1e-5, (rot, trans)
    assert r.source_points_used == len(src) and r.fitness == 1.0
    # Without the box the clutter drags the estimate away.
    r = reg.icp(frame, pts, nrm)
    assert pose_error(r.T_target_source, T)[1] > 1e-3
    # Partial overlap alone (no clutter) with a tight distance: the true pose.
    r = reg.icp(src, pts, nrm, max_correspondence_distance=0.02)
    assert max(pose_error(r.T_target_source, T)) < 1e-5


def test_our_lls_equals_pcl_on_identical_correspondences(bunny):
    pts, nrm = bunny
    src = make_source(pts, rigid((1, 0, 0), 0.02, (0.002, 0.001, -0.003)), noise=0.0005, seed=5)
    ours, rank, cond, degenerate = reg.point_to_plane_lls(src, pts, nrm)
    theirs = reg.pcl_point_to_plane_lls(src, pts, nrm)
    assert np.abs(ours - theirs).max() < 1e-6
    assert rank == 6 and not degenerate and 0 < cond <= 1


def test_lls_reports_planar_scene_as_rank_deficient():
    rng = np.random.default_rng(0)
    tgt = np.c_[rng.uniform(-0.1, 0.1, (3000, 2)), np.full(3000, 0.5)]
    nrm = np.tile([0.0, 0.0, -1.0], (3000, 1))
    src = tgt + [0.01, -0.02, -0.003]
    T, rank, cond, degenerate = reg.point_to_plane_lls(src, tgt, nrm)
    assert degenerate and rank == 3 and cond < 1e-6
    assert abs(T[2, 3] - 0.003) < 1e-6  # constrained: solved
    assert abs(T[0, 3]) < 1e-9 and abs(T[1, 3]) < 1e-9  # unconstrained: left at zero
    # The engine reports it too, instead of sliding along the plane.
    r = reg.icp(src, tgt, nrm)
    assert r.degenerate and r.min_rank == 3 and np.all(np.isfinite(r.T_target_source))


@pytest.mark.parametrize("variant", ["point_to_plane_lls", "scanalign_point_to_plane_lls", "svd", "dual_quaternion"])
def test_engine_and_pcl_icp_reach_the_same_pose(bunny, variant):
    pts, nrm = bunny
    src = make_source(pts, T_TRUE)
    ours = reg.icp(src, pts, nrm, max_iterations=200)
    theirs = reg.pcl_icp(src, pts, nrm, variant=variant, max_iterations=200)
    assert ours.converged and theirs.converged, (ours, theirs)
    rot, trans = pose_error(theirs.T_target_source, ours.T_target_source)
    tol = 1e-5 if "plane" in variant else 2e-4  # point-to-point converges more slowly
    assert rot < tol and trans < tol, (variant, rot, trans)


def test_pcl_icp_accepts_the_box(fandisk):
    pts, nrm = fandisk
    src = make_source(pts, T_TRUE)
    clutter = np.c_[np.random.default_rng(1).uniform(-0.3, 0.3, (5000, 2)), np.full(5000, 0.62)]
    frame = np.vstack([src, clutter])
    r = reg.pcl_icp(frame, pts, nrm, box=(-0.3, 0.3, -0.3, 0.3, 1e-4, 0.6))
    assert pose_error(r.T_target_source, T_TRUE)[1] < 1e-4
    assert r.source_points_used == len(src)


def test_box_rejector_plugin_keeps_points_inside():
    src = np.array([[0, 0, 0.5], [0.3, 0, 0.5], [0, 0, -0.1], [0.1, -0.1, 1.0]], np.float32)
    kept = reg.box_rejector_keep(src, [3, 2, 1, 0, 0], reg.Box.free_hand_preset())
    assert kept.tolist() == [3, 0, 0]


def test_reusable_engine_keeps_the_tree(bunny):
    pts, nrm = bunny
    engine = reg.Icp(pts, nrm, max_correspondence_distance=0.02)
    assert engine.target_size == len(pts)
    for k, T in enumerate([T_TRUE, rigid((0, 1, 0), 0.03, (0.004, 0, 0.002))]):
        r = engine.align(make_source(pts, T), init=np.eye(4))
        assert max(pose_error(r.T_target_source, T)) < 1e-5, k
    # A good initial guess (previous pose) is honoured.
    r = engine.align(make_source(pts, T_TRUE), init=T_TRUE)
    assert r.iterations <= 3 and max(pose_error(r.T_target_source, T_TRUE)) < 1e-5


def test_strided_pcl_layout_arrays_are_used_without_copy(bunny):
    pts, nrm = bunny
    src = make_source(pts, T_TRUE)
    pcl_layout = np.zeros((len(src), 8), np.float32)  # x y z pad nx ny nz curvature
    pcl_layout[:, :3] = src
    a = reg.icp(pcl_layout[:, :3], pts.astype(np.float32), nrm.astype(np.float32))
    b = reg.icp(np.ascontiguousarray(src, np.float32), pts.astype(np.float32), nrm.astype(np.float32))
    assert np.array_equal(a.T_target_source, b.T_target_source)


def test_thread_count_does_not_change_the_result(bunny):
    pts, nrm = bunny
    src = make_source(pts, T_TRUE, noise=0.0005)
    a = reg.icp(src, pts, nrm, num_threads=1)
    b = reg.icp(src, pts, nrm, num_threads=2)
    assert np.array_equal(a.T_target_source, b.T_target_source)  # fixed summing tree

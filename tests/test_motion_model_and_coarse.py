"""Two ways to run fewer full ICP iterations without giving up accuracy: the tracker's
constant-velocity motion model (on the demo scan, against the robot's poses) and the
engine's coarse-to-fine phase (on a real mesh, against a known motion)."""

from __future__ import annotations

import numpy as np
import pytest

from helpers import apply, pose_error, rigid
from scanalign import registration as reg
from scanalign import synthetic
from scanalign.pipelines.reconstruct import reconstruct
from scanalign.reconstruction import FrameToModelSettings, Reconstructor, make_reconstruction_settings

CROP = [-0.1, 0.1, -0.1, 0.1, 0.1, 1.0]  # the demo settings: workspace box, 10 mm normals, filter


@pytest.fixture(scope="module")
def demo_frames():
    return synthetic.builtin_scan(n_frames=36).frames


def test_constant_velocity_needs_fewer_iterations_at_the_same_accuracy(demo_frames):
    runs = {g: reconstruct(demo_frames, progress=False, crop_box=CROP, normal_radius=0.01, depth_filter="default",
                           initial_guess=g)
            for g in ("previous", "constant_velocity")}
    its = {g: np.mean([r.iterations for r in res.records[1:]]) for g, res in runs.items()}
    ate = {g: res.summary()["ate_m"]["rmse"] for g, res in runs.items()}
    assert all(res.summary()["merged"] == len(demo_frames) for res in runs.values())
    # The scan path is smooth: the prediction starts ICP much nearer its answer.
    assert its["constant_velocity"] < 0.7 * its["previous"], its
    # Same fixed points: the trajectory error against the robot's poses does not grow.
    assert ate["constant_velocity"] < ate["previous"] + 0.5e-3, ate
    assert ate["constant_velocity"] < 0.006, ate


def test_predicted_pose_is_the_last_motion_applied_again(demo_frames):
    rec = Reconstructor(T_model_camera0=demo_frames[0].T_base_camera, crop_box=CROP,
                        motion_model="constant_velocity")
    assert rec.settings.motion_model == "constant_velocity"
    poses = []
    for f in demo_frames[:4]:
        if len(poses) < 2:  # no velocity yet: the last pose
            np.testing.assert_array_equal(rec.predicted_pose, rec.last_pose)
        else:
            np.testing.assert_allclose(rec.predicted_pose, poses[-1] @ np.linalg.inv(poses[-2]) @ poses[-1],
                                       atol=1e-12)
        r = rec.integrate(f)
        assert r.merged
        poses.append(r.T_model_camera)
    # The eye-in-hand paper's model (Comput. Electron. Agric. 180 (2021) 105929) predicts no motion.
    baseline = Reconstructor(FrameToModelSettings(), T_model_camera0=demo_frames[0].T_base_camera, crop_box=CROP)
    assert baseline.settings.motion_model == "previous"
    for f in demo_frames[:2]:
        baseline.integrate(f)
    np.testing.assert_array_equal(baseline.predicted_pose, baseline.last_pose)


def test_motion_model_rejects_unknown_names():
    with pytest.raises(ValueError, match="constant_velocity"):
        make_reconstruction_settings(motion_model="kalman")
    with pytest.raises(ValueError, match="initial_guess"):
        reconstruct([], progress=False, initial_guess="kalman")


T_TRUE = rigid((0.3, 1.0, -0.4), np.deg2rad(8.0), (0.01, -0.008, 0.006))


@pytest.mark.data
@pytest.mark.parametrize("surface", ["bunny", "fandisk"])
def test_coarse_to_fine_reaches_the_known_motion_with_fewer_full_iterations(surface, request):
    pts, nrm = request.getfixturevalue(surface)
    rng = np.random.default_rng(5)
    # Another sampling and noise than the target: not a copy of the model.
    src = apply(np.linalg.inv(T_TRUE), pts[rng.permutation(len(pts))[:20000]]) + rng.normal(0, 2e-4, (20000, 3))
    args = (src.astype(np.float32), pts.astype(np.float32), nrm.astype(np.float32))
    baseline = reg.icp(*args)
    coarse = reg.icp(*args, coarse_stride=4)
    assert baseline.converged and coarse.converged
    assert baseline.coarse_iterations == 0 and coarse.coarse_iterations > 0
    assert coarse.iterations < baseline.iterations, (coarse.iterations, baseline.iterations)
    for res in (baseline, coarse):
        rot, trans = pose_error(res.T_target_source, T_TRUE)
        assert rot < 2e-3 and trans < 2e-4, (rot, trans)
    # Both are the full-resolution fixed point, to within the convergence tolerance.
    rot, trans = pose_error(coarse.T_target_source, baseline.T_target_source)
    assert rot < 1e-3 and trans < 1e-4, (rot, trans)
    assert coarse.source_points_used == 20000 and coarse.fitness == baseline.fitness


def test_coarse_stride_must_be_positive():
    pts = np.random.default_rng(0).normal(size=(1000, 3)).astype(np.float32)
    with pytest.raises(ValueError, match="coarse_stride"):
        reg.icp(pts, pts, estimator="point_to_point", coarse_stride=0)

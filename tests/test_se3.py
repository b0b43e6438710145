"""scanalign.common.rigid against scipy's rotations, numpy's inverse and analytic angles, and its
rigidity rule against the C++ core's (both must accept and reject the same matrices)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scanalign import registration
from scanalign.common import rigid as se3


@pytest.mark.parametrize("seed", range(4))
def test_rotations_and_inverse_match_scipy_and_numpy(seed):
    rotation = pytest.importorskip("scipy.spatial.transform").Rotation
    rng = np.random.default_rng(seed)
    axis, angle, t = rng.normal(size=3), rng.uniform(-math.pi, math.pi), rng.normal(size=3)
    T = se3.rigid(axis, angle, t)
    oracle = rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()
    np.testing.assert_allclose(T[:3, :3], oracle, atol=1e-14)
    np.testing.assert_array_equal(T[:3, 3], t)
    np.testing.assert_allclose(se3.inverse(T), np.linalg.inv(T), atol=1e-13)
    batch = np.stack([T, se3.rigid(t, 0.3, axis)])
    np.testing.assert_allclose(se3.inverse(batch) @ batch, np.broadcast_to(np.eye(4), (2, 4, 4)), atol=1e-13)


def test_rotation_angle_is_accurate_near_zero_and_pi():
    for angle in (1e-9, 1e-4, 1.0, math.pi - 1e-6, math.pi):
        R = se3.rotation_about((0.2, -1.0, 0.5), angle)
        assert se3.rotation_angle(R) == pytest.approx(angle, rel=1e-7, abs=1e-15)
    T_ref = se3.rigid((1, 0, 0), 0.2, (1.0, 2.0, 3.0))
    T_est = T_ref @ se3.rigid((0, 1, 1), 0.01, (0.003, -0.004, 0.0))
    rot, trans = se3.pose_error(T_est, T_ref)
    assert rot == pytest.approx(0.01, rel=1e-12) and trans == pytest.approx(0.005, rel=1e-12)


def test_rigid_problem_names_each_failure():
    T = se3.rigid((0.3, 1.0, -0.4), 0.7, (0.1, 0.2, 0.3))
    assert se3.rigid_problem(T) is None
    assert se3.rigid_problem(T.astype(np.float32)) is None  # float rounding passes
    bad = T.copy()
    bad[:3, :3] *= 1.001
    assert "orthonormal" in se3.rigid_problem(bad)
    bad = T.copy()
    bad[:3, 0] *= -1
    assert "reflection" in se3.rigid_problem(bad)
    bad = T.copy()
    bad[3, 1] = 1e-6
    assert "last row" in se3.rigid_problem(bad)
    bad = T.copy()
    bad[0, 3] = np.inf
    assert "non-finite" in se3.rigid_problem(bad)
    with pytest.raises(ValueError, match=r"T_base_camera: its rotation block is a reflection \(determinant -1\)"):
        se3.require_rigid(np.diag([1.0, 1.0, -1.0, 1.0]), "T_base_camera")
    with pytest.raises(ValueError, match="4x4"):
        se3.require_rigid(np.eye(3), "T")


@pytest.mark.parametrize("error, accepted", [(3e-6, True), (8e-6, True), (3e-5, False), (1e-3, False)])
def test_the_python_and_cpp_rules_agree(error, accepted):
    # A rotation whose columns are stretched by `error`: |R^T R - I| is about 2 * error.
    T = se3.rigid((0.3, 1.0, -0.4), 0.7, (0.0, 0.0, 0.0))
    T[:3, :3] *= 1.0 + error / 2
    assert (se3.rigid_problem(T) is None) == accepted
    pts = np.random.default_rng(1).normal(size=(100, 3))
    if accepted:
        registration.icp(pts, pts, init=T, estimator="point_to_point", max_iterations=1)
    else:
        with pytest.raises(ValueError, match="rigid"):
            registration.icp(pts, pts, init=T, estimator="point_to_point", max_iterations=1)

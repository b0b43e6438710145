"""The ICP engine's bucket k-d tree (against scipy's cKDTree and the left-balanced tree of
the eye-in-hand paper, Comput. Electron. Agric. 180 (2021) 105929) and the robust kernels (against outliers with a known motion)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from helpers import apply, pose_error, rigid
from scanalign import _core
from scanalign import registration as reg

pytestmark = pytest.mark.data

T_TRUE = rigid((0.3, 1.0, -0.4), np.deg2rad(5.0), (0.006, -0.004, 0.005))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("leaf", [1, 8, 32])
def test_bucket_tree_matches_scipy(bunny, dtype, leaf):
    pts, _ = bunny
    rng = np.random.default_rng(1)
    queries = pts[rng.choice(len(pts), 3000)] + rng.normal(0, 0.002, (3000, 3))
    queries = np.vstack([queries, rng.uniform(-0.3, 0.3, (500, 3)) + pts.mean(0)]).astype(dtype)
    tree = (_core.registration.BucketKdTree32 if dtype == np.float32 else _core.registration.BucketKdTree64)(
        np.ascontiguousarray(pts, dtype), leaf)
    assert tree.size == len(pts) and tree.leaf_size == leaf
    for max_distance in (np.inf, 0.003):
        idx, d2 = tree.nearest(queries, max_distance)
        dist, _ = cKDTree(pts.astype(dtype).astype(np.float64)).query(queries.astype(np.float64),
                                                                     distance_upper_bound=max_distance)
        found = np.isfinite(dist)
        assert np.array_equal(idx >= 0, found)
        np.testing.assert_allclose(np.sqrt(d2[found]), dist[found], rtol=1e-5 if dtype == np.float32 else 1e-12)
        # The returned index holds a point at the reported distance.
        got = np.linalg.norm(pts[idx[found]].astype(dtype) - queries[found], axis=1)
        np.testing.assert_allclose(got, dist[found], rtol=1e-5 if dtype == np.float32 else 1e-12)


@pytest.mark.parametrize("surface", ["bunny", "fandisk"])
def test_both_searches_give_the_same_registration(surface, request):
    # Both searches are exact, so ICP takes the same path: the same pose and iterations.
    pts, nrm = request.getfixturevalue(surface)
    src = (apply(np.linalg.inv(T_TRUE), pts) + np.random.default_rng(2).normal(0, 3e-4, pts.shape)).astype(np.float32)
    a = reg.icp(src, pts.astype(np.float32), nrm.astype(np.float32), search="bucket_kdtree")
    b = reg.icp(src, pts.astype(np.float32), nrm.astype(np.float32), search="left_balanced_kdtree")
    assert a.iterations == b.iterations and a.status == b.status
    np.testing.assert_allclose(a.T_target_source, b.T_target_source, atol=1e-7)
    assert a.correspondence_count == b.correspondence_count
    rot, trans = pose_error(a.T_target_source, T_TRUE)
    assert rot < 2e-3 and trans < 2e-4, (rot, trans)


def test_search_change_needs_a_new_target(bunny):
    pts, nrm = bunny
    engine = reg.Icp(pts, nrm, search="left_balanced_kdtree")
    engine.settings = reg.make_settings(engine.settings, search="bucket_kdtree")
    with pytest.raises(ValueError, match="setTarget again"):
        engine.align(pts)
    with pytest.raises(ValueError, match="^search: unknown value 'octree'; expected one of"):
        reg.make_settings(search="octree")


def test_robust_kernel_resists_outliers(fandisk):
    # 30 % of the source replaced by clutter up to 5 cm off the surface, with a wide
    # correspondence distance: plain least squares is pulled off, Huber / Cauchy are not.
    pts, nrm = fandisk
    rng = np.random.default_rng(3)
    src = apply(np.linalg.inv(T_TRUE), pts) + rng.normal(0, 2e-4, pts.shape)
    bad = rng.random(len(src)) < 0.3
    src[bad] += rng.normal(0, 1, (bad.sum(), 3)) * 0.03
    common = dict(max_correspondence_distance=0.08, max_iterations=100)
    plain = reg.icp(src, pts, nrm, **common)
    errors = {"none": pose_error(plain.T_target_source, T_TRUE)}
    for kernel in ("huber", "cauchy"):
        r = reg.icp(src, pts, nrm, robust_kernel=kernel, robust_scale=0.002, **common)
        errors[kernel] = pose_error(r.T_target_source, T_TRUE)
        assert r.iterations > 0
    for kernel in ("huber", "cauchy"):
        assert errors[kernel][1] < 0.5 * errors["none"][1], errors  # translation error halved at least
        assert errors[kernel][1] < 1e-3 and errors[kernel][0] < np.deg2rad(0.2), errors


def test_robust_kernel_settings_are_checked():
    with pytest.raises(ValueError, match="^robust_kernel: unknown value 'tukey'; expected one of"):
        reg.make_settings(robust_kernel="tukey")
    with pytest.raises(ValueError, match="robust_scale"):
        reg.make_settings(robust_kernel="huber", robust_scale=0.0)
    with pytest.raises(ValueError, match="robust_scale"):
        reg.make_settings(robust_scale=float("nan"))
    with pytest.raises(ValueError, match="point_to_plane estimator only"):
        reg.make_settings(robust_kernel="cauchy", estimator="point_to_point")


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan")])
def test_bucket_tree_rejects_bad_distances_and_shapes(bad):
    tree = _core.registration.BucketKdTree64(np.random.default_rng(0).random((100, 3)), 8)
    with pytest.raises(ValueError, match="max_distance"):
        tree.nearest(np.zeros((1, 3)), bad)
    with pytest.raises((ValueError, TypeError)):
        tree.nearest(np.zeros((4, 2)), 1.0)
    with pytest.raises(ValueError, match="leaf_size"):
        _core.registration.BucketKdTree64(np.zeros((10, 3)), 0)

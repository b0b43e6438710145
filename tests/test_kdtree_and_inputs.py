"""k-d tree against brute force, and bad input on every public entry point."""

from __future__ import annotations

import numpy as np
import pytest

from scanalign import registration as reg
from scanalign.features import estimate_normals
from scanalign.reconstruction import voxel_grid


def brute_nearest(points: np.ndarray, queries: np.ndarray, max_distance: float = np.inf):
    d = np.linalg.norm(queries[:, None, :].astype(np.float64) - points[None, :, :].astype(np.float64), axis=2)
    best = d.min(axis=1)
    return np.where(best < max_distance, best, np.inf)


CLOUDS = {
    "random": lambda rng: rng.uniform(-1, 1, (3000, 3)),
    "duplicates": lambda rng: np.repeat(rng.uniform(-1, 1, (15, 3)), 200, axis=0),
    "plane": lambda rng: np.c_[rng.uniform(-1, 1, (3000, 2)), np.zeros(3000)],
    "line": lambda rng: np.outer(rng.uniform(-1, 1, 3000), [1.0, 2.0, -0.5]),
    "single": lambda rng: np.array([[0.1, 0.2, 0.3]]),
    "identical": lambda rng: np.full((500, 3), 0.25),
}


@pytest.mark.parametrize("name", sorted(CLOUDS))
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_kdtree_nearest_equals_brute_force(name, dtype):
    rng = np.random.default_rng(len(name))
    pts = CLOUDS[name](rng).astype(dtype)
    queries = rng.uniform(-1.5, 1.5, (400, 3)).astype(dtype)
    tree = reg.KdTree(pts)
    for max_distance in (np.inf, 0.1):
        idx, dist, exact = tree.nearest(queries, max_distance=max_distance)
        truth = brute_nearest(pts, queries, max_distance)
        assert exact.all()
        np.testing.assert_allclose(dist, truth, rtol=1e-6, atol=1e-7)
        found = idx >= 0
        assert np.array_equal(found, np.isfinite(truth))
        # The index points at a point at that distance (ties between duplicates allowed).
        np.testing.assert_allclose(np.linalg.norm(pts[idx[found]] - queries[found], axis=1), dist[found], rtol=1e-5)


def test_kdtree_shallow_stack_reports_approximation():
    rng = np.random.default_rng(0)
    pts = rng.uniform(-1, 1, (20000, 3))
    queries = rng.uniform(-1, 1, (3000, 3))
    tree = reg.KdTree(pts)
    assert tree.height == 14
    idx, dist, exact = tree.nearest(queries, stack_depth=1)
    truth = brute_nearest(pts, queries)
    assert (~exact).any()
    np.testing.assert_allclose(dist[exact], truth[exact], rtol=1e-12)
    assert np.all(dist[~exact] >= truth[~exact] - 1e-12)


def test_kdtree_skips_non_finite_points():
    pts = np.array([[0, 0, 0], [np.nan, 0, 0], [1, 1, 1], [0, np.inf, 0]], float)
    tree = reg.KdTree(pts)
    assert tree.size == 2
    idx, _, _ = tree.nearest(np.array([[0.9, 0.9, 0.9], [0.1, 0, 0]]))
    assert idx.tolist() == [2, 0]


@pytest.fixture()
def plane_cloud():
    rng = np.random.default_rng(0)
    pts = np.c_[rng.uniform(-0.1, 0.1, (500, 2)), 0.5 + 0.01 * rng.uniform(-1, 1, 500)]
    return pts, np.tile([0.0, 0.0, -1.0], (500, 1))


def test_bad_input_raises_clear_errors(plane_cloud):
    pts, nrm = plane_cloud
    with pytest.raises(ValueError, match="empty"):
        reg.icp(np.zeros((0, 3)), pts, nrm)
    with pytest.raises(ValueError, match="empty"):
        reg.icp(pts, np.zeros((0, 3)), np.zeros((0, 3)))
    with pytest.raises(ValueError, match="normals"):
        reg.icp(pts, pts, nrm[:-1])
    with pytest.raises(ValueError, match="target_normals"):
        reg.icp(pts, pts)  # point-to-plane without normals
    with pytest.raises(TypeError, match="float"):
        reg.icp(pts.astype(np.int64), pts, nrm)
    with pytest.raises(TypeError, match="float"):
        reg.icp(pts.astype(object), pts, nrm)
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        reg.icp(pts[:, :2], pts, nrm)
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        reg.icp(pts.ravel(), pts, nrm)
    with pytest.raises(ValueError, match="4x4"):
        reg.icp(pts, pts, nrm, init=np.eye(3))
    with pytest.raises(ValueError, match="non-finite"):
        reg.icp(pts, pts, nrm, init=np.full((4, 4), np.nan))
    with pytest.raises(ValueError, match="rigid"):
        reg.icp(pts, pts, nrm, init=np.diag([2.0, 2.0, 2.0, 1.0]))
    with pytest.raises(ValueError, match="max_correspondence_distance"):
        reg.icp(pts, pts, nrm, max_correspondence_distance=-1.0)
    with pytest.raises(ValueError, match="estimator"):
        reg.icp(pts, pts, nrm, estimator="magic")
    with pytest.raises(TypeError, match="unknown ICP setting"):
        reg.icp(pts, pts, nrm, max_iteration=3)
    with pytest.raises(ValueError, match="box"):
        reg.icp(pts, pts, nrm, box=(1, 0, 0, 1, 0, 1))
    with pytest.raises(ValueError, match="no point with finite"):
        reg.icp(pts, np.full((10, 3), np.nan), np.ones((10, 3)))
    with pytest.raises(ValueError):
        reg.pcl_icp(pts, pts, None, variant="point_to_plane_lls")
    with pytest.raises(ValueError, match="variant"):
        reg.pcl_icp(pts, pts, nrm, variant="nope")
    with pytest.raises(ValueError, match="same number of rows"):
        reg.point_to_plane_lls(pts, pts[:-1], nrm)
    with pytest.raises(ValueError):
        estimate_normals(pts, radius=0.0)
    with pytest.raises(ValueError):
        estimate_normals(pts, viewpoint=(0, 0))
    with pytest.raises(TypeError):
        estimate_normals(pts.astype(np.int32))
    with pytest.raises(ValueError, match="leaf_size"):
        voxel_grid(pts, leaf_size=0.0)
    with pytest.raises(ValueError, match="too small"):
        voxel_grid(np.array([[0, 0, 0], [1000.0, 0, 0]]), leaf_size=1e-4)
    with pytest.raises(ValueError, match="normals"):
        voxel_grid(pts, normals=nrm[:10])


def test_nan_points_are_ignored_and_failures_are_statuses(plane_cloud):
    rng = np.random.default_rng(1)
    pts = rng.uniform(-0.1, 0.1, (2000, 3)) + [0, 0, 0.5]
    nrm = estimate_normals(pts, radius=0.03)
    src = pts.copy()
    src[::7] = np.nan
    r = reg.icp(src, pts, nrm)
    assert r.converged and r.source_points_used == len(pts) - len(pts[::7])
    assert np.allclose(r.T_target_source, np.eye(4), atol=1e-6)
    # Too few correspondences (5 < 6 unknowns): a status, the initial pose kept.
    r = reg.icp(pts[:5], pts, nrm)
    assert r.status == "not_enough_correspondences" and not r.converged
    assert np.array_equal(r.T_target_source, np.eye(4))
    # Nothing within range.
    r = reg.icp(pts + [5.0, 0, 0], pts, nrm)
    assert r.status == "not_enough_correspondences"
    # Iteration cap: reported, not called converged.
    r = reg.icp(pts + [0.01, 0, 0], pts, nrm, max_iterations=1)
    assert r.status == "max_iterations" and not r.converged and r.iterations == 1
    # All-NaN source: nothing usable.
    r = reg.icp(np.full((100, 3), np.nan), pts, nrm)
    assert r.status == "not_enough_correspondences" and r.source_points_used == 0


def test_settings_object_and_overrides():
    s = reg.make_settings(max_iterations=7, box=reg.Box.banana_preset())
    assert s.max_iterations == 7 and s.box.as_tuple() == (-0.05, 0.05, -0.1, 0.1, 0.0001, 10.0)
    s2 = reg.make_settings(s, max_correspondence_distance=0.01)
    assert s2.max_iterations == 7 and s2.max_correspondence_distance == 0.01 and s2.box is not None
    d = reg.IcpSettings()
    assert (d.max_iterations, d.transformation_epsilon, d.fitness_epsilon) == (50, 1e-8, 1e-8)  # eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929), §3.3
    assert d.search_stack_depth == 20  # eye-in-hand paper §3.1

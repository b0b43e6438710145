"""Normals against analytic surfaces; the voxel grid against an independent NumPy oracle."""

from __future__ import annotations

import numpy as np
import pytest

from scanalign.features import estimate_normals
from scanalign.reconstruction import voxel_grid


def test_plane_normals_are_exact_and_face_the_viewpoint():
    rng = np.random.default_rng(0)
    n_true = np.array([0.2, -0.3, 1.0]) / np.linalg.norm([0.2, -0.3, 1.0])
    u = np.cross(n_true, [1, 0, 0]); u /= np.linalg.norm(u)
    v = np.cross(n_true, u)
    ab = rng.uniform(-0.05, 0.05, (5000, 2))
    pts = np.array([0, 0, 0.5]) + ab[:, :1] * u + ab[:, 1:] * v
    normals, curvature = estimate_normals(pts, radius=0.005, return_curvature=True)
    # The camera at the origin sees the plane from the -n_true side.
    np.testing.assert_allclose(normals, np.tile(-n_true, (len(pts), 1)), atol=1e-6)
    assert np.all(curvature < 1e-9)
    flipped = estimate_normals(pts, radius=0.005, viewpoint=(0, 0, 1.0))
    np.testing.assert_allclose(flipped, np.tile(n_true, (len(pts), 1)), atol=1e-6)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_sphere_normals_are_radial(dtype):
    rng = np.random.default_rng(1)
    d = rng.normal(size=(30000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    c = np.array([0.0, 0.0, 0.4])
    pts = (c + 0.04 * d).astype(dtype)
    normals = estimate_normals(pts, radius=0.005, viewpoint=c)  # viewpoint inside: inward normals
    assert normals.dtype == dtype
    cos = np.sum(normals * -d, axis=1)
    assert np.all(cos > 0.99), cos.min()


def test_isolated_and_nan_points_get_nan_normals():
    pts = np.array([[0, 0, 0.5], [1, 1, 1], [np.nan, 0, 0]], float)
    assert np.isnan(estimate_normals(pts)).all()


def numpy_voxel_oracle(points: np.ndarray, leaf: float):
    """PCL's VoxelGrid definition written independently: index = floor(p/leaf) - floor(min/leaf)."""
    idx = np.floor(points / leaf).astype(np.int64)
    idx -= idx.min(axis=0)
    key = idx[:, 2] * (1 << 42) + idx[:, 1] * (1 << 21) + idx[:, 0]  # z-major like PCL
    uniq, inverse, counts = np.unique(key, return_inverse=True, return_counts=True)
    sums = np.zeros((len(uniq), 3))
    np.add.at(sums, inverse, points)
    return sums / counts[:, None], counts


def test_voxel_grid_equals_the_oracle():
    rng = np.random.default_rng(2)
    pts = rng.uniform(-0.03, 0.03, (100000, 3)) + [0.1, -0.2, 0.6]
    r = voxel_grid(pts, leaf_size=0.002)
    centroids, counts = numpy_voxel_oracle(pts, 0.002)
    np.testing.assert_allclose(r.points, centroids, atol=1e-12)
    assert np.array_equal(r.counts, counts) and r.counts.sum() == len(pts)


def test_voxel_grid_averages_normals_and_colors_and_bounds_model_size():
    rng = np.random.default_rng(3)
    base = rng.uniform(0, 0.05, (20000, 3))
    normals = np.tile([0.0, 0.0, 1.0], (len(base), 1)) + rng.normal(0, 0.05, base.shape)
    colors = rng.integers(0, 256, (len(base), 3), dtype=np.uint8)
    r = voxel_grid(base, 0.001, normals=normals, colors=colors)
    np.testing.assert_allclose(np.linalg.norm(r.normals, axis=1), 1.0, atol=1e-12)
    assert r.colors.dtype == np.uint8
    # Colours of a voxel are the rounded mean of its members (checked on one voxel).
    key = np.floor(base / 0.001).astype(int)
    k0 = np.floor(r.points[0] / 0.001).astype(int)
    members = np.all(key == k0, axis=1)
    np.testing.assert_array_equal(r.colors[0], np.rint(colors[members].mean(axis=0)).astype(np.uint8))
    # Merging the same surface again (as frame-to-model does) does not grow the model.
    twice = voxel_grid(np.vstack([r.points, base + rng.normal(0, 1e-5, base.shape)]), 0.001)
    assert len(twice.points) <= len(r.points) * 1.05 + 100
    assert len(r.points) <= 50**3


def test_voxel_grid_min_points_and_nan():
    pts = np.array([[0.0001, 0, 0], [0.0002, 0, 0], [0.0051, 0, 0], [np.nan, 0, 0]])
    r = voxel_grid(pts, 0.001, min_points_per_voxel=2)
    assert len(r.points) == 1 and r.counts.tolist() == [2]
    assert voxel_grid(np.full((3, 3), np.nan), 0.001).points.shape == (0, 3)


# --- shape factors (Kleppe, PhD thesis, NTNU 2018, (6.1)-(6.3)) -------------------------------


def test_shape_factors_sum_and_ideal_shapes():
    from scanalign.features import shape_factors

    rng = np.random.default_rng(3)
    lam = rng.uniform(0, 2, size=(500, 3))
    f = shape_factors(lam)
    assert f.shape == (500, 3)
    np.testing.assert_allclose(f.sum(axis=1), 1.0, atol=1e-12)
    assert np.all(f >= 0)
    # (6.1)-(6.3) by hand, per row, independent of the vectorised path
    for row, fr in zip(lam[:20], f[:20]):
        l1, l2, l3 = sorted(row, reverse=True)
        s = l1 + l2 + l3
        np.testing.assert_allclose(fr, [(l1 - l2) / s, 2 * (l2 - l3) / s, 3 * l3 / s], atol=1e-14)
    np.testing.assert_allclose(shape_factors([2.5, 0, 0]), [1, 0, 0])
    np.testing.assert_allclose(shape_factors([1.5, 1.5, 0]), [0, 1, 0])
    np.testing.assert_allclose(shape_factors([0.3, 0.3, 0.3]), [0, 0, 1])
    np.testing.assert_allclose(shape_factors([1, 3, 2]), [1 / 6, 2 / 6, 3 / 6])


@pytest.mark.parametrize("bad", [[1, -0.1, 0], [1, np.nan, 0], [0, 0, 0], [[1, 1, 1], [0, 0, 0]], [1, 2]])
def test_shape_factors_rejects_invalid(bad):
    from scanalign.features import shape_factors

    with pytest.raises(ValueError):
        shape_factors(bad)


def test_shape_factors_pca_of_sampled_shapes():
    from scanalign.features import shape_factors

    rng = np.random.default_rng(5)
    n = 3000
    d = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    line = rng.uniform(-1, 1, (n, 1)) * d + 1e-3 * rng.uniform(-1, 1, (n, 3))
    plane = np.c_[rng.uniform(-1, 1, (n, 2)), 1e-3 * rng.uniform(-1, 1, n)]
    ball = rng.uniform(-1, 1, (3 * n, 3))
    ball = ball[np.linalg.norm(ball, axis=1) <= 1]

    def eig(p):
        q = p - p.mean(axis=0)
        return np.linalg.eigvalsh(q.T @ q)  # P5(11), ascending; shape_factors sorts

    f = shape_factors(np.stack([eig(line), eig(plane), eig(ball)]))
    assert f[0, 0] > 0.95 and f[1, 1] > 0.95 and f[2, 2] > 0.85
    assert list(np.argmax(f, axis=1)) == [0, 1, 2]

"""estimate_normals (the grid search with cell moments) against a NumPy brute-force PCA on a
real-like frame: the demo's SR300-like synthetic depth (noise, the part's edges and the
table), back-projected, cropped and gridded at 1 mm as the reconstruction does, plus a
sparse scatter of isolated points."""

from __future__ import annotations

import numpy as np
import pytest

from scanalign import synthetic
from scanalign.features import estimate_normals
from scanalign.reconstruction import BilateralFilterSettings, bilateral_filter_depth, depth_to_cloud, voxel_grid


@pytest.fixture(scope="module")
def frame_cloud() -> np.ndarray:
    scan = synthetic.builtin_scan(n_frames=4)
    f = scan.frames[1]
    depth = bilateral_filter_depth(f.depth, BilateralFilterSettings(), depth_scale=f.depth_scale)
    p, _ = depth_to_cloud(depth, f.intrinsics, depth_scale=f.depth_scale)
    # A 7 x 7 cm window across the part's edge and the table keeps the brute force small.
    c = p[np.argmin(np.abs(p[:, 0]) + np.abs(p[:, 1]))]
    keep = (np.abs(p[:, 0] - c[0]) < 0.035) & (np.abs(p[:, 1] - c[1]) < 0.035)
    cloud = voxel_grid(p[keep], 0.001).points.astype(np.float64)
    rng = np.random.default_rng(3)
    sparse = c + rng.uniform(-0.05, 0.05, (150, 3))
    return np.vstack([cloud, sparse])


def brute_force(points: np.ndarray, radius: float, viewpoint: np.ndarray, ambiguity: float):
    """PCA over every point within the radius, in float64; flags queries with a point within
    `ambiguity` (relative, in squared distance) of the sphere."""
    p = points.astype(np.float64)
    n = len(p)
    normals = np.full((n, 3), np.nan)
    curvature = np.full(n, np.nan)
    gap = np.zeros(n)
    ambiguous = np.zeros(n, bool)
    r2 = radius * radius
    for start in range(0, n, 256):
        q = p[start:start + 256]
        d = p[None, :, :] - q[:, None, :]              # (b, n, 3)
        d2 = np.einsum("bnk,bnk->bn", d, d)
        inside = d2 <= r2
        ambiguous[start:start + 256] = np.any(np.abs(d2 - r2) <= ambiguity * r2, axis=1)
        k = inside.sum(axis=1)
        w = inside[:, :, None] * d
        s1 = w.sum(axis=1)
        s2 = np.einsum("bni,bnj->bij", w, d)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = s1 / k[:, None]
            cov = s2 / k[:, None, None] - mean[:, :, None] * mean[:, None, :]
        ok = k >= 3
        lam, vec = np.linalg.eigh(np.where(ok[:, None, None], cov, np.eye(3)))
        lam = np.maximum(lam, 0.0)
        nrm = vec[:, :, 0]
        flip = np.einsum("bk,bk->b", nrm, viewpoint - q) < 0
        nrm[flip] *= -1
        idx = np.arange(start, start + len(q))
        normals[idx[ok]] = nrm[ok]
        curvature[idx[ok]] = (lam[:, 0] / lam.sum(axis=1))[ok]
        gap[idx] = np.where(lam[:, 2] > 0, (lam[:, 1] - lam[:, 0]) / np.where(lam[:, 2] > 0, lam[:, 2], 1), 0)
    return normals, curvature, gap, ambiguous


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("radius", [0.003, 0.005, 0.01, 0.02])
def test_normals_equal_the_brute_force_pca(frame_cloud, dtype, radius):
    pts = frame_cloud.astype(dtype)
    viewpoint = np.zeros(3)
    single = dtype == np.float32
    # Float clouds are tested and summed in float near the sphere's surface.
    eps, ambiguity = (2e-6, 2e-6) if single else (1e-12, 1e-12)
    ref_n, ref_c, gap, ambiguous = brute_force(pts, radius, viewpoint, ambiguity)
    normals, curvature = estimate_normals(pts, radius, viewpoint, return_curvature=True)
    assert normals.dtype == dtype
    use = ~ambiguous
    assert use.mean() > 0.98
    # Too few neighbours: NaN in both.
    np.testing.assert_array_equal(np.isnan(normals[use, 0]), np.isnan(ref_n[use, 0]))
    valid = use & ~np.isnan(ref_n[:, 0])
    np.testing.assert_allclose(curvature[valid], ref_c[valid], atol=20 * eps + 1e-15, rtol=0)
    # The normal's error is bounded by the sums' rounding over the eigenvalue gap.
    well = valid & (gap > 1e-3)
    assert well.sum() > 0.5 * len(pts)
    err = np.linalg.norm(normals[well].astype(np.float64) - ref_n[well], axis=1)
    bound = 20 * eps / gap[well] + 4 * np.finfo(dtype).eps
    assert np.all(err <= bound), (err / bound).max()

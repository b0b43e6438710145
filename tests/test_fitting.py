"""scanalign.fitting: the CGA sphere fit (Kleppe, PhD thesis, NTNU 2018, (5.26)-(5.34), weighted
(6.5)-(6.11)) and Pratt's circle fit ((5.1)-(5.25)), against analytic truth and an independent
geometric least-squares oracle."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from scanalign.fitting import fit_circle_2d, fit_sphere, fit_spheres


def sphere_points(rng, c, r, n, noise=0.0, max_polar=np.pi):
    """Area-uniform points on a spherical cap of polar angle <= max_polar around +z."""
    ct = 1 - rng.random(n) * (1 - np.cos(max_polar))
    st = np.sqrt(np.clip(1 - ct**2, 0, None))
    phi = 2 * np.pi * rng.random(n)
    d = np.stack([st * np.cos(phi), st * np.sin(phi), ct], axis=1)
    return np.asarray(c) + (r + noise * rng.standard_normal(n))[:, None] * d


def geometric_oracle(p, w=None):
    """Independent oracle: minimise sum w (|p - c| - r)^2 with scipy (Levenberg-Marquardt)."""
    w = np.ones(len(p)) if w is None else w
    # start: Kasa's linear fit |p|^2 = 2 c.p + (r^2 - |c|^2), weighted least squares
    A = np.c_[2 * p, np.ones(len(p))] * np.sqrt(w)[:, None]
    x = np.linalg.lstsq(A, (p * p).sum(axis=1) * np.sqrt(w), rcond=None)[0]
    c0 = x[:3]
    r0 = np.sqrt(max(x[3] + c0 @ c0, 1e-12))
    res = least_squares(lambda x: np.sqrt(w) * (np.linalg.norm(p - x[:3], axis=1) - x[3]),
                        np.r_[c0, r0], method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return res.x[:3], res.x[3]


def test_exact_points_on_random_spheres():  # (5.31): exact points give the exact sphere
    rng = np.random.default_rng(0)
    for trial in range(40):
        c = rng.uniform(-3, 3, 3)
        r = rng.uniform(0.01, 2)
        p = sphere_points(rng, c, r, 5 + trial)
        f = fit_sphere(p)
        assert not f.is_plane and not f.imaginary
        np.testing.assert_allclose(f.center, c, atol=1e-9)
        assert abs(f.radius - r) < 1e-9
        assert f.rms < 1e-9 and f.count == 5 + trial
        np.testing.assert_allclose(f.dual, np.r_[c, 0.5 * (c @ c - r * r), 1.0], atol=1e-8)


def test_float32_input():
    rng = np.random.default_rng(1)
    p = sphere_points(rng, [0.1, 0.2, 0.5], 0.03, 200).astype(np.float32)
    f = fit_sphere(p)
    np.testing.assert_allclose(f.center, [0.1, 0.2, 0.5], atol=1e-6)
    assert abs(f.radius - 0.03) < 1e-6


def test_any_array_layout_gives_the_same_fit():
    """Strided rows (a[:, :3] of an (N, 4) array), Fortran order, reversed rows and nested lists
    are all accepted and fitted exactly as the C-contiguous array."""
    rng = np.random.default_rng(14)
    p = sphere_points(rng, [0.3, -0.2, 0.1], 0.2, 60, 1e-3)
    f = fit_sphere(p)
    padded = np.c_[p, np.ones(60)]
    for q in (padded[:, :3], np.asfortranarray(p), p[::-1], p.tolist()):
        g = fit_sphere(q)
        np.testing.assert_allclose(g.center, f.center, atol=1e-12)
        assert abs(g.radius - f.radius) < 1e-12


def test_noisy_cap_within_noise_and_matches_oracle():
    rng = np.random.default_rng(2)
    c, r, sigma = np.array([0.2, -0.1, 0.6]), 0.05, 3e-4
    p = sphere_points(rng, c, r, 3000, sigma, max_polar=np.pi / 3)
    f = fit_sphere(p)
    assert np.linalg.norm(f.center - c) < 1e-3 and abs(f.radius - r) < 1e-3
    assert abs(f.rms - sigma) < 0.2 * sigma
    co, ro = geometric_oracle(p)
    # (S.P)^2/S^2 = delta^2 (1 + delta/2r)^2 (5.27): the CGA optimum is close to the geometric one
    assert np.linalg.norm(f.center - co) < 0.1 * sigma
    assert abs(f.radius - ro) < 0.1 * sigma
    # and the geometric oracle's rms is the minimum, the CGA fit's within a hair of it
    rms_o = np.sqrt(np.mean((np.linalg.norm(p - co, axis=1) - ro) ** 2))
    assert rms_o <= f.rms + 1e-12 and f.rms < rms_o * (1 + 1e-4)


@pytest.mark.data
def test_bunny_patches_match_geometric_oracle(bunny):
    """Real-mesh data: neighbourhoods of the Stanford bunny (15 cm). The surface is not a
    sphere, so the truth is the geometric least-squares sphere of each patch."""
    points, _ = bunny
    rng = np.random.default_rng(3)
    checked = sphere_like = 0
    for i in rng.choice(len(points), 40, replace=False):
        patch = points[np.linalg.norm(points - points[i], axis=1) < 0.01]
        if len(patch) < 30:
            continue
        f = fit_sphere(patch)
        if f.is_plane:
            continue
        co, ro = geometric_oracle(patch)
        rms_o = np.sqrt(np.mean((np.linalg.norm(patch - co, axis=1) - ro) ** 2))
        rel = rms_o / ro
        # the oracle's geometric rms is the minimum; the CGA fit minimises
        # delta^2 (1 + delta/2r)^2 (5.27) instead, so its geometric rms exceeds the minimum by
        # a factor that grows with rms/r: negligible on sphere-like patches, a few % otherwise
        assert rms_o <= f.rms + 1e-12
        if rel < 0.05:
            assert f.rms <= rms_o * (1 + 0.2 * rel) + 1e-12
            sphere_like += 1
        else:
            assert f.rms < rms_o * 1.2
        checked += 1
    assert checked >= 30 and sphere_like >= 20


def test_coplanar_points_give_plane():  # (5.26)-(5.34): e0 coefficient ~ 0, a plane
    rng = np.random.default_rng(4)
    n = np.array([0.2, -0.6, 0.7])
    n /= np.linalg.norm(n)
    a = np.cross(n, [1.0, 0, 0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    delta = 0.8
    p = delta * n + rng.uniform(-0.1, 0.1, (50, 1)) * a + rng.uniform(-0.1, 0.1, (50, 1)) * b
    f = fit_sphere(p)
    assert f.is_plane
    np.testing.assert_allclose(f.normal, n, atol=1e-9)
    assert abs(f.distance - delta) < 1e-9 and f.rms < 1e-9
    assert np.isnan(f.radius) and np.all(np.isnan(f.center))
    np.testing.assert_allclose(f.dual, np.r_[n, delta, 0.0], atol=1e-9)
    # the opposite orientation of the same plane is reported with distance >= 0
    f2 = fit_sphere(-p)
    np.testing.assert_allclose(f2.normal, -n, atol=1e-9)
    assert abs(f2.distance - delta) < 1e-9


def test_weights_zero_removes_and_integers_duplicate():  # (6.5)-(6.6); invariant to weight scaling
    rng = np.random.default_rng(5)
    p = sphere_points(rng, [0, 0, 0.4], 0.1, 60, 0.005, 1.0)
    w = rng.integers(0, 4, 60).astype(float)
    w[:5] = 1
    dup = np.repeat(p, w.astype(int), axis=0)
    q = p.copy()
    q[w == 0] = np.nan  # removed points are never read
    fw, fd = fit_sphere(q, w), fit_sphere(dup)
    np.testing.assert_allclose(fw.center, fd.center, atol=1e-10)
    assert abs(fw.radius - fd.radius) < 1e-10 and abs(fw.rms - fd.rms) < 1e-10
    assert fw.count == np.count_nonzero(w)
    fz = fit_sphere(p[w > 0])
    np.testing.assert_allclose(fit_sphere(p, (w > 0).astype(float)).center, fz.center, atol=1e-12)
    fs = fit_sphere(q, 3.5 * w)  # uniform scaling of the weights changes nothing
    np.testing.assert_allclose(fs.center, fd.center, atol=1e-10)
    # the weighted fit agrees with a weighted geometric oracle on noisy data
    co, ro = geometric_oracle(p[w > 0], w[w > 0])
    assert np.linalg.norm(fw.center - co) < 1e-3 and abs(fw.radius - ro) < 1e-3


def test_permutation_and_rigid_motion():  # (5.27): permutation invariant, rigid-motion equivariant
    rng = np.random.default_rng(6)
    p = sphere_points(rng, [0.1, 0.1, 0.1], 0.2, 80, 0.01, 1.2)
    f = fit_sphere(p)
    g = fit_sphere(p[rng.permutation(80)])
    np.testing.assert_allclose(f.center, g.center, atol=1e-12)
    angle = 0.9
    axis = np.array([1.0, -2, 0.5]) / np.linalg.norm([1.0, -2, 0.5])
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    t = np.array([1.0, -0.5, 2.0])
    h = fit_sphere(p @ R.T + t)
    np.testing.assert_allclose(h.center, R @ f.center + t, atol=1e-10)
    assert abs(h.radius - f.radius) < 1e-10


@pytest.mark.parametrize("make, exc", [
    (lambda p: p[:4], ValueError),                     # fewer than 5 points
    (lambda p: p.astype(np.int64), TypeError),
    (lambda p: p[:, :2], ValueError),
    (lambda p: np.where(np.arange(10)[:, None] == 3, np.nan, p), ValueError),
    (lambda p: np.tile([[1.0, 2, 3]], (10, 1)), ValueError),                        # coincident
    (lambda p: np.outer(np.arange(10.0), [1, 2, 3]), ValueError),                   # collinear
    (lambda p: np.c_[np.cos(np.arange(10.0)), np.sin(np.arange(10.0)), np.ones(10)], ValueError),  # one circle
])
def test_bad_points(make, exc):
    p = sphere_points(np.random.default_rng(7), [0, 0, 0], 1, 10)
    with pytest.raises(exc):
        fit_sphere(make(p))


def test_bad_weights():
    p = sphere_points(np.random.default_rng(8), [0, 0, 0], 1, 10)
    for w, exc in [(np.zeros(10), ValueError), (-np.ones(10), ValueError), (np.ones(9), ValueError),
                   (np.r_[np.ones(9), np.inf], ValueError), (np.array(["a"] * 10), TypeError),
                   (np.r_[np.ones(4), np.zeros(6)], ValueError)]:
        with pytest.raises(exc):
            fit_sphere(p, w)
    with pytest.raises(ValueError):
        fit_sphere(p, plane_tolerance=-1)


def test_batched_matches_single():
    rng = np.random.default_rng(9)
    groups = [sphere_points(rng, rng.uniform(-1, 1, 3), rng.uniform(0.01, 0.5), 50, 1e-3, 1.0) for _ in range(30)]
    groups.append(np.zeros((3, 3)))  # too few points: NaN row, no exception
    pts = np.concatenate(groups)
    offsets = np.r_[0, np.cumsum([len(g) for g in groups])]
    b = fit_spheres(pts, offsets)
    for k, g in enumerate(groups[:-1]):
        f = fit_sphere(g)
        np.testing.assert_allclose(b.center[k], f.center, atol=1e-12)
        assert abs(b.radius[k] - f.radius) < 1e-12 and b.count[k] == 50
    assert b.count[-1] == 0 and np.isnan(b.radius[-1]) and np.all(np.isnan(b.dual[-1]))
    # every field of the batch is the single fit's, also read back one group at a time
    assert len(b) == 31 and b.center.shape == (31, 3) and b.dual.shape == (31, 5) and b.normal.shape == (31, 3)
    for k in (0, 7, 29):
        f = fit_sphere(groups[k])
        np.testing.assert_allclose(b.dual[k], f.dual, atol=1e-10)
        assert b.is_plane[k] == f.is_plane and b.imaginary[k] == f.imaginary and abs(b.rms[k] - f.rms) < 1e-12
        assert b[k].radius == b.radius[k] and b[k - 31].count == b.count[k]
    with pytest.raises(IndexError):
        b[31]
    with pytest.raises(ValueError):
        fit_spheres(pts, offsets[::-1])
    with pytest.raises(ValueError):
        fit_spheres(pts, np.r_[offsets[:-1], len(pts) + 1])
    with pytest.raises(TypeError):
        fit_spheres(pts, offsets.astype(float))


def test_pratt_analytic_circles():
    rng = np.random.default_rng(10)
    for trial in range(30):
        c = rng.uniform(-2, 2, 2)
        r = rng.uniform(0.01, 1.5)
        t = rng.uniform(0, 2 * np.pi, 3 + trial)
        p = c + r * np.c_[np.cos(t), np.sin(t)]
        f = fit_circle_2d(p)
        np.testing.assert_allclose(f.center, c, atol=1e-9)
        assert abs(f.radius - r) < 1e-9 and f.rms < 1e-9
        a, d, e, ff = f.coefficients
        assert abs(d * d + e * e - 4 * a * ff - 1) < 1e-9


def test_pratt_noisy_arc_matches_oracle():
    rng = np.random.default_rng(11)
    c, r, sigma = np.array([0.3, -0.2]), 0.1, 1e-3
    t = rng.uniform(0, 2.0, 500)
    p = c + (r + sigma * rng.standard_normal(500))[:, None] * np.c_[np.cos(t), np.sin(t)]
    f = fit_circle_2d(p)
    res = least_squares(lambda x: np.linalg.norm(p - x[:2], axis=1) - x[2], np.r_[p.mean(0), 0.05], method="lm")
    assert np.linalg.norm(f.center - res.x[:2]) < 0.5 * sigma and abs(f.radius - res.x[2]) < 0.5 * sigma
    assert np.linalg.norm(f.center - c) < 5 * sigma


def test_pratt_bad_input():
    for p, exc in [(np.zeros((2, 2)), ValueError), (np.c_[np.arange(5.0), np.arange(5.0)], ValueError),
                   (np.array([[0, 0], [1, 0], [0, np.nan]]), ValueError), (np.zeros((5, 3)), ValueError),
                   (np.array([[0, 0], [1, 0], [0, 1]]), TypeError)]:
        with pytest.raises(exc):
            fit_circle_2d(p)


def test_far_from_origin_and_tiny_scale():
    """Centring and scaling inside the fit keep it exact for data far from the origin or in
    a small patch (a naive Q of raw coordinates loses ~|p|^4 / r^4 to rounding)."""
    rng = np.random.default_rng(12)
    for c, r in [(np.array([1000.0, -2000.0, 500.0]), 0.05), (np.array([0.3, 0.2, 0.9]), 1e-4)]:
        p = sphere_points(rng, c, r, 100, max_polar=0.8)
        f = fit_sphere(p)
        assert np.linalg.norm(f.center - c) < 1e-6 * r + 1e-9
        assert abs(f.radius - r) < 1e-6 * r + 1e-9


def test_noisy_plane_is_plane_or_huge_sphere_no_worse_than_plane_fit():
    """Noisy planar data: spheres include planes as a limit, so the fit is never worse than the
    least-squares plane (SVD oracle) and, when a sphere, it is far larger than the patch."""
    rng = np.random.default_rng(13)
    n = np.array([0.0, 0.6, 0.8])
    a, b = np.array([1.0, 0, 0]), np.cross(n, [1.0, 0, 0])
    sigma = 1e-4
    p = 0.5 * n + rng.uniform(-0.05, 0.05, (400, 1)) * a + rng.uniform(-0.05, 0.05, (400, 1)) * b
    p += sigma * rng.standard_normal((400, 1)) * n
    m = p.mean(axis=0)
    n_svd = np.linalg.svd(p - m)[2][-1]
    rms_plane = np.sqrt(np.mean(((p - m) @ n_svd) ** 2))
    f = fit_sphere(p)
    assert f.rms <= rms_plane * (1 + 1e-6)
    if f.is_plane:
        assert abs(abs(f.normal @ n) - 1) < 1e-3
    else:
        assert f.radius > 1.0  # 20x the 5 cm patch
    g = fit_sphere(p, plane_tolerance=1.0)  # everything flatter than the patch counts as a plane
    assert g.is_plane and abs(abs(g.normal @ n) - 1) < 1e-3 and abs(g.rms - sigma) < 0.2 * sigma

"""The bilateral depth filter (vectorised, polynomial exp) against a straightforward NumPy
implementation of its definition in float64, on a synthetic SR300 frame and on images with
invalid pixels, depth edges and borders."""

from __future__ import annotations

import numpy as np
import pytest

from scanalign import synthetic
from scanalign.reconstruction import BilateralFilterSettings, bilateral_filter_depth


def reference(depth: np.ndarray, radius: int, sigma_space: float, sigma_depth: float) -> np.ndarray:
    """Each valid pixel: the mean of the valid pixels within `radius` (a square window),
    weighted by exp(-(dx^2 + dy^2) / 2 sigma_space^2) exp(-dz^2 / 2 sigma_depth^2)."""
    z = depth.astype(np.float64)
    valid = np.isfinite(z) & (z > 0)
    h, w = z.shape
    padded = np.full((h + 2 * radius, w + 2 * radius), np.nan)
    padded[radius:radius + h, radius:radius + w] = np.where(valid, z, np.nan)
    num = np.zeros_like(z)
    den = np.zeros_like(z)
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            n = padded[radius + dy:radius + dy + h, radius + dx:radius + dx + w]
            ok = np.isfinite(n)
            wgt = np.exp(-(dx * dx + dy * dy) / (2 * sigma_space**2)) * np.exp(-((n - z) ** 2) / (2 * sigma_depth**2))
            wgt = np.where(ok, wgt, 0.0)
            num += np.where(ok, wgt * n, 0.0)
            den += wgt
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(valid, num / den, np.nan)


def check(depth: np.ndarray, f: BilateralFilterSettings) -> None:
    got = bilateral_filter_depth(depth.astype(np.float32), f)
    want = reference(depth, f.radius, f.sigma_space, f.sigma_depth)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    ok = ~np.isnan(want)
    # Documented tolerance: float rounding, 3e-6 of the depth. The float sums of up to 121
    # terms dominate (the filter with libm's expf was 1.5e-6 off at radius 5 too); the
    # polynomial exp adds about 1e-7 per weight.
    np.testing.assert_allclose(got[ok], want[ok], rtol=3e-6, atol=0)


@pytest.mark.parametrize("f", [BilateralFilterSettings(), BilateralFilterSettings(radius=0), BilateralFilterSettings(radius=1, sigma_space=0.7),
                               BilateralFilterSettings(radius=3, sigma_space=2.0, sigma_depth=0.01),
                               BilateralFilterSettings(radius=5, sigma_space=3.0, sigma_depth=0.001)])
def test_filter_equals_the_definition_on_a_sr300_frame(f):
    frame = synthetic.builtin_scan(n_frames=4).frames[2]
    depth = frame.depth.astype(np.float64) * frame.depth_scale
    depth[frame.depth == 0] = np.nan
    check(depth, f)


def test_filter_equals_the_definition_with_holes_edges_and_odd_sizes():
    rng = np.random.default_rng(7)
    for h, w in [(1, 1), (3, 17), (37, 53), (64, 9)]:
        v, u = np.mgrid[0:h, 0:w]
        depth = 0.5 + 0.002 * u - 0.001 * v + rng.normal(0, 0.002, (h, w))
        depth[u > w // 2] += 0.3                               # a depth edge
        depth[rng.random((h, w)) < 0.15] = 0.0                 # dropouts (0 = invalid)
        depth[rng.random((h, w)) < 0.05] = np.nan
        depth[rng.random((h, w)) < 0.02] = np.inf
        depth[rng.random((h, w)) < 0.02] = -1.0
        for f in (BilateralFilterSettings(), BilateralFilterSettings(radius=4, sigma_space=2.5, sigma_depth=0.05)):
            check(depth, f)

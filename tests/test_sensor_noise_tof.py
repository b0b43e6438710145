"""The time-of-flight depth model (issue 30 §2: the fixed 3D camera of the thesis's Paper 3 is a Kinect One): axial
noise growing as z^1.5 and mixed ("flying") pixels between the two surfaces at depth edges, against the model's own
analytic values on a rendered step; the triangulation presets keep dropping their edge pixels."""

from __future__ import annotations

import numpy as np
import pytest

from scanalign import _core
from scanalign.synthetic import NOISE_PRESETS, SensorNoise


def _step(h=400, w=400, near=1.0, far=1.5):
    z = np.full((h, w), near, np.float32)
    z[:, w // 2:] = far
    return z, np.ones_like(z)


def test_kinect_one_axial_noise_follows_its_power_law():
    tof = NOISE_PRESETS["kinect_one"]
    assert tof.sigma(np.array([1.0, 2.0, 4.0])) == pytest.approx([0.0015, 0.0015 * 2 ** 1.5, 0.012])
    for depth in (1.0, 2.0, 3.0):
        z = np.full((300, 300), depth, np.float32)
        out = _core.synthetic.apply_sensor_noise(tof, z, np.ones_like(z), 7)
        err = out[np.isfinite(out)] - depth
        expect = np.sqrt(tof.sigma(depth) ** 2 + tof.depth_unit ** 2 / 12)  # Gaussian plus rounding to 1 mm
        assert abs(err.std() / expect - 1) < 0.03, (depth, err.std(), expect)
        assert abs(err.mean()) < 3 * expect / np.sqrt(err.size) + 1e-5
        assert 0.98 < np.isfinite(out).mean() < 1.0  # 0.5 % random holes


def test_kinect_one_edges_give_mixed_depths_between_the_surfaces():
    z, c = _step()
    tof = NOISE_PRESETS["kinect_one"]
    out = _core.synthetic.apply_sensor_noise(tof, z, c, 3)
    edge = out[:, 199:201]  # the two columns on each side of the step (edge_width 1)
    between = np.isfinite(edge) & (edge > 1.0 + 6 * tof.sigma(1.0)) & (edge < 1.5 - 6 * tof.sigma(1.5))
    # Half of the edge pixels mix (a uniform depth between 1.0 and 1.5, a few land within 6 sigma of either side).
    frac = between.mean()
    assert 0.40 < frac < 0.5, frac
    assert np.isnan(edge).mean() == pytest.approx(0.5, abs=0.06)
    # Away from the edge, no pixel lies between the surfaces.
    rest = np.delete(out, [199, 200], axis=1)
    assert not ((rest > 1.0 + 6 * tof.sigma(1.0)) & (rest < 1.5 - 6 * tof.sigma(1.5))).any()


@pytest.mark.parametrize("preset", ["sr300", "d435", "zivid"])
def test_triangulation_presets_drop_their_edge_pixels(preset):
    z, c = _step()
    noise = NOISE_PRESETS[preset]
    assert noise.axial_exponent == 2.0 and noise.flying_pixels == 0.0
    out = _core.synthetic.apply_sensor_noise(noise, z, c, 3)
    w = noise.edge_width
    assert np.isnan(out[:, 200 - w:200 + w]).all()


def test_bad_tof_fields_are_refused_by_name():
    with pytest.raises(ValueError, match="flying_pixels"):
        SensorNoise(flying_pixels=1.5)
    with pytest.raises(ValueError, match="axial_exponent"):
        SensorNoise(axial_exponent=-1.0)

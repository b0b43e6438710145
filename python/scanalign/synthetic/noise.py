"""Depth sensor error models: axial noise, dropouts at grazing angles and depth edges,
range limits and quantisation, with RealSense- and Zivid-like presets."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, Union

import numpy as np

__all__ = ["SensorNoise", "NOISE_PRESETS"]


@dataclass(frozen=True)
class SensorNoise:
    """A depth sensor's error model, applied to noise-free depth.

    In order: pixels are dropped at grazing incidence (``|cos| < grazing_cos``), on both
    sides of depth discontinuities (a 4-neighbour more than ``edge_threshold`` times the
    depth nearer or farther, or missing) dilated to ``edge_width`` pixels, and at random with
    probability ``dropout``; the rest get axial Gaussian noise of standard deviation
    ``sigma(z) = axial_sigma_ref * (z / z_ref)**2`` (triangulation sensors: the depth error
    grows with the square of the distance); values outside ``[min_range, max_range]`` are
    dropped; the result is rounded to multiples of ``depth_unit`` (0 = no quantisation).

    Attributes:
        name: label.
        axial_sigma_ref: standard deviation of the depth error at ``z_ref`` (m).
        z_ref: reference depth (m).
        depth_unit: quantisation step of the reported depth (m); 0 for none.
        min_range, max_range: measurable depth range (m).
        grazing_cos: minimum |cosine of incidence| for a measurement.
        edge_threshold: relative depth jump marking a discontinuity; 0 disables edge dropout.
        edge_width: pixels dropped on each side of a discontinuity (>= 1 when enabled).
        dropout: probability that any other pixel is missing.
    """

    name: str = "custom"
    axial_sigma_ref: float = 0.0
    z_ref: float = 1.0
    depth_unit: float = 0.0
    min_range: float = 0.0
    max_range: float = math.inf
    grazing_cos: float = 0.0
    edge_threshold: float = 0.0
    edge_width: int = 0
    dropout: float = 0.0

    def __post_init__(self) -> None:
        for n in ("axial_sigma_ref", "depth_unit", "min_range", "grazing_cos", "edge_threshold", "dropout"):
            v = getattr(self, n)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"SensorNoise.{n} must be finite and >= 0, got {v!r}")
        if not (math.isfinite(self.z_ref) and self.z_ref > 0):
            raise ValueError("SensorNoise.z_ref must be positive (m)")
        if not self.max_range > self.min_range:
            raise ValueError("SensorNoise.max_range must exceed min_range")
        if self.grazing_cos >= 1 or self.dropout >= 1:
            raise ValueError("SensorNoise.grazing_cos and dropout must be < 1")
        if int(self.edge_width) != self.edge_width or self.edge_width < 0:
            raise ValueError("SensorNoise.edge_width must be a non-negative integer")

    def sigma(self, z: Union[float, np.ndarray]) -> Union[float, np.ndarray]:
        """Axial standard deviation (m) at depth ``z`` (m)."""
        return self.axial_sigma_ref * (np.asarray(z) / self.z_ref) ** 2

    def apply(self, depth: np.ndarray, cos_incidence: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Noisy (H, W) float32 depth in metres (NaN = missing) from noise-free ``depth``
        (float, NaN = nothing hit) and the rendered ``cos_incidence``; all randomness from
        ``rng``."""
        z = np.asarray(depth, dtype=np.float32)
        valid = np.isfinite(z)
        if self.grazing_cos > 0:
            valid &= np.abs(cos_incidence) >= self.grazing_cos
        if self.edge_threshold > 0 and self.edge_width > 0:
            valid &= ~_depth_edges(z, self.edge_threshold, int(self.edge_width))
        if self.dropout > 0:
            valid &= rng.random(z.shape, dtype=np.float32) >= self.dropout
        out = np.full(z.shape, np.nan, dtype=np.float32)
        zv = z[valid].astype(np.float64)
        if self.axial_sigma_ref > 0:
            zv = zv + self.sigma(zv) * rng.standard_normal(zv.shape, dtype=np.float32)
        keep = (zv >= self.min_range) & (zv <= self.max_range)
        if self.depth_unit > 0:
            zv = np.round(zv / self.depth_unit) * self.depth_unit
        zv[~keep] = np.nan
        out[valid] = zv
        return out


def _depth_edges(z: np.ndarray, threshold: float, width: int) -> np.ndarray:
    """Pixels within ``width`` pixels of a depth discontinuity: a 4-neighbour pair whose
    depths differ by more than ``threshold`` times the nearer one, or where exactly one of
    the two sees a surface (a silhouette against the void). Both sides are marked."""
    valid = np.isfinite(z)
    zz = np.where(valid, z, 0.0)
    edge = np.zeros(z.shape, dtype=bool)
    for a, b in (((slice(None, -1), slice(None)), (slice(1, None), slice(None))),
                 ((slice(None), slice(None, -1)), (slice(None), slice(1, None)))):
        va, vb = valid[a], valid[b]
        jump = (va != vb) | (va & vb & (np.abs(zz[a] - zz[b]) > threshold * np.minimum(zz[a], zz[b])))
        edge[a] |= jump
        edge[b] |= jump
    for _ in range(width - 1):  # dilate by one pixel per step (4-neighbourhood)
        grown = edge.copy()
        grown[1:] |= edge[:-1]
        grown[:-1] |= edge[1:]
        grown[:, 1:] |= edge[:, :-1]
        grown[:, :-1] |= edge[:, 1:]
        edge = grown
    return edge & valid


#: Sensor presets. The axial noise follows the triangulation law sigma = z^2 e / (f b)
#: (disparity error e in pixels, focal length f in pixels, baseline b), hence
#: sigma(z) = sigma_ref (z / z_ref)^2. The two RealSense cameras are those of the eye-in-hand
#: paper (Comput. Electron. Agric. 180 (2021) 105929, §4): an SR300 on the robot, a D435 free-hand.
#:
#: - ``"sr300"``: Intel RealSense SR300 (coded light): about 1 mm at 0.4 m; depth unit 1/8 mm
#:   (its default depth scale); range 0.2-1.5 m (datasheet); it loses pixels beyond ~78 deg
#:   incidence and one pixel around depth edges (projector shadow).
#: - ``"d435"``: Intel RealSense D435 (active stereo) at 640x480: f = 385 px, b = 50 mm and a
#:   typical sub-pixel disparity error of 0.15 px give 0.15 / (385 * 0.05) = 7.8e-3 /m, i.e.
#:   1.95 mm at 0.5 m; depth unit 1 mm (its default); minimum depth about 0.175 m at this
#:   resolution, 3 m useful maximum; stereo matching fails at grazing angles (~75 deg) and
#:   fattens edges (2 pixels), plus 0.5 % random holes.
#: - ``"zivid"``: Zivid Two-like structured-light industrial camera: about 0.1 mm at 0.5 m,
#:   no quantisation of its float output, working range 0.3-1.2 m, few holes.
#: - ``"none"``: the exact rendered depth.
NOISE_PRESETS: Dict[str, SensorNoise] = {
    "none": SensorNoise(name="none"),
    "sr300": SensorNoise(name="sr300", axial_sigma_ref=0.0010, z_ref=0.4, depth_unit=0.000125, min_range=0.2,
                         max_range=1.5, grazing_cos=0.2, edge_threshold=0.02, edge_width=1, dropout=0.002),
    "d435": SensorNoise(name="d435", axial_sigma_ref=0.00195, z_ref=0.5, depth_unit=0.001, min_range=0.175,
                        max_range=3.0, grazing_cos=0.25, edge_threshold=0.02, edge_width=2, dropout=0.005),
    "zivid": SensorNoise(name="zivid", axial_sigma_ref=0.0001, z_ref=0.5, depth_unit=0.0, min_range=0.3,
                         max_range=1.2, grazing_cos=0.1, edge_threshold=0.02, edge_width=1, dropout=0.0),
}


def as_noise(noise: Union[SensorNoise, str, None]) -> SensorNoise:
    """A :class:`SensorNoise`, a preset name, or None ("none") as a :class:`SensorNoise`."""
    if noise is None:
        return NOISE_PRESETS["none"]
    if isinstance(noise, str):
        try:
            return NOISE_PRESETS[noise]
        except KeyError:
            raise ValueError(f"unknown noise preset {noise!r}; known: {sorted(NOISE_PRESETS)}") from None
    if not isinstance(noise, SensorNoise):
        raise TypeError(f"noise: expected SensorNoise or a preset name, got {type(noise)!r}")
    return noise

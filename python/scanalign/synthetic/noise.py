"""Depth sensor error models: axial noise, dropouts at grazing angles and depth edges,
range limits and quantisation, with RealSense- and Zivid-like presets."""

from __future__ import annotations

from typing import Dict, Union

from scanalign import _core

__all__ = ["SensorNoise", "NOISE_PRESETS"]


#: A depth sensor's error model (the C++ type; fields and units in its docstring).
SensorNoise = _core.synthetic.SensorNoise


#: Sensor presets. The axial noise follows the triangulation law sigma = z^2 e / (f b) (disparity error e in pixels,
#: focal length f in pixels, baseline b), hence sigma(z) = sigma_ref (z / z_ref)^2. The two RealSense cameras are those
#: of the eye-in-hand paper (Comput. Electron. Agric. 180 (2021) 105929, §4): an SR300 on the robot, a D435 free-hand.
#:
#: - ``"sr300"``: Intel RealSense SR300 (coded light): about 1 mm at 0.4 m; depth unit 1/8 mm
#:   (its default depth scale); range 0.2-1.5 m (datasheet); it loses pixels beyond ~78 deg
#:   incidence and one pixel around depth edges (projector shadow).
#: - ``"d435"``: Intel RealSense D435 (active stereo) at 640x480: f = 385 px, b = 50 mm and a typical sub-pixel
#:   disparity error of 0.15 px give 0.15 / (385 * 0.05) = 7.8e-3 /m, i.e. 1.95 mm at 0.5 m; depth unit 1 mm (its
#:   default); minimum depth about 0.175 m at this resolution, 3 m useful maximum; stereo matching fails at grazing
#:   angles (~75 deg) and fattens edges (2 pixels), plus 0.5 % random holes.
#: - ``"zivid"``: Zivid Two-like structured-light industrial camera: about 0.1 mm at 0.5 m,
#:   no quantisation of its float output, working range 0.3-1.2 m, few holes.
#: - ``"kinect_one"``: Microsoft Kinect One (Kinect v2, time of flight), the fixed 3D camera of the thesis's Paper 3
#:   (Kleppe et al., Robotics 6 (2017) 14): axial noise about 1.5 mm at 1 m growing as z^1.5 (time of flight: the
#:   error follows the return's amplitude, not a baseline; 1-4 mm between 1 and 3 m is the usual range of reports),
#:   depth unit 1 mm, range 0.5-4.5 m (datasheet), dropped beyond ~80 deg incidence, and at depth edges mixed
#:   ("flying") pixels between the two surfaces for half of the edge pixels (the other half dropped), 0.5 % holes.
#: - ``"none"``: the exact rendered depth.
NOISE_PRESETS: Dict[str, SensorNoise] = {
    "none": SensorNoise(name="none"),
    "sr300": SensorNoise(name="sr300", axial_sigma_ref=0.0010, z_ref=0.4, depth_unit=0.000125, min_range=0.2,
                         max_range=1.5, grazing_cos=0.2, edge_threshold=0.02, edge_width=1, dropout=0.002),
    "d435": SensorNoise(name="d435", axial_sigma_ref=0.00195, z_ref=0.5, depth_unit=0.001, min_range=0.175,
                        max_range=3.0, grazing_cos=0.25, edge_threshold=0.02, edge_width=2, dropout=0.005),
    "zivid": SensorNoise(name="zivid", axial_sigma_ref=0.0001, z_ref=0.5, min_range=0.3, max_range=1.2,
                         grazing_cos=0.1, edge_threshold=0.02, edge_width=1),  # no quantisation, no random holes
    "kinect_one": SensorNoise(name="kinect_one", axial_sigma_ref=0.0015, z_ref=1.0, axial_exponent=1.5,
                              depth_unit=0.001, min_range=0.5, max_range=4.5, grazing_cos=0.17, edge_threshold=0.03,
                              edge_width=1, flying_pixels=0.5, dropout=0.005),
}


def as_noise(noise: Union[SensorNoise, str, None]) -> SensorNoise:
    """A :class:`SensorNoise`, a preset name, or None ("none") as a :class:`SensorNoise`."""
    noise = "none" if noise is None else noise
    if not isinstance(noise, (str, SensorNoise)):
        raise TypeError(f"noise: expected SensorNoise or a preset name, got {type(noise)!r}")
    if isinstance(noise, str) and noise not in NOISE_PRESETS:
        raise ValueError(f"unknown noise preset {noise!r}; known: {sorted(NOISE_PRESETS)}")
    return NOISE_PRESETS[noise] if isinstance(noise, str) else noise

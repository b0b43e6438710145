"""scanalign: real-time eye-in-hand 3D reconstruction and CAD-based pose estimation.

Submodules are imported on first use so ``import scanalign`` stays fast:

- :mod:`scanalign.registration` -- ICP engine (point-to-plane LLS, box rejector),
  stock PCL baselines.
- :mod:`scanalign.features` -- surface normals, PCA shape factors.
- :mod:`scanalign.reconstruction` -- depth to cloud, frame-to-model reconstruction, voxel grid.
- :mod:`scanalign.segmentation` -- RANSAC planes and spheres (CGA models), table segmentation.
- :mod:`scanalign.fitting` -- CGA sphere / plane fit (weighted), Pratt circle fit.
- :mod:`scanalign.io` -- PCD / PLY / OFF / STL / OBJ readers and a PLY writer.
- :mod:`scanalign.datasets` -- real test data from Debian packages, built-in objects.
- :mod:`scanalign.camera` -- pinhole intrinsics and RGB-D frames.
- :mod:`scanalign.trajectory` -- timestamped camera poses, the TUM trajectory format.
- :mod:`scanalign.tum` -- RGB-D sequences in the TUM RGB-D benchmark folder layout.
- :mod:`scanalign.synthetic` -- the synthetic eye-in-hand RGB-D scanner (ground truth known).
- :mod:`scanalign.pipeline` -- the reconstruction job: frames in, model, trajectory and report out.
- :mod:`scanalign.evaluation` -- ATE / RPE (Sturm et al. 2012), exact cloud-to-mesh distance.
- :mod:`scanalign.cga` -- conformal geometric algebra G(4,1): points, spheres, planes, lines, motors.
- :mod:`scanalign.cad` -- CAD model to clouds: tessellated-sphere viewpoint sampling.
- :mod:`scanalign.cbd` -- the curvature-based descriptor (keypoints, weighted CGA spheres, matching).
- :mod:`scanalign.pose` -- CAD-model pose: motor estimation, RANSAC, CBD / paper 4 / PCL baseline
  alignment, the table-scene pipeline.
- :mod:`scanalign.kinematics` -- 6R robots (KUKA KR6 R900 sixx, UR arms): forward kinematics, analytic CGA
  inverse kinematics.
- :mod:`scanalign.plots` -- trajectory, per-frame and benchmark figures (matplotlib, Agg).

Units are metres and radians throughout.  A transform named ``T_a_b`` is a 4x4
homogeneous matrix that maps coordinates expressed in frame ``b`` into frame ``a``
(``p_a = T_a_b @ p_b``).
"""

from __future__ import annotations

import importlib
from typing import Any

__version__ = "0.1.0"

_SUBMODULES = ("registration", "features", "reconstruction", "io", "datasets", "camera", "trajectory", "tum",
               "synthetic", "cga", "kinematics", "cad", "cbd", "pose", "fitting", "segmentation", "pipeline", "evaluation", "plots", "cli")

__all__ = ["__version__", *_SUBMODULES]


def __getattr__(name: str) -> Any:  # PEP 562: lazy submodules
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)

"""scanalign: real-time eye-in-hand 3D reconstruction and CAD-based pose estimation.

Submodules are imported on first use so ``import scanalign`` stays fast:

- :mod:`scanalign.registration` -- ICP engine (point-to-plane LLS, box rejector),
  stock PCL baselines.
- :mod:`scanalign.features` -- surface normals, PCA shape factors.
- :mod:`scanalign.reconstruction` -- depth to cloud, frame-to-model reconstruction, voxel grid.
- :mod:`scanalign.segmentation` -- RANSAC planes and spheres (CGA models), table segmentation.
- :mod:`scanalign.fitting` -- CGA sphere / plane fit (weighted), Pratt circle fit.
- :mod:`scanalign.io` -- PCD / PLY / OFF / STL / OBJ readers and a PLY writer.
- :mod:`scanalign.datasets` -- real test data downloaded from Debian packages and PyPI.
- :mod:`scanalign.parts` -- the built-in part (mesh and sampled cloud), area-weighted mesh sampling.
- :mod:`scanalign.rendering` -- exact z-buffer depth rendering of meshes, ``look_at`` camera poses.
- :mod:`scanalign.camera` -- pinhole intrinsics and RGB-D frames.
- :mod:`scanalign.trajectory` -- timestamped camera poses, the TUM trajectory format, the one
  timestamp-association rule (``associate_timestamps``).
- :mod:`scanalign.tum` -- RGB-D sequences in the TUM RGB-D benchmark folder layout.
- :mod:`scanalign.synthetic` -- the synthetic eye-in-hand RGB-D scanner (ground truth known).
- :mod:`scanalign.pipeline` -- the reconstruction job: frames in, model, trajectory and report out.
- :mod:`scanalign.evaluation` -- ATE / RPE (Sturm et al. 2012).
- :mod:`scanalign.mesh_metrics` -- exact cloud-to-mesh distance (C++ BVH) and its statistics.
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

_SUBMODULES = ("registration", "features", "reconstruction", "io", "datasets", "parts", "rendering", "camera",
               "trajectory", "tum", "synthetic", "cga", "kinematics", "cad", "cbd", "pose", "fitting", "segmentation",
               "pipeline", "evaluation", "mesh_metrics", "plots", "se3", "cli")

__all__ = ["__version__", *_SUBMODULES]


def __getattr__(name: str) -> Any:  # PEP 562: lazy submodules
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)

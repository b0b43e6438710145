"""scanalign: real-time eye-in-hand 3D reconstruction and CAD-based pose estimation.

Submodules, imported on first use so ``import scanalign`` stays fast: ``registration`` (ICP
engine, PCL baselines), ``features`` (normals, shape factors), ``reconstruction`` (depth to
cloud, frame-to-model, voxel grid), ``segmentation`` and ``fitting`` (RANSAC, CGA sphere and
plane fits), ``cga``, ``cad``, ``cbd`` and ``pose`` (CAD-model pose), ``kinematics`` (FK and
analytic IK of 6R arms), ``io``, ``tum``, ``trajectory`` and ``datasets`` (files and data),
``camera``, ``rendering``, ``parts`` and ``synthetic`` (the simulated eye-in-hand scanner),
``pipeline``, ``evaluation`` and ``mesh_metrics`` (the reconstruction job and its metrics),
``calibration``, ``grasp`` and ``pick`` (hand-eye, grasps, the pick pipeline), ``part_library``
and ``batch`` (batch runs on a process pool or Ray), ``urdf`` (robots from URDF), ``config`` (settings
files for the commands), ``interop`` and ``viewer`` (Open3D/trimesh objects, a live rerun view),
``se3``, ``plots`` and ``cli``. Each
module's docstring describes it.

Units are metres and radians throughout.  A transform named ``T_a_b`` is a 4x4
homogeneous matrix that maps coordinates expressed in frame ``b`` into frame ``a``
(``p_a = T_a_b @ p_b``).
"""

from __future__ import annotations

import importlib
from typing import Any

_SUBMODULES = ("registration", "features", "reconstruction", "io", "datasets", "parts", "rendering", "camera",
               "trajectory", "tum", "synthetic", "cga", "kinematics", "cad", "cbd", "pose", "fitting", "segmentation",
               "pipeline", "evaluation", "mesh_metrics", "plots", "se3", "cli", "calibration", "grasp", "pick",
               "part_library", "batch", "urdf", "config", "sources", "interop", "viewer")

__all__ = ["__version__", *_SUBMODULES]


def __getattr__(name: str) -> Any:  # PEP 562: lazy submodules
    if name == "__version__":  # the compiled core's, from CMakeLists.txt (the one version source)
        from ._core import __version__

        return __version__
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)

"""scanalign: real-time eye-in-hand 3D reconstruction and CAD-based pose estimation.

Subpackages, imported on first use so ``import scanalign`` stays fast. The areas mirror the compiled core
(``_core.<area>``) and the C++ tree (``cpp/include/scanalign/<area>/``): ``common`` (argument checks, rigid transforms,
the settings schema), ``io`` (clouds, meshes, Open3D/trimesh interop), ``registration`` (ICP engine, PCL baselines),
``features``, ``segmentation``, ``fitting``, ``cga``, ``calibration`` (hand-eye), ``evaluation`` (trajectories, ATE/RPE,
cloud-to-mesh), ``kinematics`` (FK and analytic IK, URDF), ``reconstruction`` (cameras, depth, rendering,
frame-to-model), ``pose`` (CBD, model views, CAD pose, part identification), ``grasp`` (parts, grasps, planning, the
part library) and ``synthetic`` (the simulated eye-in-hand scanner). Above them the application layers: ``data``
(built-in parts, test data downloads), ``datasets`` (recordings: one ``open_source`` factory), ``pipelines``
(reconstruct, pick, batch), ``viz`` (plots, reports, the live viewer) and ``cli``. docs/architecture.md draws the map
and its import rules.

Units are metres and radians throughout.  A transform named ``T_a_b`` is a 4x4 homogeneous matrix
that maps coordinates expressed in frame ``b`` into frame ``a`` (``p_a = T_a_b @ p_b``).
"""

from __future__ import annotations

import importlib
from typing import Any

_SUBMODULES = ("common", "io", "registration", "features", "segmentation", "fitting", "cga", "calibration",
               "evaluation", "kinematics", "reconstruction", "pose", "grasp", "synthetic", "data", "datasets",
               "pipelines", "viz", "cli")

__all__ = ["__version__", *_SUBMODULES]


def __getattr__(name: str) -> Any:  # PEP 562: lazy submodules
    if name == "__version__":  # the compiled core's, from CMakeLists.txt (the one version source)
        from scanalign._core import __version__

        return __version__
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)

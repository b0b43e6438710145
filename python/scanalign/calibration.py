"""Hand-eye calibration of an eye-in-hand camera: ``T_flange_camera`` from robot poses and
camera poses (AX = ZB; see ``docs/api/calibration.md``).

The robot's forward kinematics gives ``T_base_flange[i]`` (flange -> base) and the camera
gives its pose in a frame ``world`` that is fixed but unknown relative to the base:

- views of a fixed, known target: ``T_camera_target[i]`` (target -> camera, e.g. a
  checkerboard pose from PnP); ``world`` is the target;
- no target: the frame-to-model ICP trajectory of a scan, ``T_world_camera[i]`` (camera ->
  the scan's model frame; :func:`scanalign.pipelines.reconstruct.reconstruct` with
  ``model_frame="camera"``, whose model frame is the first camera's).

Both unknowns are solved for: ``T_base_flange[i] @ T_flange_camera = T_base_world @ T_world_camera[i]``. The closed form
is Daniilidis' dual-quaternion method (1999) over all pose pairs, refined by Levenberg-Marquardt on SE(3) (the C++ core,
``scanalign._core.calibration``). Metres and radians.
"""

from __future__ import annotations

from typing import Any, Optional

from scanalign import _core
from scanalign.common.settings import with_overrides

__all__ = ["HandEyeSettings", "HandEyeResult", "calibrate_hand_eye"]

_C = _core.calibration

HandEyeSettings = _C.HandEyeSettings
HandEyeResult = _C.HandEyeResult


def calibrate_hand_eye(T_base_flange: Any, T_camera_target: Any = None, *, T_world_camera: Any = None,
                       settings: Optional[HandEyeSettings] = None, **overrides: Any) -> HandEyeResult:
    """Solves ``T_base_flange[i] @ X = Z @ T_world_camera[i]`` for ``X = T_flange_camera`` (camera -> flange) and
    ``Z = T_base_world``.

    ``T_base_flange``: (N, 4, 4) flange poses in the robot base frame (forward kinematics), m. Exactly one of
    ``T_camera_target``, (N, 4, 4) poses of a fixed target in each camera frame (target -> camera; the result's
    ``T_base_world`` is then ``T_base_target``), and ``T_world_camera``, (N, 4, 4) camera poses in a fixed frame (camera
    -> world), e.g. a scan's ICP trajectory. ``settings``: :class:`HandEyeSettings`; keyword ``overrides`` (its field
    names, e.g. ``rotation_weight=0.1``, ``huber_delta=0.002``) are applied on top.

    Returns a :class:`HandEyeResult`: ``status`` ``"ok"``, or ``"too_few_poses"`` (< 3), ``"degenerate_motion"``
    (rotations too small or about parallel axes) or ``"inconsistent_poses"`` (an RMS residual above
    ``max_rms_translation`` / ``max_rms_rotation``: poses paired wrongly, a bad view) with a message. ValueError: both
    or neither camera-pose argument, a shape other than (N, 4, 4), a different N, a pose that is not rigid or lies
    beyond 1e6 m (named with its index), invalid settings. TypeError: a non-numeric array, an unknown setting.
    """
    if (T_camera_target is None) == (T_world_camera is None):
        raise ValueError("give exactly one of T_camera_target (target views) and T_world_camera (a scan trajectory)")
    s = with_overrides(HandEyeSettings, settings, overrides, "hand-eye")
    if T_camera_target is not None:
        return _C.calibrate_hand_eye_from_target(T_base_flange, T_camera_target, s)
    return _C.calibrate_hand_eye(T_base_flange, T_world_camera, s)

"""The two-step pose's refinement loop (Kleppe et al., "Automated assembly using 3D and 2D cameras", Robotics 6 (2017)
14, the thesis's Paper 3, §3.3): from a rough 3D estimate of a part, move the hand camera above it, match the part's
reference image, read the fine planar pose off the homography, and repeat from the new estimate until a step moves it
by less than ``Refine2dSettings.converged_translation`` / ``converged_angle``.

Frames (``T_a_b`` maps b into a; metres, radians): ``base`` (z up, the table's normal), ``part`` (upright), ``camera``
(x right, y down, z forward), ``flange``. The camera is either carried by a robot (the view is planned with its
analytic IK, every branch judged as the pick planner judges a grasp) or fixed (``T_base_camera`` given).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, List, Optional, Sequence

import numpy as np

from scanalign.common.arrays import as_transform
from scanalign.common.settings import with_overrides
from scanalign.grasp import Gripper, ViewPlannerSettings, plan_camera_view
from scanalign.pose.image_matching import Refine2dSettings, Refine2dStep, refine_planar_pose

__all__ = ["Refine2dResult", "ViewStep", "refine_2d"]


@dataclass
class ViewStep:
    """One view of the loop: where the camera was, what it matched and how far the estimate moved."""

    T_base_camera: np.ndarray  #: (4, 4) m
    q: Optional[np.ndarray]  #: (6,) rad, the camera arm's joints (None for a fixed camera)
    step: Refine2dStep
    correction_m: float = float("nan")  #: how far this step moved the estimate (m)
    correction_rad: float = float("nan")  #: how far it turned it (rad)


@dataclass
class Refine2dResult:
    """The refined pose and every view. ``status``: "ok" (converged), "not_converged" (``max_steps`` views, the last
    correction still above the thresholds: ``T_base_part`` is the last estimate), "unreachable" (no view of the
    estimate is reachable), or the failed step's status ("too_few_features", "too_few_matches", "too_few_inliers",
    "non_rigid", "part_outside_image", "not_in_view"); then ``T_base_part`` is the last good estimate (the rough pose
    if no step succeeded) and must not be trusted as refined."""

    status: str
    reason: str
    T_base_part: np.ndarray
    T_base_part_rough: np.ndarray
    views: List[ViewStep] = field(default_factory=list)

    def __bool__(self) -> bool:
        return self.status == "ok"

    @property
    def inliers(self) -> int:
        """RANSAC inliers of the last view's homography."""
        return self.views[-1].step.match.inliers if self.views else 0


def _yaw(T: np.ndarray) -> float:
    return float(np.arctan2(T[1, 0], T[0, 0]))


def refine_2d(T_base_part_rough: Any, reference: Any, geometry: Any, capture: Callable[[np.ndarray], Any], *,
              intrinsics: Any, robot: Any = None, camera_mount: Optional[Gripper] = None,
              table_plane: Sequence[float] = (0.0, 0.0, 1.0, 0.0), q_current: Optional[Sequence[float]] = None,
              T_base_camera: Any = None, settings: Optional[Refine2dSettings] = None,
              view_settings: Optional[ViewPlannerSettings] = None) -> Refine2dResult:
    """Refines ``T_base_part_rough`` (4x4, m) with the hand camera.

    ``reference``, ``geometry``: the part's top-face reference image and its
    :class:`scanalign.pose.image_matching.ReferenceImageGeometry`; ``capture(T_base_camera)``: takes an image with the
    camera at that pose (the robot moves there first; a synthetic cell renders it); ``intrinsics``: the camera's.
    With ``robot`` (a :class:`scanalign.kinematics.Robot` or a name) and ``camera_mount`` (its
    ``T_flange_tcp`` is the hand-eye ``T_flange_camera``; :func:`scanalign.grasp.hand_camera_mount`) each view is
    planned above the current estimate (:func:`scanalign.grasp.plan_camera_view` with ``view_settings``, from
    ``q_current``, then from the last view's joints); without a robot ``T_base_camera`` is the fixed camera's pose.
    ``settings``: :class:`Refine2dSettings` (matching, homography, ``max_steps``, convergence)."""
    s = with_overrides(Refine2dSettings, settings, {}, "Refine2dSettings")
    s.validate()
    rough = as_transform(T_base_part_rough, "T_base_part_rough")
    if robot is None and T_base_camera is None:
        raise ValueError("refine_2d: give a robot with a camera_mount (the view is planned) or a fixed T_base_camera")
    if robot is not None and camera_mount is None:
        raise ValueError("refine_2d: a robot needs its camera_mount (T_flange_tcp = T_flange_camera)")
    fixed = None if T_base_camera is None else as_transform(T_base_camera, "T_base_camera")
    vs = with_overrides(ViewPlannerSettings, view_settings, {}, "ViewPlannerSettings")
    q = None if q_current is None else np.asarray(q_current, np.float64)
    estimate = rough.copy()
    result = Refine2dResult("not_converged", "", estimate, rough)
    for k in range(s.max_steps):
        if robot is not None:
            plan = plan_camera_view(robot, estimate, geometry.top_height, camera_mount=camera_mount,
                                    table_plane=table_plane, q_current=q, settings=vs)
            if not plan.found:
                result.status, result.reason = "unreachable", f"no view above the estimate is reachable: {plan.message}"
                return result
            T_cam, q = np.asarray(plan.T_base_camera), np.asarray(plan.q)
        else:
            T_cam = fixed
        step = refine_planar_pose(capture(T_cam), reference, geometry, intrinsics, T_cam, estimate, s)
        view = ViewStep(T_cam, None if robot is None else q.copy(), step)
        result.views.append(view)
        if not step:
            result.status, result.reason = step.status, f"view {k + 1}: {step.reason}"
            return result
        view.correction_m = float(np.linalg.norm(step.T_base_part[:2, 3] - estimate[:2, 3]))
        view.correction_rad = float(abs(np.remainder(_yaw(step.T_base_part) - _yaw(estimate) + np.pi, 2 * np.pi)
                                        - np.pi))
        estimate = step.T_base_part
        result.T_base_part = estimate
        if view.correction_m < s.converged_translation and view.correction_rad < s.converged_angle:
            result.status = "ok"
            result.reason = f"converged after {k + 1} views ({step.match.inliers} inliers)"
            return result
    last = result.views[-1]
    result.reason = (f"{s.max_steps} views, the last still moved the estimate {last.correction_m * 1e3:.2f} mm / "
                     f"{np.degrees(last.correction_rad):.2f} deg")
    return result

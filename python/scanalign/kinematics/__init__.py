"""Serial 6R robots: forward kinematics and analytic inverse kinematics with conformal
geometric algebra (Kleppe, PhD thesis, NTNU 2018, Ch. 5.3 and Paper 1); docs/api/kinematics.md
has the details (statuses, singularities, corrections to the printed construction).

A :class:`Robot` is a standard Denavit-Hartenberg (DH) table with joint limits and two
fixed transforms. Frames and units (metres and radians everywhere):

- DH frame i is attached to link i; frame 0 is the DH base frame, frame 6 the flange.
  ``T_{i-1,i} = Rot_z(theta_i) Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i)`` (Paper 1 eq. (1)) with
  ``theta_i = q_i + theta_offset_i``, where ``q`` are the joint values the controller shows.
- ``T_base_dh0`` places DH frame 0 in the user's robot base frame and ``T_flange_tool`` places the tool centre point in
  the flange frame, so ``T_base_tool(q) = T_base_dh0 @ T_01 @ ... @ T_56 @ T_flange_tool`` (Paper 1 eq. (3)).
  ``T_base_tool`` maps tool coordinates into the robot base frame.

Inverse kinematics is solved in closed form for two arm layouts (``Robot.geometry``): ``"spherical_wrist"`` (KUKA KR6
R900 sixx "Agilus" and arms of the same layout: shoulder offset a1, elbow offset a3, spherical wrist) and
``"universal_robots"`` (three parallel axes and an offset wrist). The joint points of the arm are intersections of CGA
spheres and planes (point pairs); an imaginary point pair (Q^2 < 0) reports the configuration as ``"unreachable"``
(``q`` NaN) instead of returning wrong angles.

Every pose has up to 8 solutions, stored at a fixed index ``4*(shoulder<0) + 2*(elbow<0) + (wrist<0)``
(:meth:`IKResult.index`). The labels are geometric:

- ``shoulder`` +1 ("front"): the wrist centre (KUKA ``P_w``; UR ``P_c``, the projection of ``P5`` onto the arm plane)
  lies on the side of the first joint axis that the upper arm points to at theta2 = 0, ``f = sign(a2) x1`` (x1: DH x
  axis of link 1; the +x1 side for the KUKA, the -x1 side for UR arms, whose a2 < 0); -1 ("back").
- ``elbow`` +1 ("up"): the elbow point ``P2`` lies above the line from the shoulder point
  ``P1`` to the wrist point (KUKA ``P_w``, UR ``P3``), seen in the arm plane with the arm
  reaching forward (towards the wrist centre); -1 ("down").
- ``wrist`` +1 ("no flip"): ``sin(theta5) > 0`` (DH angle); -1 ("flip").

Singular poses are solved with a free angle (``q_free``): KUKA shoulder (wrist centre on the first axis)
``q1 = q_free[0]``, KUKA wrist ``q4 = q_free[3]``, UR wrist ``q6 = q_free[5]`` (or the nearest q6 for which the elbow
still reaches), ``+ pi`` for "back" / "flip"; :attr:`IKResult.singular` names which applied, per solution.

The classes are the C++ structs, bound directly (``scanalign._core.kinematics``): every argument is checked once, at the
C++ boundary, and a bad one raises TypeError / ValueError naming it. Results are values with read-only arrays.
"""

from __future__ import annotations

from typing import Callable, Tuple

import numpy as np

from scanalign import _core

__all__ = [
    "Robot", "IKResult", "IKSolution", "IKBatchResult", "JointTrajectoryResult", "IKConstruction", "STATUS_NAMES",
    "SINGULAR_NAMES", "STEP_NAMES", "CONFIGS", "BUILTIN_ROBOTS", "config_index",
    "kuka_kr6_r900_sixx", "ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e", "ur5_thesis", "robot_from_urdf"]

_K = _core.kinematics
Robot, IKResult, IKSolution, IKBatchResult = _K.Robot, _K.IKResult, _K.IKSolution, _K.IKBatchResult
JointTrajectoryResult, IKConstruction, config_index = _K.JointTrajectoryResult, _K.IKConstruction, _K.config_index

from scanalign.kinematics.urdf import robot_from_urdf  # noqa: E402  (imports yourdfpy only when called)

# Robot is the bound C++ class; the URDF reader is Python (it needs a URDF parser; the geometry is
# Robot.from_joint_chain), attached here so that it reads like the other constructors:
# Robot.from_urdf(path, base_link, tip_link).
Robot.from_urdf = staticmethod(robot_from_urdf)

#: Status names by code (C++ ``IKStatus``): 0 ok, 1 outside_limits, 2 unreachable, 3 invalid_input.
STATUS_NAMES: Tuple[str, ...] = _K.STATUS_NAMES
#: Singularity names by bit (C++ ``SingularBits``): 1 shoulder, 2 elbow, 4 wrist.
SINGULAR_NAMES: Tuple[str, ...] = _K.SINGULAR_NAMES
#: Names of the failed step by code (C++ ``IKStep``): 0 none, 1 shoulder, 2 elbow, 3 fk_check.
STEP_NAMES: Tuple[str, ...] = _K.STEP_NAMES
#: (8, 3) int8, read-only: the configuration (shoulder, elbow, wrist) stored at each solution index.
CONFIGS: np.ndarray = _K.CONFIGS
#: Names accepted by :meth:`Robot.by_name` ("agilus" is an alias of "kr6_r900_sixx").
BUILTIN_ROBOTS: Tuple[str, ...] = ("kr6_r900_sixx", "agilus", "ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e",
                                   "ur5_thesis")


def _builtin(function: str, name: str, doc: str) -> Callable[[], Robot]:
    """A function named ``function`` returning the built-in robot ``name`` (:meth:`Robot.by_name`)."""
    def builtin() -> Robot:
        return Robot.by_name(name)
    builtin.__name__ = builtin.__qualname__ = function
    builtin.__doc__ = doc
    return builtin


kuka_kr6_r900_sixx = _builtin("kuka_kr6_r900_sixx", "kr6_r900_sixx", """KUKA KR6 R900 sixx ("Agilus"): the DH table
    of the thesis authors' code (thesis Paper 1 Table 1 is garbled in print), q = KUKA's axis values A1..A6; home
    q = (0, -pi/2, pi/2, 0, 0, 0) puts the flange at (0.525, 0, 0.890) m pointing along +x. Limits from KUKA's data
    sheet.""")
ur3, ur5, ur10, ur3e, ur5e, ur10e = (
    _builtin(n, n, f"Universal Robots {n[:2].upper() + n[2:]}{'' if n.endswith('e') else ' (CB series)'}, UR's "
             "published DH table, limits +-2*pi.") for n in ("ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e"))
ur5_thesis = _builtin("ur5_thesis", "ur5_thesis", """The UR5 with the numbers printed in the thesis (Paper 1
    Table 2), for reproducing its zero pose: q = 0 puts the flange at (-0.81743, -0.19145, -0.00545) m.""")

"""Robots from URDF files: ``Robot.from_urdf(path, base_link, tip_link)``.

A URDF describes an arm as a tree of links joined by joints, each joint placed by an arbitrary ``<origin>`` and turning
about an arbitrary ``<axis>``. This module reads the file (with the ``yourdfpy`` parser), walks the chain
``base_link -> tip_link`` and folds the fixed joints into their neighbours; :meth:`Robot.from_joint_chain` (C++,
``scanalign/kinematics/joint_chain.hpp``) then derives the standard DH table the analytic inverse kinematics needs,
``T_base_dh0`` and ``T_flange_tool`` from the joint axes, so that ``robot.fk(q)`` is the pose of ``tip_link`` in
``base_link`` for the URDF's joint values q, limits included.

The DH z axes follow the URDF joint axes, so q maps 1:1 onto the URDF joints unless ``joint_signs`` reverses some. Each
DH x axis has a free sign (it flips alpha_i and a_i and moves theta offsets by pi); of the 32 choices the one that makes
the table one of the analytic layouts is taken, with the smallest theta offsets.

Needs the ``yourdfpy`` parser (``pip install 'scanalign[urdf]'``), imported on first use.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from typing import Optional, Sequence

import numpy as np

from scanalign import _core

__all__ = ["robot_from_urdf", "LAYOUTS"]

#: The DH layouts the analytic IK solves (``Robot.geometry``).
LAYOUTS = ("spherical_wrist", "universal_robots")


def _load_chain(path: str, base_link: str, tip_link: str):
    """Parse the URDF and return (robot name, joints of the chain base -> tip)."""
    try:
        import yourdfpy
    except ImportError as e:  # optional dependency: say how to get it
        raise ImportError("Robot.from_urdf needs the URDF parser 'yourdfpy': pip install 'scanalign[urdf]' "
                          "(or pip install yourdfpy)") from e
    if not os.path.isfile(path):
        raise FileNotFoundError(f"{path}: no such URDF file")
    # yourdfpy recovers silently from broken XML; a strict parse first gives a clear error.
    try:
        ET.parse(path)
    except ET.ParseError as e:
        raise ValueError(f"{path}: not a well-formed URDF (XML error: {e})") from None
    try:  # kinematics only: no scene graph, no meshes (their files need not exist)
        model = yourdfpy.URDF.load(path, build_scene_graph=False, load_meshes=False,
                                   build_collision_scene_graph=False, load_collision_meshes=False)
    except Exception as e:  # noqa: BLE001 - any parser failure is a bad file
        raise ValueError(f"{path}: not a valid URDF ({type(e).__name__}: {e})") from None
    links = {link.name for link in model.robot.links}
    for role, name in (("base_link", base_link), ("tip_link", tip_link)):
        if name not in links:
            raise ValueError(f"{path}: {role} '{name}' is not a link of robot '{model.robot.name}' "
                             f"(links: {', '.join(sorted(links))})")
    parent_joint = {}
    for j in model.robot.joints:
        if j.child in parent_joint:
            raise ValueError(f"{path}: link '{j.child}' is the child of two joints "
                             f"('{parent_joint[j.child].name}', '{j.name}')")
        parent_joint[j.child] = j
    chain, link = [], tip_link
    while link != base_link:  # up from the tip: a tree has one path
        if link not in parent_joint or len(chain) > len(parent_joint):
            raise ValueError(f"{path}: tip_link '{tip_link}' is not below base_link '{base_link}' in the link tree")
        chain.append(parent_joint[link])
        link = chain[-1].parent
    return model.robot.name, chain[::-1]


def _segments(path: str, chain, where: str):
    """Split the chain into 6 revolute joints: per joint the fixed transform from the previous
    joint's child frame (or base_link) to its joint frame, its unit axis, limits and name,
    and the fixed transform from the last joint's child frame to the tip."""
    offsets, axes, limits, names = [], [], [], []
    pending = np.eye(4)
    for j in chain:
        origin = np.eye(4) if j.origin is None else np.asarray(j.origin, float)
        if not np.all(np.isfinite(origin)):
            raise ValueError(f"{path}: joint '{j.name}' has a non-finite <origin>")
        if j.type == "fixed":
            pending = pending @ origin
            continue
        if j.type not in ("revolute", "continuous"):
            raise ValueError(f"{path}: joint '{j.name}' of the chain {where} is {j.type}; a Robot has revolute "
                             "joints only")
        if j.mimic is not None:
            raise ValueError(f"{path}: joint '{j.name}' of the chain {where} mimics '{j.mimic.joint}'; a Robot "
                             "has 6 independent joints")
        axis = np.asarray(j.axis if j.axis is not None else (1.0, 0.0, 0.0), float)
        if not (axis.shape == (3,) and np.all(np.isfinite(axis)) and np.linalg.norm(axis) > 1e-12):
            raise ValueError(f"{path}: joint '{j.name}' has no valid axis ({j.axis})")
        if j.type == "revolute" and j.limit is None:  # urdfdom refuses this too
            raise ValueError(f"{path}: revolute joint '{j.name}' has no <limit>")
        # Continuous joints are unlimited (the IK then wraps to the 2*pi multiple nearest 0); the URDF
        # specification's defaults for a missing lower / upper are 0.
        lim = (-np.inf, np.inf) if j.type == "continuous" else (j.limit.lower or 0.0, j.limit.upper or 0.0)
        if not lim[0] <= lim[1]:
            raise ValueError(f"{path}: joint '{j.name}' has the limits lower {lim[0]} > upper {lim[1]}")
        offsets.append(pending @ origin)
        axes.append(axis / np.linalg.norm(axis))
        limits.append(lim)
        names.append(j.name)
        pending = np.eye(4)
    if len(names) != 6:
        raise ValueError(f"{path}: the chain {where} has {len(names)} revolute/continuous joints "
                         f"({', '.join(names) or 'none'}); a Robot is a 6-joint arm")
    return offsets, axes, np.array(limits, float), names, pending


def robot_from_urdf(path, base_link: str, tip_link: str, *, name: Optional[str] = None,
                    joint_signs: Optional[Sequence[float]] = None, fk_only: bool = False,
                    tolerance: float = 1e-9):
    """A :class:`~scanalign.kinematics.Robot` from the chain ``base_link -> tip_link`` of a URDF.

    ``robot.fk(q)`` is ``T_base_tip``, the pose of ``tip_link`` in ``base_link`` (metres), for the URDF joint values q
    (rad, the 6 revolute / continuous joints of the chain in order; fixed joints are folded in). The DH table,
    ``T_base_dh0`` and ``T_flange_tool`` are derived from the joint axes (:meth:`Robot.from_joint_chain`); limits are
    the URDF's ``<limit>`` (continuous joints: +-inf).

    Args:
        path: the ``.urdf`` file (meshes are not loaded and need not exist).
        base_link, tip_link: link names; tip_link must lie below base_link.
        name: the Robot's label (default: the URDF's robot name).
        joint_signs: (6,) of +1 / -1 (default all +1): the Robot's joint i turns ``q_i = joint_signs[i] * q_urdf_i``.
            For URDFs whose axes point against the analytic layouts (e.g. a KUKA description with A1, A4, A6 about -z /
            -x); the error for such a chain names the signs that make it analytic.
        fk_only: return the Robot even when the chain is none of the analytic layouts
            (``robot.geometry == 'unsupported'``; fk works, ik raises ValueError).
        tolerance: axes within this angle (rad) count as parallel, and DH values within it of
            0 or a multiple of pi/2 (m, rad) are set to them (URDFs write pi/2 with 10-12
            digits); FK then departs from the URDF by at most about tolerance x reach.

    Raises:
        ImportError: yourdfpy is not installed.
        FileNotFoundError: no such file.
        ValueError (naming the file): malformed URDF, unknown link, tip not below base, a
            prismatic / floating / planar / mimic joint in the chain, not exactly 6 revolute
            joints, or (unless fk_only) a chain the analytic IK cannot solve.
        RuntimeError: the DH model departs from the URDF chain (a bug, not a bad file).
    """
    path = os.fspath(path)
    robot_name, chain = _load_chain(path, base_link, tip_link)
    where = f"{base_link} -> {tip_link}"
    origins, axes, limits, joints, tail = _segments(path, chain, where)
    return _core.kinematics.Robot.from_joint_chain(
        np.array(origins), np.array(axes), limits, tail, name=robot_name if name is None else str(name),
        joint_signs=joint_signs, fk_only=fk_only, tolerance=tolerance,
        what=f"{path}: the chain {where} (joints {', '.join(joints)})")

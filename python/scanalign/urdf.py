"""Robots from URDF files: ``Robot.from_urdf(path, base_link, tip_link)``.

A URDF describes an arm as a tree of links joined by joints, each joint placed by an
arbitrary ``<origin>`` and turning about an arbitrary ``<axis>``. The analytic inverse
kinematics of :mod:`scanalign.kinematics` needs the arm as a standard DH table
(``T_{i-1,i} = Rot_z(theta_i) Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i)``) in one of two
layouts. This module walks the chain ``base_link -> tip_link``, folds the fixed joints into
their neighbours, places the six joint axes in ``base_link`` at q = 0 and derives the DH
frames from these lines (the common normals of consecutive axes), plus ``T_base_dh0``
(DH frame 0 in ``base_link``) and ``T_flange_tool`` (``tip_link`` in the flange frame), so
that ``robot.fk(q)`` is the pose of ``tip_link`` in ``base_link`` for the URDF's joint
values q, limits included.

The DH z axes follow the URDF joint axes, so q maps 1:1 onto the URDF joints (``Robot`` has
no joint direction signs). Each DH x axis has a free sign (it flips alpha_i and a_i and
moves theta offsets by pi); of the 32 choices the one that makes the table one of the
analytic layouts is taken, with the smallest theta offsets.

Needs the ``yourdfpy`` parser (``pip install 'scanalign[urdf]'``), imported on first use.
"""

from __future__ import annotations

import itertools
import os
import xml.etree.ElementTree as ET
from typing import Optional, Sequence

import numpy as np

from . import _core

__all__ = ["robot_from_urdf", "LAYOUTS"]

#: The DH layouts the analytic IK solves (``Robot.geometry``).
LAYOUTS = ("spherical_wrist", "universal_robots")

_LAYOUT_TEXT = ("'spherical_wrist' (KUKA type: alpha = (-pi/2, 0, -pi/2, pi/2, -pi/2, 0), d2 = d3 = d5 = 0, "
                "a4 = a5 = a6 = 0, a2 > 0, d4 > 0) and 'universal_robots' (alpha = (pi/2, 0, 0, pi/2, -pi/2, 0), "
                "a1 = a4 = a5 = a6 = 0, d2 = d3 = 0, a2, a3 != 0, d4, d5 > 0)")


def _rotation(axis: np.ndarray, q: float) -> np.ndarray:
    """4x4 rotation by q about the unit vector axis (Rodrigues)."""
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    T = np.eye(4)
    T[:3, :3] = np.eye(3) + np.sin(q) * K + (1 - np.cos(q)) * (K @ K)
    return T


def _frame(x: np.ndarray, z: np.ndarray, o: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, np.cross(z, x), z, o
    return T


def _foot(point: np.ndarray, p: np.ndarray, u: np.ndarray) -> np.ndarray:
    """The point of the line (p, u) nearest to point."""
    return p + u * np.dot(point - p, u)


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
        if j.type == "continuous":  # unlimited: the IK then wraps to the 2*pi multiple nearest 0
            lim = (-np.inf, np.inf)
        else:
            if j.limit is None:  # urdfdom refuses this too
                raise ValueError(f"{path}: revolute joint '{j.name}' has no <limit>")
            # The URDF specification's defaults for a missing lower / upper are 0.
            lim = (j.limit.lower or 0.0, j.limit.upper or 0.0)
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


def _urdf_fk(offsets, axes, tail, q: np.ndarray) -> np.ndarray:
    """T_base_tip(q) by the URDF's own chain (the reference the DH robot is checked against)."""
    T = np.eye(4)
    for off, ax, qi in zip(offsets, axes, q):
        T = T @ off @ _rotation(ax, qi)
    return T @ tail


def _dh_table(p, u, o_tip, flips, tol):
    """DH frames through the joint lines (p_i, u_i) in base_link at q = 0 (z_{i-1} = u_i) with
    x-axis signs flips (5 values, frames 1..5); returns the (6, 4) table [a, alpha, d,
    theta_offset] and T_base_dh0.

    Frame i (1..5) sits where the common normal of axes i and i+1 meets axis i+1, x_i along that
    normal. For parallel axes the normal is not unique: the one through the previous origin is
    taken (d_i = 0, as both layouts need) and its sign follows x_{i-1} (small theta offsets).
    Frame 0 is on axis 1 at the foot of base_link's origin with x0 = x1 (theta_offset_1 = 0);
    the flange, frame 6, is on axis 6 at the foot of the tip's origin with x6 = x5."""
    z = list(u) + [u[5]]
    o, x = [_foot(np.zeros(3), p[0], u[0])] + [None] * 6, [None] * 7
    for i in range(1, 6):
        pa, ua, pb, ub = p[i - 1], u[i - 1], p[i], u[i]
        c = np.cross(ua, ub)
        if np.linalg.norm(c) > tol:  # skew or intersecting: the unique common normal
            w, b = pa - pb, np.dot(ua, ub)
            den = 1.0 - b * b
            t = (np.dot(ub, w) - b * np.dot(ua, w)) / den  # parameter of the nearest point on axis i+1
            n, B = c / np.linalg.norm(c), pb + t * ub
        else:
            B = _foot(o[i - 1], pb, ub)
            n = B - o[i - 1]
            n = n - ub * np.dot(n, ub)
            if np.linalg.norm(n) > tol:
                n = n / np.linalg.norm(n)
                if i > 1 and np.dot(n, x[i - 1]) < 0:
                    n = -n
            elif i > 1:  # collinear axes: any normal, keep the previous x
                n = x[i - 1]
            else:
                n = np.cross(ua, [1.0, 0, 0] if abs(ua[0]) < 0.9 else [0, 1.0, 0])
                n /= np.linalg.norm(n)
        x[i], o[i] = flips[i - 1] * n, B
    x[0], x[6], o[6] = x[1], x[5], _foot(o_tip, p[5], u[5])
    dh = np.zeros((6, 4))
    for i in range(1, 7):
        step = o[i] - o[i - 1]
        dh[i - 1] = (np.dot(step, x[i]), np.arctan2(np.dot(np.cross(z[i - 1], z[i]), x[i]), np.dot(z[i - 1], z[i])),
                     np.dot(step, z[i - 1]),
                     np.arctan2(np.dot(np.cross(x[i - 1], x[i]), z[i - 1]), np.dot(x[i - 1], x[i])))
    return dh, _frame(x[0], z[0], o[0])


def _snapped(dh: np.ndarray, tol: float) -> np.ndarray:
    """dh with the values within tol of what the layouts test exactly (alpha a multiple of pi/2,
    a and d zero) set to them: URDFs write pi/2 with 10-12 digits (1.57079632679 is 4.9e-12
    short), which the layout test (1e-12) refuses; FK moves by about tol x reach at most."""
    dh = dh.copy()
    quarter = np.round(dh[:, 1] / (np.pi / 2)) * (np.pi / 2)
    dh[:, 1] = np.where(np.abs(dh[:, 1] - quarter) <= tol, quarter, dh[:, 1])
    for c in (0, 2):
        dh[:, c] = np.where(np.abs(dh[:, c]) <= tol, 0.0, dh[:, c])
    return dh


def _best_robot(p, u, o_tip, limits, name, tol):
    """The Robot (no tool yet) over the 32 x-sign choices: an analytic layout with the smallest
    theta offsets if one exists, else the default signs (FK only)."""
    best, fallback = None, None
    for flips in itertools.product((1.0, -1.0), repeat=5):
        raw, T0 = _dh_table(p, u, o_tip, flips, tol)
        for dh in (raw, _snapped(raw, tol)):  # the exact table first; rounded only if that makes it analytic
            r = _core.kinematics.Robot.from_dh(dh[:, 0], dh[:, 1], dh[:, 2], dh[:, 3], limits, name, T0)
            fallback = r if fallback is None else fallback
            if r.geometry in LAYOUTS:
                cost = float(np.abs(dh[:, 3]).sum())
                if best is None or cost < best[0] - 1e-12:
                    best = (cost, r)
                break
    return best[1] if best is not None else fallback


def robot_from_urdf(path, base_link: str, tip_link: str, *, name: Optional[str] = None,
                    joint_signs: Optional[Sequence[float]] = None, fk_only: bool = False,
                    tolerance: float = 1e-9):
    """A :class:`~scanalign.kinematics.Robot` from the chain ``base_link -> tip_link`` of a URDF.

    ``robot.fk(q)`` is ``T_base_tip``, the pose of ``tip_link`` in ``base_link`` (metres), for
    the URDF joint values q (rad, the 6 revolute / continuous joints of the chain in order;
    fixed joints are folded in). The DH table, ``T_base_dh0`` and ``T_flange_tool`` are derived
    from the joint axes; limits are the URDF's ``<limit>`` (continuous joints: +-inf).

    Args:
        path: the ``.urdf`` file (meshes are not loaded and need not exist).
        base_link, tip_link: link names; tip_link must lie below base_link.
        name: the Robot's label (default: the URDF's robot name).
        joint_signs: (6,) of +1 / -1 (default all +1): the Robot's joint i turns
            ``q_i = joint_signs[i] * q_urdf_i``. For URDFs whose axes point against the
            analytic layouts (e.g. a KUKA description with A1, A4, A6 about -z / -x); the
            error for such a chain names the signs that make it analytic.
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
    """
    path = os.fspath(path)
    signs = np.ones(6) if joint_signs is None else np.asarray(joint_signs, float).reshape(-1)
    if signs.shape != (6,) or not np.all(np.abs(signs) == 1):
        raise ValueError(f"joint_signs: expected 6 values of +1 or -1, got {joint_signs}")
    if not (np.isfinite(tolerance) and 0 <= tolerance < 1e-3):
        raise ValueError(f"tolerance: expected 0 <= tolerance < 1e-3, got {tolerance}")
    tol = max(float(tolerance), 1e-12)  # below ~1e-12 rounding alone would break parallel axes
    robot_name, chain = _load_chain(path, base_link, tip_link)
    where = f"{base_link} -> {tip_link}"
    offsets, axes, limits, joints, tail = _segments(path, chain, where)
    name = robot_name if name is None else str(name)

    def build(sg):
        """The Robot without tool for joint signs sg: z_{i-1} = sg_i x the URDF axis, limits mirrored."""
        F = np.eye(4)
        p, u = [], []
        for off, ax, s in zip(offsets, axes, sg):  # joint frames at q = 0 in base_link
            F = F @ off
            p.append(F[:3, 3].copy())
            u.append(s * (F[:3, :3] @ ax))
        lim = np.where(np.asarray(sg)[:, None] > 0, limits, -limits[:, ::-1])
        try:
            return _best_robot(p, u, (F @ tail)[:3, 3], lim, name, tol)
        except ValueError as e:  # from_dh: e.g. nearly parallel axes giving huge offsets
            raise ValueError(f"{path}: the chain {where} gives no usable DH table ({e}): nearly parallel joint "
                             f"axes put their common normal far away; a tolerance above their angle (now "
                             f"{tolerance}) treats them as parallel") from None

    robot = build(signs)
    if robot.geometry not in LAYOUTS and not fk_only:
        hint = ""
        if joint_signs is None:  # would reversing some joints make it analytic?
            for s in sorted(itertools.product((1.0, -1.0), repeat=6), key=lambda s: s.count(-1.0))[1:]:
                geometry = build(np.array(s)).geometry  # fewest reversed joints first
                if geometry in LAYOUTS:
                    hint = (f"; with joint_signs={tuple(int(v) for v in s)} (q = joint_signs * q_urdf) it is a "
                            f"'{geometry}' arm")
                    break
        raise ValueError(
            f"{path}: the chain {where} (joints {', '.join(joints)}) is none of the layouts the analytic IK "
            f"solves, {_LAYOUT_TEXT}; its DH table [a (m), alpha, d (m), theta_offset] is "
            f"[{'; '.join(', '.join(f'{v:.6g}' for v in row) for row in np.round(robot.dh, 6) + 0.0)}]{hint}. Pass "
            "fk_only=True for a Robot with forward kinematics only")
    # tip_link in the flange frame, from the Robot's own flange pose: exact at q = 0 even after
    # the rounding of near-layout values above.
    T_tip0 = _urdf_fk(offsets, axes, tail, np.zeros(6))
    F6 = robot.fk_flange(np.zeros(6))
    T_flange_tip = np.eye(4)
    T_flange_tip[:3] = F6[:3, :3].T @ np.c_[T_tip0[:3, :3], T_tip0[:3, 3] - F6[:3, 3]]
    robot = robot.with_tool(T_flange_tip)
    # Check against the URDF chain itself (a wrong frame would show here, not later in a cell).
    rng = np.random.default_rng(0)
    lim = np.clip(robot.limits, -np.pi, np.pi)
    for q in np.vstack([np.zeros(6), rng.uniform(lim[:, 0], lim[:, 1], (8, 6))]):
        err = np.abs(robot.fk(q) - _urdf_fk(offsets, axes, tail, signs * q)).max()
        if err > 1e-9 + 100 * tol:
            raise RuntimeError(f"{path}: the DH model of {where} departs from the URDF by {err:.3g} at q = {q}")
    return robot

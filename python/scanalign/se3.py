"""Rigid transforms (SE(3)) in one place for the Python layer.

Building rotations and 4x4 transforms, inverting them, their rotation angles and pose
errors, and the rigidity check that every function taking a transform applies. The check
is the C++ core's (``scanalign/common/rigid.hpp``, ``requireRigid``) with the same
tolerances, so a transform accepted here is accepted there. Transforms are 4x4 float64
arrays ``T_to_from`` mapping ``from``-frame coordinates (metres) into the ``to`` frame.
"""

from __future__ import annotations

import math
from typing import Optional, Sequence, Tuple

import numpy as np

from ._arrays import as_transform

__all__ = ["ROTATION_TOLERANCE", "ROW_TOLERANCE", "rotation_about", "rigid", "inverse", "rotation_angle",
           "pose_error", "rigid_problem", "require_rigid"]

#: Largest |R^T R - I| entry accepted as a rotation (C++ ``kRigidTolerance``).
ROTATION_TOLERANCE = 1e-5
#: Largest |entry - target| accepted in the last row (0, 0, 0, 1) (C++ ``kRigidRowTolerance``).
ROW_TOLERANCE = 1e-9


def rotation_about(axis: Sequence[float], angle: float) -> np.ndarray:
    """3x3 rotation of ``angle`` radians about ``axis`` (any length > 0), Rodrigues' formula."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * K @ K


def rigid(axis: Sequence[float], angle: float, t: Sequence[float]) -> np.ndarray:
    """4x4 rigid transform: rotation of ``angle`` radians about ``axis``, then translation
    ``t`` (metres)."""
    T = np.eye(4)
    T[:3, :3] = rotation_about(axis, angle)
    T[:3, 3] = t
    return T


def inverse(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms (..., 4, 4): ``[R^T, -R^T t]``, exact (no matrix inversion)."""
    R = T[..., :3, :3]
    Rt = np.swapaxes(R, -1, -2)
    out = np.zeros_like(T)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def rotation_angle(R: np.ndarray) -> np.ndarray:
    """Rotation angles in [0, pi] (radians) of rotation matrices (..., 3, 3).

    ``atan2(|axis| 2 sin(theta), 2 cos(theta))`` from the skew and trace parts: accurate to
    rounding over the whole range, unlike ``arccos((trace - 1) / 2)`` near 0 and pi.
    """
    v = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    tr = R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2]
    return np.arctan2(np.linalg.norm(v, axis=-1), tr - 1.0)


def pose_error(T_est: np.ndarray, T_ref: np.ndarray) -> Tuple[float, float]:
    """(rotation error in radians, translation error in metres) of ``T_est`` relative to
    ``T_ref``: the angle and length of ``T_ref^-1 T_est``."""
    E = inverse(np.asarray(T_ref, dtype=np.float64)) @ np.asarray(T_est, dtype=np.float64)
    return float(rotation_angle(E[:3, :3])), float(np.linalg.norm(E[:3, 3]))


def rigid_problem(m: np.ndarray) -> Optional[str]:
    """Why the 4x4 matrix ``m`` is not a rigid transform, or None when it is: finite, last
    row (0, 0, 0, 1), rotation part orthonormal (ROTATION_TOLERANCE) with determinant +1.
    Plain float arithmetic on the 16 entries: NumPy calls on a 3x3 cost more than an
    inverse kinematics solve, which checks every pose it is given."""
    r0, r1, r2, r3 = np.asarray(m, dtype=np.float64).tolist()
    if not all(math.isfinite(v) for v in (*r0, *r1, *r2, *r3)):
        return "non-finite entries"
    if max(abs(r3[0]), abs(r3[1]), abs(r3[2]), abs(r3[3] - 1.0)) > ROW_TOLERANCE:
        return f"last row (the bottom row) must be [0, 0, 0, 1], got {r3}"
    cols = ((r0[0], r1[0], r2[0]), (r0[1], r1[1], r2[1]), (r0[2], r1[2], r2[2]))
    err = 0.0
    for i in range(3):
        ci = cols[i]
        for j in range(i, 3):
            cj = cols[j]
            g = ci[0] * cj[0] + ci[1] * cj[1] + ci[2] * cj[2] - (1.0 if i == j else 0.0)
            err = max(err, abs(g))
    if err > ROTATION_TOLERANCE:
        return f"rotation part is not orthonormal (|R^T R - I| = {err:.3g} > {ROTATION_TOLERANCE:g})"
    a, b, c = cols
    det = (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
           + a[2] * (b[0] * c[1] - b[1] * c[0]))
    if det <= 0:
        return "rotation part is a reflection (det < 0)"
    return None


def require_rigid(T: object, name: str) -> np.ndarray:
    """``T`` as a 4x4 float64 rigid transform; ValueError naming ``name`` and the failed
    property otherwise (shape, finiteness, last row, orthonormality, reflection)."""
    m = as_transform(T, name)
    why = rigid_problem(m)
    if why is not None:
        raise ValueError(f"{name}: {why}")
    return m

"""Rigid transforms (SE(3)) in one place for the Python layer.

Building rotations and 4x4 transforms, inverting them, their rotation angles and pose errors, and the rigidity check
that every function taking a transform applies. The check is the C++ core's (``scanalign/common/rigid.hpp``,
``rigidProblem``), called directly, so a transform accepted here is accepted there. Transforms are 4x4 float64 arrays
``T_to_from`` mapping ``from``-frame coordinates (metres) into the ``to`` frame.
"""

from __future__ import annotations

import math
import numbers
from typing import Optional, Sequence, Tuple

import numpy as np

from scanalign import _core
from scanalign.common.arrays import as_transform

__all__ = ["ROTATION_TOLERANCE", "ROW_TOLERANCE", "rotation_about", "rigid", "inverse", "rotation_angle",
           "pose_error", "rigid_problem", "require_rigid", "transform_points"]

#: Largest |R^T R - I| entry accepted as a rotation (C++ ``kRigidTolerance``: 1e-5).
ROTATION_TOLERANCE: float = _core.common.RIGID_TOLERANCE
#: Largest |entry - target| accepted in the last row (0, 0, 0, 1) (C++ ``kRigidRowTolerance``: 1e-9).
ROW_TOLERANCE: float = _core.common.RIGID_ROW_TOLERANCE


def _real(x: object, name: str, *tail: int) -> np.ndarray:
    """``x`` as a float64 array of shape ``(..., *tail)``; TypeError (not real: strings, None,
    complex) or ValueError (another shape) naming ``name``."""
    if (a := np.asarray(x)).dtype.kind not in "biuf":
        raise TypeError(f"{name}: expected real numbers, got dtype {a.dtype}")
    if a.ndim < len(tail) or a.shape[a.ndim - len(tail):] != tail:
        raise ValueError(f"{name}: expected shape (..., {', '.join(map(str, tail))}), got {a.shape}")
    return a.astype(np.float64)


def rotation_about(axis: Sequence[float], angle: float) -> np.ndarray:
    """3x3 rotation of ``angle`` radians about ``axis`` (any finite length > 0), Rodrigues' formula."""
    if (a := _real(axis, "axis", 3)).ndim != 1 or not np.linalg.norm(a) > 0 or not np.all(np.isfinite(a)):
        raise ValueError(f"axis: expected 3 finite coordinates, not all zero, got {a}")
    if not isinstance(angle, numbers.Real) or not math.isfinite(angle):
        raise (ValueError if isinstance(angle, numbers.Real) else TypeError)(f"angle: expected radians, got {angle!r}")
    a = a / np.linalg.norm(a)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * K @ K


def rigid(axis: Sequence[float], angle: float, t: Sequence[float]) -> np.ndarray:
    """4x4 rigid transform: rotation of ``angle`` radians about ``axis``, then translation ``t`` (metres)."""
    T = np.eye(4)
    T[:3, :3] = rotation_about(axis, angle)
    T[:3, 3] = _real(t, "t", 3)
    return T


def inverse(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms (..., 4, 4): ``[R^T, -R^T t]``, exact (no matrix inversion)."""
    R = (T := _real(T, "T", 4, 4))[..., :3, :3]
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
    R = _real(R, "R", 3, 3)
    v = np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], axis=-1)
    tr = R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2]
    return np.arctan2(np.linalg.norm(v, axis=-1), tr - 1.0)


def pose_error(T_est: np.ndarray, T_ref: np.ndarray) -> Tuple[float, float]:
    """(rotation error in radians, translation error in metres) of ``T_est`` relative to
    ``T_ref``: the angle and length of ``T_ref^-1 T_est``."""
    E = inverse(as_transform(T_ref, "T_ref")) @ as_transform(T_est, "T_est")
    return float(rotation_angle(E[:3, :3])), float(np.linalg.norm(E[:3, 3]))


def rigid_problem(m: np.ndarray) -> Optional[str]:
    """Why the 4x4 matrix ``m`` is not a rigid transform, or None when it is: finite, last row
    (0, 0, 0, 1) to ROW_TOLERANCE, rotation part orthonormal to ROTATION_TOLERANCE, determinant +1."""
    if (a := _real(m, "m", 4, 4)).ndim != 2:
        raise ValueError(f"m: expected a 4x4 matrix, got shape {a.shape}")
    return _core.common.rigid_problem(a)


def require_rigid(T: object, name: str) -> np.ndarray:
    """``T`` as a 4x4 float64 rigid transform; ValueError naming ``name`` and the failed
    property otherwise (shape, finiteness, last row, orthonormality, reflection)."""
    m = as_transform(T, name)
    if (why := rigid_problem(m)) is not None:
        raise ValueError(f"{name}: {why}")
    return m


def transform_points(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``T`` (4x4, finite, last row 0 0 0 1) applied to (N, 3) float32/float64 points: a new
    array of their dtype, computed in double in C++ (``transformPoints``)."""
    return _core.common.transform_points(np.asarray(T, dtype=np.float64), points)

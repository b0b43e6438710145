"""Small geometry helpers for the tests (independent of scanalign)."""

from __future__ import annotations

import numpy as np


def rigid(axis, angle: float, t) -> np.ndarray:
    """4x4 rigid transform: rotation of `angle` rad about `axis`, then translation `t` (m)."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    T = np.eye(4)
    T[:3, :3] = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    T[:3, 3] = t
    return T


def apply(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    return p @ T[:3, :3].T + T[:3, 3]


def pose_error(T_est: np.ndarray, T_true: np.ndarray) -> tuple:
    """(rotation error rad, translation error m) of T_est relative to T_true."""
    E = np.linalg.inv(T_true) @ T_est
    angle = np.arccos(np.clip((np.trace(E[:3, :3]) - 1) / 2, -1, 1))
    return float(angle), float(np.linalg.norm(E[:3, 3]))

"""Trajectory and reconstruction accuracy: ATE, RPE (Sturm et al., "A Benchmark for the Evaluation of RGB-D SLAM
Systems", IROS 2012), cloud-to-mesh distance.  Inputs in metres and radians; a pose ``T_world_camera`` maps camera
coordinates into the trajectory's world frame.  Error statistics report translations in metres and rotations in
**degrees** (as the TUM tools and ``evo``, whose APE ``translation_part`` and RPE these equal).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, Optional, Tuple, Union

import numpy as np

from scanalign import _core
from scanalign._core.evaluation import ErrorStats
from scanalign.common import rigid as se3
from scanalign.common.arrays import mesh_arrays
from scanalign.evaluation.mesh_distance import (MeshDistanceIndex, MeshDistanceStats, mesh_distance_stats,
                                                point_to_mesh_distance)
from scanalign.evaluation.trajectory import Trajectory, associate_timestamps

__all__ = ["umeyama_alignment", "associate", "ErrorStats", "AteResult", "RpeResult",
           "absolute_trajectory_error", "relative_pose_error", "MeshDistanceIndex", "MeshDistanceStats",
           "point_to_mesh_distance", "mesh_distance_stats", "evaluate_reconstruction"]

TrajectoryLike = Union[Trajectory, np.ndarray]


def _as_trajectory(x: TrajectoryLike, name: str) -> Trajectory:
    if isinstance(x, Trajectory):
        return x
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 3 or a.shape[1:] != (4, 4):
        raise TypeError(f"{name}: expected a Trajectory or an (N, 4, 4) array of poses, got "
                        f"{type(x).__name__} of shape {a.shape}")
    return Trajectory(np.arange(a.shape[0], dtype=np.float64), a)


def _paired(estimate: TrajectoryLike, reference: TrajectoryLike, associate: bool, max_difference: float,
            offset: float, minimum: int, what: str) -> Tuple[Trajectory, Trajectory]:
    """The two trajectories, paired by timestamps with ``associate`` (else by index, so they must have equal lengths),
    with at least ``minimum`` pairs."""
    est, ref = _as_trajectory(estimate, "estimate"), _as_trajectory(reference, "reference")
    if associate:
        est, ref = _associate(est, ref, max_difference=max_difference, offset=offset)
    if len(est) != len(ref):
        raise ValueError(
            f"{what}: estimate has {len(est)} poses, reference {len(ref)}; poses are paired by index, "
            "so pass trajectories of equal length or associate=True to match timestamps")
    if len(est) < minimum:
        raise ValueError(f"{what} needs at least {minimum} poses, got {len(est)}")
    return est, ref


def umeyama_alignment(source: np.ndarray, target: np.ndarray,
                      with_scale: bool = False) -> Tuple[np.ndarray, np.ndarray, float]:
    """``(R (3, 3), t (3,), s)``, the least-squares similarity (or rigid) transform taking ``source`` onto ``target``
    ((N, 3) corresponding points in one unit; Umeyama 1991, the C++ core's one implementation): it minimises
    ``sum_i || target_i - (s R source_i + t) ||^2`` over rotations R (det +1), translations t and, with ``with_scale``,
    a scale s > 0 (else s = 1). The 4x4 ``[[s R, t], [0, 1]]`` is ``T_target_source``. ValueError: shape mismatch, N <
    3, non-finite values, or all points coincident or collinear in source or target (the rotation is not determined)."""
    R, t, s = _core.registration.fit_similarity(np.ascontiguousarray(source, dtype=np.float64),
                                                np.ascontiguousarray(target, dtype=np.float64), bool(with_scale))
    return np.asarray(R), np.asarray(t), float(s)


def associate(estimate: Trajectory, reference: Trajectory, max_difference: float = 0.02, offset: float = 0.0,
              method: str = "greedy", return_indices: bool = False):
    """Pairs the poses of two trajectories by timestamp (s): ``(estimate_matched, reference_matched)``, with
    ``return_indices`` also the index arrays into the inputs, ``(est, ref, idx_est, idx_ref)``.

    ``offset`` (s) is added to the estimate's timestamps before matching (the TUM tools' ``--offset``); the returned
    trajectories keep their own timestamps.  ``method``: ``"greedy"`` (default; pairs in reference time order),
    :func:`scanalign.evaluation.trajectory.associate_timestamps` (pairs with
    ``|t_ref - (t_est + offset)| <= max_difference``, closest first, every pose used at most once); ``"nearest"``
    (pairs in the shorter trajectory's order), ``evo.core.sync.associate_trajectories(reference, estimate,
    max_diff=max_difference, offset_2=offset)``: every pose of the shorter trajectory (the estimate on a tie) takes
    the nearest pose of the other within ``max_difference``, which may be used more than once.  ValueError: no pair
    within ``max_difference``, a negative ``max_difference``, a non-finite ``offset``, an unknown method."""
    est, ref = _as_trajectory(estimate, "estimate"), _as_trajectory(reference, "reference")
    if not np.isfinite(offset):  # max_difference is checked by both C++ association rules
        raise ValueError(f"offset must be finite, got {offset}")
    te, tr = est.timestamps + float(offset), ref.timestamps
    if method == "greedy":
        # Trajectories need not be time-sorted: match in time order, map back to rows.
        o_r, o_e = np.argsort(tr, kind="stable"), np.argsort(te, kind="stable")
        pairs = associate_timestamps(tr[o_r], te[o_e], max_difference)
        ir, ie = o_r[pairs[:, 0]], o_e[pairs[:, 1]]
    elif method == "nearest":
        # as evo's associate_trajectories(reference, estimate, offset_2=offset): the offset
        # moves the longer trajectory's stamps (sign chosen so it always applies to the estimate)
        est_short = len(est) <= len(ref)
        ts, tl = (est.timestamps, tr - float(offset)) if est_short else (tr, te)
        i_s, i_l = _core.evaluation.associate_nearest(ts, tl, max_difference).T
        ie, ir = (i_s, i_l) if est_short else (i_l, i_s)
    else:
        raise ValueError(f"unknown association method {method!r} (use 'greedy' or 'nearest')")
    if ie.size == 0:
        span = [f"[{t.min()}, {t.max()}]" if len(t) else "[empty, ]" for t in (est.timestamps, tr)]
        raise ValueError(f"associate: no timestamps match within max_difference={max_difference} s (offset "
                         f"{offset} s); estimate spans {span[0]} s, reference {span[1]} s")
    return (est[ie], ref[ir], ie, ir) if return_indices else (est[ie], ref[ir])


@dataclass
class AteResult:
    """Absolute trajectory error: ``translation`` (m) and ``rotation`` (degrees) statistics, the alignment
    ``T_reference_estimate`` = ``[[s R, t], [0, 1]]`` applied to the estimate's world frame (identity without
    ``align``) with its ``scale`` s, the estimate ``aligned`` to the reference frame (rotations ``R R_i``, centres
    ``s R p_i + t``) and the ``reference`` poses paired with it (after association, if any)."""

    translation: ErrorStats
    rotation: ErrorStats
    T_reference_estimate: np.ndarray
    scale: float
    aligned: Trajectory
    reference: Trajectory

    @property
    def rmse(self) -> float:
        """Translational ATE RMSE (m), the number Sturm et al. 2012 report."""
        return self.translation.rmse

    def as_dict(self) -> Dict[str, Any]:
        """JSON-ready: statistics (m, degrees), ``T_reference_estimate`` and ``scale``."""
        return {"translation_m": self.translation.as_dict(), "rotation_deg": self.rotation.as_dict(),
                "T_reference_estimate": self.T_reference_estimate.tolist(), "scale": self.scale}


@dataclass
class RpeResult:
    """Relative pose error: ``translation`` (m) and ``rotation`` (degrees) statistics over the (M, 2) index ``pairs``
    (i, j) of the compared trajectories, chosen by ``delta``, ``delta_unit`` and ``all_pairs``."""

    translation: ErrorStats
    rotation: ErrorStats
    pairs: np.ndarray
    delta: float
    delta_unit: str
    all_pairs: bool

    def as_dict(self) -> Dict[str, Any]:
        """JSON-ready: statistics (m, degrees) and how the pairs were chosen."""
        return {"translation_m": self.translation.as_dict(), "rotation_deg": self.rotation.as_dict(),
                "delta": self.delta, "delta_unit": self.delta_unit, "all_pairs": self.all_pairs}


def absolute_trajectory_error(estimate: TrajectoryLike, reference: TrajectoryLike, align: bool = True,
                              with_scale: bool = False, associate: bool = False,
                              max_difference: float = 0.02, offset: float = 0.0) -> AteResult:
    """Absolute trajectory error (Sturm et al. 2012), translational (m) and rotational (degrees), of ``estimate``
    against ``reference`` (``T_world_camera`` poses, :class:`Trajectory` or (N, 4, 4)) paired by index (equal
    lengths), or with ``associate`` by timestamps (greedy :func:`associate`, ``max_difference`` s, ``offset`` s added
    to the estimate's times).

    With ``align``, the estimated camera centres are fitted to the reference ones by :func:`umeyama_alignment` (a
    similarity with ``with_scale``); the error of pose i is ``|| q_i - (s R p_i + t) ||`` (evo's APE
    ``translation_part`` after ``align``) and the angle of ``R_ref_i^T (R R_est_i)``.  ValueError: different lengths
    without ``associate``, fewer than 3 poses (with ``align``; 1 without), degenerate (collinear) centres with
    ``align``."""
    est, ref = _paired(estimate, reference, associate, max_difference, offset, 3 if align else 1,
                       "absolute_trajectory_error")
    R, t, s = umeyama_alignment(est.positions, ref.positions, with_scale) if align else (np.eye(3), np.zeros(3), 1.0)
    T = np.vstack([np.column_stack([s * R, t]), [0.0, 0.0, 0.0, 1.0]])
    aligned = est.transformed(T)
    aligned.poses[:, :3, :3] = R @ est.rotations  # the scale moves the centres only
    trans_err = np.linalg.norm(aligned.positions - ref.positions, axis=1)
    rot_err = np.degrees(se3.rotation_angle(np.swapaxes(ref.rotations, 1, 2) @ aligned.rotations))
    return AteResult(translation=ErrorStats.from_errors(trans_err), rotation=ErrorStats.from_errors(rot_err),
                     T_reference_estimate=T, scale=float(s), aligned=aligned, reference=ref)


_associate = associate  # absolute_trajectory_error / relative_pose_error shadow the name
_DELTA_UNITS = ("frames", "seconds", "meters")


def relative_pose_error(estimate: TrajectoryLike, reference: TrajectoryLike, delta: float = 1,
                        delta_unit: str = "frames", all_pairs: bool = False, rel_delta_tol: float = 0.1,
                        pairs_from_reference: bool = False, associate: bool = False,
                        max_difference: float = 0.02, offset: float = 0.0) -> RpeResult:
    """Relative pose error (Sturm et al. 2012), translational (m) and rotational (degrees): for each pair (i, j),
    ``E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)`` with Q the reference and P the estimate poses (``T_world_camera``); errors
    are ``|| trans(E_ij) ||`` (m) and the rotation angle of ``E_ij`` (degrees).  No alignment is needed: RPE is
    invariant to a rigid change of either world frame.

    Pairs are chosen as ``evo.core.metrics.RPE`` chooses them, ``delta`` apart in ``delta_unit``: ``"frames"`` (a
    positive integer; Sturm's script is ``all_pairs=True``), ``"meters"`` along the camera-centre path (of the
    estimate, or of the reference with ``pairs_from_reference``) or ``"seconds"`` (not in evo).  ``all_pairs=False``:
    the chain of pairs, each starting where the last ended and ending at the first pose at least ``delta`` further;
    ``all_pairs=True``: for every i the first j > i closest to ``delta`` away, kept within ``rel_delta_tol * delta``
    (exactly ``delta`` for frames).  Poses are paired as in :func:`absolute_trajectory_error`.  ValueError: different
    lengths, fewer than 2 poses, bad delta / unit, no pair found."""
    est, ref = _paired(estimate, reference, associate, max_difference, offset, 2, "relative_pose_error")
    if delta_unit not in _DELTA_UNITS:
        raise ValueError(f"delta_unit must be one of {_DELTA_UNITS}, got {delta_unit!r}")
    if not (np.isfinite(delta) and delta > 0):
        raise ValueError(f"delta must be a positive number, got {delta}")
    n = len(est)
    if delta_unit == "frames" and float(delta) != int(delta):
        raise ValueError(f"delta must be an integer number of frames, got {delta}")
    delta_out = int(delta) if delta_unit == "frames" else float(delta)
    src, tol = (ref if pairs_from_reference else est), rel_delta_tol * delta_out
    if delta_unit == "frames":  # frame indices, exact spacing: (i, i + d) or the chain (0, d), (d, 2d), ...
        s, tol = np.arange(n, dtype=np.float64), 0.0
    elif delta_unit == "meters":
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(src.positions, axis=0), axis=1))])
    else:
        s = src.timestamps
        if np.any(np.diff(s) < 0):
            raise ValueError("delta_unit='seconds' needs non-decreasing timestamps")
    pairs = _core.evaluation.relative_pose_pairs(s, delta_out, bool(all_pairs), tol)
    if pairs.shape[0] == 0:
        raise ValueError(f"relative_pose_error: delta = {delta} {delta_unit} gives no pose pair among {n} poses")
    i, j = pairs[:, 0], pairs[:, 1]
    E = se3.inverse(se3.inverse(ref.poses[i]) @ ref.poses[j]) @ (se3.inverse(est.poses[i]) @ est.poses[j])
    trans = np.linalg.norm(E[:, :3, 3], axis=1)
    rot = np.degrees(se3.rotation_angle(E[:, :3, :3]))
    return RpeResult(translation=ErrorStats.from_errors(trans), rotation=ErrorStats.from_errors(rot),
                     pairs=pairs.astype(np.intp), delta=delta_out, delta_unit=delta_unit, all_pairs=bool(all_pairs))


def evaluate_reconstruction(estimate: TrajectoryLike, reference: TrajectoryLike, *, associate: bool = False,
                            max_difference: float = 0.02, offset: float = 0.0, with_scale: bool = False,
                            rpe_delta: float = 1, rpe_delta_unit: str = "frames", rpe_all_pairs: bool = True,
                            points: Optional[np.ndarray] = None,
                            mesh: Optional[Tuple[np.ndarray, np.ndarray]] = None) -> Dict[str, Any]:
    """ATE and RPE (and optionally cloud-to-mesh distances) as a JSON-ready dict (m, degrees), by default as in the
    TUM benchmark: ATE after rigid alignment, RPE over every pair (i, i + 1 frame).  Keys: ``poses``, ``ate``
    (:meth:`AteResult.as_dict`), ``rpe`` (:meth:`RpeResult.as_dict`) and, given ``points`` (the reconstructed cloud, in
    the mesh's frame) and ``mesh`` ``(vertices, faces)`` (or an Open3D / trimesh mesh), ``cloud_to_mesh_m``."""
    if (points is None) != (mesh is None):
        raise ValueError("pass both points and mesh=(vertices, faces) for the cloud-to-mesh distance, or neither")
    est, ref = _paired(estimate, reference, associate, max_difference, offset, 0, "evaluate_reconstruction")
    ate = absolute_trajectory_error(est, ref, with_scale=with_scale)
    rpe = relative_pose_error(est, ref, delta=rpe_delta, delta_unit=rpe_delta_unit, all_pairs=rpe_all_pairs)
    out: Dict[str, Any] = {"poses": len(est), "ate": ate.as_dict(), "rpe": rpe.as_dict()}
    if mesh is not None:
        mesh = mesh_arrays(mesh) or mesh  # or an Open3D / trimesh mesh
        out["cloud_to_mesh_m"] = mesh_distance_stats(points, mesh[0], mesh[1]).as_dict()
    return out

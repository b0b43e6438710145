"""Trajectory and reconstruction accuracy: ATE, RPE (Sturm et al. 2012), cloud-to-mesh distance.

Conventions (see the package README): metres, radians for inputs; a pose ``T_world_camera``
maps camera coordinates into the trajectory's world frame.  Error statistics report
translations in metres and rotations in **degrees** (like the TUM benchmark tools and
``evo``'s ``rotation_angle_deg``).

- :func:`absolute_trajectory_error` (ATE): after the least-squares rigid (optionally
  similarity) alignment of the estimated camera centres to the reference ones (Horn 1987 /
  Umeyama 1991), the per-pose distance ``|| q_i - (s R p_i + t) ||`` between reference centre
  ``q_i`` and aligned estimated centre.  Identical to ``evo``'s APE with
  ``PoseRelation.translation_part`` after ``traj_est.align(traj_ref)``.
- :func:`relative_pose_error` (RPE): for index pairs (i, j), with Q the reference and P the
  estimate, ``E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)``; the translational error is
  ``||trans(E_ij)||`` (m), the rotational error the angle of ``rot(E_ij)`` (degrees).
  Pairs are chosen as ``evo``'s ``RPE`` does (see :func:`relative_pose_error`).
- :func:`point_to_mesh_distance`: exact Euclidean distance from each point to the nearest
  triangle of a mesh, through a bounding-volume hierarchy with exact box bounds.

Everything is vectorised NumPy; only NumPy is required.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Dict, Optional, Tuple, Union

import numpy as np

from . import _core, se3
from .trajectory import Trajectory

__all__ = [
    "umeyama_alignment",
    "associate",
    "ErrorStats",
    "AteResult",
    "RpeResult",
    "absolute_trajectory_error",
    "relative_pose_error",
    "MeshDistanceIndex",
    "MeshDistanceStats",
    "point_to_mesh_distance",
    "mesh_distance_stats",
    "evaluate_reconstruction",
]

TrajectoryLike = Union[Trajectory, np.ndarray]


# --------------------------------------------------------------------------------------
# Small SE(3) helpers
# --------------------------------------------------------------------------------------

def _as_trajectory(x: TrajectoryLike, name: str) -> Trajectory:
    if isinstance(x, Trajectory):
        return x
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 3 or a.shape[1:] != (4, 4):
        raise TypeError(f"{name}: expected a Trajectory or an (N, 4, 4) array of poses, got {type(x).__name__}"
                        f"{' of shape ' + str(a.shape) if hasattr(a, 'shape') else ''}")
    return Trajectory(np.arange(a.shape[0], dtype=np.float64), a)


def _check_same_length(est: Trajectory, ref: Trajectory, minimum: int, what: str) -> None:
    if len(est) != len(ref):
        raise ValueError(
            f"{what}: estimate has {len(est)} poses, reference {len(ref)}; poses are paired by index, "
            "so pass trajectories of equal length or associate=True to match timestamps")
    if len(est) < minimum:
        raise ValueError(f"{what} needs at least {minimum} poses, got {len(est)}")


# --------------------------------------------------------------------------------------
# Umeyama / Horn alignment
# --------------------------------------------------------------------------------------

def umeyama_alignment(source: np.ndarray, target: np.ndarray,
                      with_scale: bool = False) -> Tuple[np.ndarray, np.ndarray, float]:
    """Least-squares similarity (or rigid) transform taking ``source`` onto ``target``.

    Minimises ``sum_i || target_i - (s R source_i + t) ||^2`` over rotations R (det +1),
    translations t and, when ``with_scale``, a scale s > 0 (otherwise s = 1): Umeyama 1991,
    the closed form of Horn 1987 with the reflection correction.

    Args:
        source: (N, 3) points (e.g. estimated camera centres), any unit.
        target: (N, 3) corresponding points (e.g. reference centres), same unit.
        with_scale: also estimate the scale (monocular / scale-drifting estimates).

    Returns:
        (R (3, 3), t (3,), s float) so that ``target ~ s * R @ source + t``, i.e. the
        4x4 ``[[s R, t], [0, 1]]`` is ``T_target_source``.

    Raises:
        ValueError: shape mismatch, N < 3, non-finite values, or a degenerate configuration
            (all points coincident or collinear in source or target: the cross-covariance
            has rank < 2 and the rotation is not determined).
    """
    # The one Kabsch/Umeyama implementation is C++'s (scanalign/common/rigid.hpp).
    R, t, s = _core.registration.fit_similarity(np.ascontiguousarray(source, dtype=np.float64),
                                                np.ascontiguousarray(target, dtype=np.float64), bool(with_scale))
    return np.asarray(R), np.asarray(t), float(s)


# --------------------------------------------------------------------------------------
# Timestamp association
# --------------------------------------------------------------------------------------

def _greedy_matching(i_a: np.ndarray, i_b: np.ndarray, n_a: int, n_b: int) -> np.ndarray:
    """Greedy one-to-one matching over candidate edges given in priority order (best first).

    Returns the boolean mask of the selected edges.  Equivalent to scanning the edges in
    order and taking each whose two ends are still free.  Vectorised: rounds of "locally
    dominant" edges (best among all remaining edges at both ends), which greedy provably
    selects; when a round selects few edges (long chains of decreasing quality), the rest
    is finished by the sequential scan.
    """
    m = i_a.shape[0]
    chosen = np.zeros(m, dtype=bool)
    alive = np.ones(m, dtype=bool)
    prio = np.arange(m)
    big = np.iinfo(np.int64).max
    for _ in range(64):
        idx = np.flatnonzero(alive)
        if idx.size == 0:
            return chosen
        best_a = np.full(n_a, big, dtype=np.int64)
        best_b = np.full(n_b, big, dtype=np.int64)
        np.minimum.at(best_a, i_a[idx], prio[idx])
        np.minimum.at(best_b, i_b[idx], prio[idx])
        dom = idx[(best_a[i_a[idx]] == prio[idx]) & (best_b[i_b[idx]] == prio[idx])]
        chosen[dom] = True
        used_a = np.zeros(n_a, dtype=bool)
        used_b = np.zeros(n_b, dtype=bool)
        used_a[i_a[dom]] = True
        used_b[i_b[dom]] = True
        alive[idx[used_a[i_a[idx]] | used_b[i_b[idx]]]] = False
        if dom.size * 20 < idx.size:
            break
    # Sequential finish (edges remain in priority order).
    used_a = np.zeros(n_a, dtype=bool)
    used_b = np.zeros(n_b, dtype=bool)
    used_a[i_a[chosen]] = True
    used_b[i_b[chosen]] = True
    for e in np.flatnonzero(alive).tolist():
        a, b = i_a[e], i_b[e]
        if not used_a[a] and not used_b[b]:
            used_a[a] = used_b[b] = True
            chosen[e] = True
    return chosen


def associate(estimate: Trajectory, reference: Trajectory, max_difference: float = 0.02,
              offset: float = 0.0, method: str = "greedy",
              return_indices: bool = False):
    """Pairs the poses of two trajectories by timestamp.

    ``offset`` (s) is added to the estimate's timestamps before matching (the TUM tools'
    ``--offset`` on the second file); the returned trajectories keep their own timestamps.

    Methods:
        ``"greedy"`` (default): TUM RGB-D ``associate.py``: all pairs with
            ``|t_ref - (t_est + offset)| < max_difference`` (strict) are ranked by that
            difference (ties: reference time, then estimate time) and taken greedily so that
            every pose is used at most once.
        ``"nearest"``: ``evo.core.sync.associate_trajectories(reference, estimate,
            max_diff=max_difference, offset_2=offset)`` (evo's command-line order): every pose of the
            trajectory with fewer poses (the estimate on a tie) is matched to the nearest
            pose of the other within ``<= max_difference`` (ties to the earlier one); a pose
            of the longer trajectory may be used more than once.

    Returns:
        ``(estimate_matched, reference_matched)``, equal-length trajectories ordered by
        reference time for ``"greedy"`` and by the shorter trajectory's order for
        ``"nearest"``; with ``return_indices`` also the index arrays into the inputs,
        ``(est, ref, idx_est, idx_ref)``.

    Raises:
        ValueError: no pair within ``max_difference``, a negative ``max_difference``, an
            unknown method.
    """
    est = _as_trajectory(estimate, "estimate")
    ref = _as_trajectory(reference, "reference")
    if not (max_difference >= 0.0 and np.isfinite(max_difference)):
        raise ValueError(f"max_difference must be a finite number >= 0 (s), got {max_difference}")
    if not np.isfinite(offset):
        raise ValueError(f"offset must be finite, got {offset}")
    te = est.timestamps + float(offset)
    tr = ref.timestamps
    if method == "greedy":
        order_r = np.argsort(tr, kind="stable")
        tr_sorted = tr[order_r]
        lo = np.searchsorted(tr_sorted, te - max_difference, side="left")
        hi = np.searchsorted(tr_sorted, te + max_difference, side="right")
        counts = np.maximum(hi - lo, 0)
        ie = np.repeat(np.arange(te.shape[0]), counts)
        start = np.repeat(lo - np.cumsum(counts) + counts, counts)
        ir = order_r[start + np.arange(ie.shape[0])] if ie.size else np.zeros(0, dtype=np.intp)
        diff = np.abs(tr[ir] - te[ie])
        keep = diff < max_difference
        ie, ir, diff = ie[keep], ir[keep], diff[keep]
        prio = np.lexsort((ie, ir, te[ie], tr[ir], diff))
        ie, ir = ie[prio], ir[prio]
        sel = _greedy_matching(ir, ie, tr.shape[0], te.shape[0])
        ie, ir = ie[sel], ir[sel]
        o = np.lexsort((te[ie], tr[ir]))
        ie, ir = ie[o], ir[o]
    elif method == "nearest":
        # as evo's associate_trajectories(reference, estimate, offset_2=offset): the offset
        # moves the longer trajectory's stamps (sign chosen so it always applies to the estimate)
        est_short = len(est) <= len(ref)
        ts, tl = (est.timestamps, tr - float(offset)) if est_short else (tr, te)
        if np.any(np.diff(tl) < 0):
            raise ValueError("method='nearest' needs the longer trajectory's timestamps sorted")
        if tl.size == 0 or ts.size == 0:
            i_s = i_l = np.zeros(0, dtype=np.intp)
        else:
            k = np.minimum(np.searchsorted(tl, ts, side="right"), tl.size - 1)
            d_ub = tl[k] - ts
            d_lb = np.where(k > 0, ts - tl[np.maximum(k - 1, 0)], np.inf)
            in_range = (ts >= tl[0] - max_difference) & (ts <= tl[-1] + max_difference)
            take_ub = (d_ub <= max_difference) & (d_ub < d_lb)
            take_lb = ~take_ub & (d_lb <= max_difference) & (d_lb <= d_ub)
            ok = in_range & (take_ub | take_lb)
            i_s = np.flatnonzero(ok)
            i_l = np.where(take_ub, k, k - 1)[ok]
        ie, ir = (i_s, i_l) if est_short else (i_l, i_s)
    else:
        raise ValueError(f"unknown association method {method!r} (use 'greedy' or 'nearest')")
    if ie.size == 0:
        raise ValueError(
            f"associate: no timestamps match within max_difference={max_difference} s (offset {offset} s); "
            f"estimate spans [{est.timestamps.min() if len(est) else 'empty'}, "
            f"{est.timestamps.max() if len(est) else ''}] s, reference "
            f"[{tr.min() if len(ref) else 'empty'}, {tr.max() if len(ref) else ''}] s")
    est_m, ref_m = est[ie], ref[ir]
    if return_indices:
        return est_m, ref_m, ie, ir
    return est_m, ref_m


# --------------------------------------------------------------------------------------
# Error statistics and results
# --------------------------------------------------------------------------------------

@dataclass
class ErrorStats:
    """Summary of per-pose (or per-pair) errors, as the TUM tools and ``evo`` report them.

    Units are those of ``errors`` (metres for translations, degrees for rotations).
    ``std`` is the population standard deviation (ddof = 0, like ``numpy.std``, ``evo``
    and the TUM scripts); ``sse`` the sum of squares; ``rmse = sqrt(sse / count)``.
    """

    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float
    sse: float
    count: int
    errors: np.ndarray = field(repr=False)

    @classmethod
    def from_errors(cls, errors: np.ndarray) -> "ErrorStats":
        e = np.asarray(errors, dtype=np.float64).reshape(-1)
        if e.size == 0:
            raise ValueError("no errors to summarise")
        sse = float(np.sum(e * e))
        return cls(rmse=float(np.sqrt(sse / e.size)), mean=float(np.mean(e)), median=float(np.median(e)),
                   std=float(np.std(e)), min=float(np.min(e)), max=float(np.max(e)), sse=sse,
                   count=int(e.size), errors=e)

    def as_dict(self, include_errors: bool = False) -> Dict[str, Any]:
        """Plain floats (JSON-serialisable); the per-pose errors only on request."""
        keys = ("rmse", "mean", "median", "std", "min", "max", "sse", "count")
        d: Dict[str, Any] = {k: getattr(self, k) for k in keys}
        if include_errors:
            d["errors"] = self.errors.tolist()
        return d


@dataclass
class AteResult:
    """Absolute trajectory error.

    Attributes:
        translation: ATE, distances between reference and aligned estimated camera centres (m).
        rotation: angles of ``R_ref_i^T R_aligned_i`` (degrees) after the same alignment.
        T_reference_estimate: 4x4 ``[[s R, t], [0, 1]]`` that was applied to the estimate's
            world frame (identity when ``align=False``); a similarity when ``scale != 1``.
        scale: s (1.0 unless ``with_scale``).
        aligned: the estimate in the reference world frame: rotations ``R R_i``, centres
            ``s R p_i + t`` (after association, if any).
        reference: the reference poses paired with ``aligned`` (after association, if any).
    """

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
        return {"translation_m": self.translation.as_dict(), "rotation_deg": self.rotation.as_dict(),
                "T_reference_estimate": self.T_reference_estimate.tolist(), "scale": self.scale}


@dataclass
class RpeResult:
    """Relative pose error over index pairs (i, j) of the (associated) trajectories.

    Attributes:
        translation: ``|| trans(E_ij) ||`` (m) per pair.
        rotation: rotation angle of ``E_ij`` (degrees) per pair.
        pairs: (M, 2) indices (i, j) into the compared trajectories.
        delta, delta_unit, all_pairs: the pair selection used.
    """

    translation: ErrorStats
    rotation: ErrorStats
    pairs: np.ndarray
    delta: float
    delta_unit: str
    all_pairs: bool

    def as_dict(self) -> Dict[str, Any]:
        return {"translation_m": self.translation.as_dict(), "rotation_deg": self.rotation.as_dict(),
                "delta": self.delta, "delta_unit": self.delta_unit, "all_pairs": self.all_pairs}


# --------------------------------------------------------------------------------------
# ATE
# --------------------------------------------------------------------------------------

def absolute_trajectory_error(estimate: TrajectoryLike, reference: TrajectoryLike, align: bool = True,
                              with_scale: bool = False, associate: bool = False,
                              max_difference: float = 0.02, offset: float = 0.0) -> AteResult:
    """Absolute trajectory error (Sturm et al. 2012, §"ATE"), translational and rotational.

    The estimated camera centres are aligned to the reference ones by the least-squares
    rigid transform (Horn; with ``with_scale`` a similarity, Umeyama), then the error of
    pose i is ``|| q_i - (s R p_i + t) ||`` (m).  Equal to ``evo``'s
    ``APE(PoseRelation.translation_part)`` after ``traj_est.align(traj_ref, correct_scale)``.
    The rotational error of pose i is the angle (degrees) of ``R_ref_i^T (R R_est_i)``
    (evo's ``rotation_angle_deg``); the alignment is fitted to positions only.

    Args:
        estimate: estimated ``T_world_camera`` poses (a :class:`Trajectory` or (N, 4, 4)).
        reference: reference (ground-truth) poses, same form.
        align: fit the alignment (otherwise both are compared in their given frames).
        with_scale: fit a scale too.
        associate: pair the poses by timestamps with :func:`associate` (greedy,
            ``max_difference`` s, ``offset`` s added to the estimate's times); otherwise they
            are paired by index and must have equal lengths.

    Raises:
        ValueError: different lengths without ``associate``, fewer than 3 poses (with
            ``align``; 1 without), degenerate (collinear) centres with ``align``.
    """
    est = _as_trajectory(estimate, "estimate")
    ref = _as_trajectory(reference, "reference")
    if associate:
        est, ref = _associate(est, ref, max_difference=max_difference, offset=offset)
    _check_same_length(est, ref, 3 if align else 1, "absolute_trajectory_error")
    p = est.positions
    q = ref.positions
    if align:
        R, t, s = umeyama_alignment(p, q, with_scale=with_scale)
    else:
        R, t, s = np.eye(3), np.zeros(3), 1.0
    aligned_poses = est.poses.copy()
    aligned_poses[:, :3, :3] = R @ est.rotations
    aligned_poses[:, :3, 3] = s * (p @ R.T) + t
    aligned = Trajectory(est.timestamps.copy(), aligned_poses)
    trans_err = np.linalg.norm(aligned_poses[:, :3, 3] - q, axis=1)
    rel_rot = np.swapaxes(ref.rotations, 1, 2) @ aligned_poses[:, :3, :3]
    rot_err = np.degrees(se3.rotation_angle(rel_rot))
    T = np.eye(4)
    T[:3, :3] = s * R
    T[:3, 3] = t
    return AteResult(translation=ErrorStats.from_errors(trans_err), rotation=ErrorStats.from_errors(rot_err),
                     T_reference_estimate=T, scale=float(s), aligned=aligned, reference=ref)


_associate = associate  # absolute_trajectory_error / relative_pose_error shadow the name


# --------------------------------------------------------------------------------------
# RPE
# --------------------------------------------------------------------------------------

_DELTA_UNITS = ("frames", "seconds", "meters")


def _pairs_consecutive(s: np.ndarray, delta: float) -> np.ndarray:
    """Chain 0 = i_0 < i_1 < ...: i_{k+1} is the first index with s[i_{k+1}] - s[i_k] >= delta."""
    n = s.shape[0]
    nxt = np.searchsorted(s, s + delta, side="left")
    # searchsorted on rounded sums can land one off; fix so that nxt is exactly the first
    # j > i with (s[j] - s[i]) >= delta as computed in floating point.
    nxt = np.maximum(nxt, np.arange(n) + 1)
    for _ in range(2):
        prev = np.maximum(nxt - 1, 0)
        step_back = (nxt - 1 > np.arange(n)) & (s[prev] - s >= delta)
        nxt = np.where(step_back, nxt - 1, nxt)
        cur = np.minimum(nxt, n - 1)
        step_fwd = (nxt < n) & (s[cur] - s < delta)
        nxt = np.where(step_fwd, nxt + 1, nxt)
    ids = [0]
    i = 0
    nxt_list = nxt.tolist()
    while nxt_list[i] < n:  # walks the chain only (one step per pair)
        i = nxt_list[i]
        ids.append(i)
    ids_a = np.asarray(ids, dtype=np.intp)
    return np.stack([ids_a[:-1], ids_a[1:]], axis=1)


def _pairs_all(s: np.ndarray, delta: float, tol: float) -> np.ndarray:
    """For each i, the first j > i minimising |(s[j] - s[i]) - delta|, kept if <= tol."""
    n = s.shape[0]
    if n < 2:
        return np.zeros((0, 2), dtype=np.intp)
    i = np.arange(n - 1)
    k = np.searchsorted(s, s[i] + delta, side="left")
    cand = k[:, None] + np.arange(-2, 2)[None, :]
    cand = np.clip(cand, i[:, None] + 1, n - 1)
    # first index holding the same value (argmin takes the first of equal errors)
    cand = np.maximum(np.searchsorted(s, s[cand], side="left"), i[:, None] + 1)
    err = np.abs((s[cand] - s[i][:, None]) - delta)
    pick = np.argmin(err, axis=1)  # candidates are ascending: ties go to the smallest j
    j = cand[i, pick]
    e = err[i, pick]
    ok = e <= tol
    return np.stack([i[ok], j[ok]], axis=1)


def relative_pose_error(estimate: TrajectoryLike, reference: TrajectoryLike, delta: float = 1,
                        delta_unit: str = "frames", all_pairs: bool = False, rel_delta_tol: float = 0.1,
                        pairs_from_reference: bool = False, associate: bool = False,
                        max_difference: float = 0.02, offset: float = 0.0) -> RpeResult:
    """Relative pose error (Sturm et al. 2012), translational (m) and rotational (degrees).

    For each pair (i, j): ``E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)`` with Q the reference and P
    the estimate poses (``T_world_camera``); errors are ``|| trans(E_ij) ||`` (m) and the
    rotation angle of ``E_ij`` (degrees).  No alignment is needed: RPE is invariant to a
    rigid change of either world frame.

    Pair selection follows ``evo.core.metrics.RPE`` (so results equal evo's):

    - ``delta_unit="frames"``: ``all_pairs=False`` uses non-overlapping pairs
      (0, d), (d, 2d), ...; ``all_pairs=True`` every (i, i + d).  (Sturm's script uses
      every (i, i + d), i.e. ``all_pairs=True``.)
    - ``"meters"``: distance travelled along the camera-centre path (of the estimate, or the
      reference with ``pairs_from_reference``).  Consecutive: from the last pair end, the
      first pose at least ``delta`` m further along the path; all pairs: for every i the
      first j > i whose path distance is closest to ``delta``, kept if within
      ``rel_delta_tol * delta``.
    - ``"seconds"`` (not in evo): the same rules on the timestamps (s) instead of path length.

    Args:
        estimate, reference: trajectories (or (N, 4, 4) arrays) paired by index, or by
            timestamps with ``associate`` (greedy :func:`associate`, ``max_difference`` s,
            ``offset`` s added to the estimate's times).
        delta: pair spacing in ``delta_unit`` (a positive integer for frames).

    Raises:
        ValueError: different lengths, fewer than 2 poses, bad delta / unit, no pair found.
    """
    est = _as_trajectory(estimate, "estimate")
    ref = _as_trajectory(reference, "reference")
    if associate:
        est, ref = _associate(est, ref, max_difference=max_difference, offset=offset)
    _check_same_length(est, ref, 2, "relative_pose_error")
    if delta_unit not in _DELTA_UNITS:
        raise ValueError(f"delta_unit must be one of {_DELTA_UNITS}, got {delta_unit!r}")
    if not (np.isfinite(delta) and delta > 0):
        raise ValueError(f"delta must be a positive number, got {delta}")
    n = len(est)
    if delta_unit == "frames":
        if float(delta) != int(delta):
            raise ValueError(f"delta must be an integer number of frames, got {delta}")
        d = int(delta)
        if all_pairs:
            i = np.arange(max(n - d, 0))
            pairs = np.stack([i, i + d], axis=1)
        else:
            ids = np.arange(0, n, d)
            pairs = np.stack([ids[:-1], ids[1:]], axis=1)
        delta_out: float = d
    else:
        if delta_unit == "meters":
            src = ref if pairs_from_reference else est
            steps = np.linalg.norm(np.diff(src.positions, axis=0), axis=1)
            s = np.concatenate([[0.0], np.cumsum(steps)])
        else:
            s = (ref if pairs_from_reference else est).timestamps
            if np.any(np.diff(s) < 0):
                raise ValueError("delta_unit='seconds' needs non-decreasing timestamps")
        delta_out = float(delta)
        pairs = _pairs_all(s, delta_out, rel_delta_tol * delta_out) if all_pairs else _pairs_consecutive(s, delta_out)
    if pairs.shape[0] == 0:
        raise ValueError(f"relative_pose_error: delta = {delta} {delta_unit} gives no pose pair among {n} poses")
    i, j = pairs[:, 0], pairs[:, 1]
    Q, P = ref.poses, est.poses
    Q_rel = se3.inverse(Q[i]) @ Q[j]
    P_rel = se3.inverse(P[i]) @ P[j]
    E = se3.inverse(Q_rel) @ P_rel
    trans = np.linalg.norm(E[:, :3, 3], axis=1)
    rot = np.degrees(se3.rotation_angle(E[:, :3, :3]))
    return RpeResult(translation=ErrorStats.from_errors(trans), rotation=ErrorStats.from_errors(rot),
                     pairs=pairs.astype(np.intp), delta=delta_out, delta_unit=delta_unit, all_pairs=bool(all_pairs))


# --------------------------------------------------------------------------------------
# Exact point-to-mesh distance
# --------------------------------------------------------------------------------------

_FLOATS = (np.dtype(np.float32), np.dtype(np.float64))


class MeshDistanceIndex:
    """Exact point-to-triangle-mesh distance queries; build once, query many times.

    Index: a bounding-volume hierarchy stored as an implicit complete binary tree.  The
    triangles are split top-down at the median centroid along the longest axis of each
    node's centroid extent, down to leaves of at most ``leaf_size`` triangles; every node
    keeps the tight axis-aligned box of its triangles.

    Query, for a block of points at once (vectorised, level by level):

    1. Upper bound u: each point descends to one leaf, always into the child whose box is
       nearer (ties: smaller MinMaxDist), and u is the exact distance to that leaf's
       triangles.
    2. Every node whose box lies within u of the point is visited (a box's distance is a
       lower bound for all triangles inside it, so no node holding a nearer triangle is
       skipped).
    3. The surviving leaves are evaluated nearest-box first, shrinking u after each round
       and skipping leaves and triangles whose boxes are farther than u.

    The result is the exact minimum over all triangles whatever their sizes (up to
    floating-point rounding; every pruning test has a relative slack of 1e-9).  Cost grows
    for points far from the mesh relative to its triangle size: axis-aligned boxes bound a
    distant surface loosely, so many leaves stay candidates.

    Point-to-triangle distance: the smaller of the distances to the three edge segments
    and, when the point's projection falls inside the triangle, to the plane.  Zero-area
    (degenerate) triangles are handled as their edges.

    Args:
        vertices: (V, 3) float32/float64 vertex coordinates (m).
        faces: (F, 3) integer vertex indices (any integer dtype), F >= 1.  Vertices not
            used by any face are ignored (and may be non-finite).
        leaf_size: triangles per leaf.

    Raises:
        TypeError: wrong dtypes.  ValueError: wrong shapes, no faces, an index out of
        range, a non-finite vertex used by a face.
    """

    # columns of the packed per-triangle table
    _A, _B, _C, _E0, _E1, _E2, _INV, _N, _M0, _M1, _M2 = (slice(3 * k, 3 * k + 3) for k in range(11))
    _NONDEG = 33

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, leaf_size: int = 8) -> None:
        v = np.asarray(vertices)
        f = np.asarray(faces)
        if v.dtype not in _FLOATS:
            raise TypeError(f"vertices: expected a float32 or float64 array, got dtype {v.dtype}")
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"vertices: expected shape (V, 3), got {v.shape}")
        if not np.issubdtype(f.dtype, np.integer):
            raise TypeError(f"faces: expected an integer array, got dtype {f.dtype}")
        if f.ndim != 2 or f.shape[1] != 3:
            raise ValueError(f"faces: expected shape (F, 3), got {f.shape}")
        if f.shape[0] == 0:
            raise ValueError("faces: the mesh has no triangles")
        if f.min() < 0 or f.max() >= v.shape[0]:
            raise ValueError(f"faces: vertex indices must lie in [0, {v.shape[0]}), got [{f.min()}, {f.max()}]")
        if int(leaf_size) < 1:
            raise ValueError("leaf_size must be >= 1")
        leaf_size = int(leaf_size)
        v = v.astype(np.float64)
        f = f.astype(np.intp)
        used = v[np.unique(f)]
        if not np.all(np.isfinite(used)):
            raise ValueError("vertices: a vertex used by a face is not finite")
        self.n_faces = int(f.shape[0])
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        # --- per-triangle data for the exact distance -----------------------------------
        e0, e1, e2 = b - a, c - b, a - c
        lens = np.stack([np.einsum("ij,ij->i", e, e) for e in (e0, e1, e2)], axis=1)
        inv = np.where(lens > 0, 1.0 / np.where(lens > 0, lens, 1.0), 0.0)  # 0: zero-length edge
        n = np.cross(e0, c - a)
        nn = np.einsum("ij,ij->i", n, n)
        # Degenerate when |e0 x e2|^2 is rounding-level relative to |e0|^2 |e2|^2 (sin^2 of
        # the angle at a); such triangles are exactly their edges.
        nondeg = (nn > 0) & (nn > 1e-24 * lens[:, 0] * lens[:, 2])
        nhat = np.where(nondeg[:, None], n / np.sqrt(np.where(nondeg, nn, 1.0))[:, None], 0.0)
        # inward edge normals: dot(m_k, p - v_k) >= 0 for all k <=> projection inside
        m0, m1, m2 = np.cross(nhat, e0), np.cross(nhat, e1), np.cross(nhat, e2)
        self._td = np.concatenate([a, b, c, e0, e1, e2, inv, nhat, m0, m1, m2, nondeg[:, None]], axis=1)
        self._tri_box = np.concatenate([np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)], axis=1)
        # --- leaves and the box hierarchy (top-down median splits) ----------------------
        n_leaves = -(-self.n_faces // leaf_size)
        depth = int(np.ceil(np.log2(n_leaves))) if n_leaves > 1 else 0
        n_nodes = 1 << depth
        # Leaf k receives floor or ceil of F / 2^depth (<= leaf_size) consecutive triangles
        # of ``order``; node ranges at every level follow from these counts.
        per_leaf = np.full(n_nodes, self.n_faces // n_nodes)
        per_leaf[: self.n_faces % n_nodes] += 1
        cen = (a + b + c) / 3.0
        order = np.arange(self.n_faces)
        for level in range(depth):
            # node of every position at this level, then sort each node's range along the
            # longest axis of its centroids' extent: the halves become the two children.
            node_of_leaf = np.arange(n_nodes) >> (depth - level)
            node = np.repeat(node_of_leaf, per_leaf)
            cc = cen[order]
            n_lvl = 1 << level
            lo = np.full((n_lvl, 3), np.inf)
            hi = np.full((n_lvl, 3), -np.inf)
            _group_minmax(lo, hi, node, cc)
            axis = np.argmax(np.where(np.isfinite(hi - lo), hi - lo, -1.0), axis=1)
            key = cc[np.arange(self.n_faces), axis[node]]
            order = order[np.lexsort((key, node))]
        starts = np.concatenate([[0], np.cumsum(per_leaf)[:-1]])
        slot = np.repeat(np.arange(n_nodes) * leaf_size - starts, per_leaf) + np.arange(self.n_faces)
        leaf_tris = np.full(n_nodes * leaf_size, -1, dtype=np.intp)
        leaf_tris[slot] = order
        self._leaf_tris = leaf_tris.reshape(n_nodes, leaf_size)
        valid = self._leaf_tris >= 0
        idx = np.where(valid, self._leaf_tris, 0)
        leaf_lo = np.where(valid[..., None], self._tri_box[idx, :3], np.inf).min(axis=1)
        leaf_hi = np.where(valid[..., None], self._tri_box[idx, 3:], -np.inf).max(axis=1)
        self._box_lo = [leaf_lo]
        self._box_hi = [leaf_hi]
        for _ in range(depth):  # empty boxes (lo = +inf, hi = -inf) stay empty
            self._box_lo.insert(0, self._box_lo[0].reshape(-1, 2, 3).min(axis=1))
            self._box_hi.insert(0, self._box_hi[0].reshape(-1, 2, 3).max(axis=1))
        self._depth = depth
        self._abs_slack = 1e-12 * max(float(np.max(np.abs(used))), 1e-300)

    # -- exact distance for (point, triangle) pairs --------------------------------------
    def _pair_d2(self, p: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Squared exact distances for pairs (p[k], triangle t[k])."""
        out = np.empty(p.shape[0])
        step = 1 << 16
        dot = _rowdot
        for s0 in range(0, p.shape[0], step):  # chunks bound temporary memory
            pp = p[s0:s0 + step]
            td = self._td[t[s0:s0 + step]]
            ap, bp, cp = pp - td[:, self._A], pp - td[:, self._B], pp - td[:, self._C]
            best = None
            for vp, es, k in ((ap, self._E0, 0), (bp, self._E1, 1), (cp, self._E2, 2)):
                e = td[:, es]
                u = np.clip(dot(vp, e) * td[:, 18 + k], 0.0, 1.0)
                r = vp - u[:, None] * e
                d2 = dot(r, r)
                best = d2 if best is None else np.minimum(best, d2)
            inside = ((td[:, self._NONDEG] > 0) & (dot(ap, td[:, self._M0]) >= 0)
                      & (dot(bp, td[:, self._M1]) >= 0) & (dot(cp, td[:, self._M2]) >= 0))
            h = dot(ap, td[:, self._N])
            out[s0:s0 + step] = np.where(inside, np.minimum(best, h * h), best)
        return out

    @staticmethod
    def _box_d2(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Squared distance from p to boxes [lo, hi] (inf for empty boxes)."""
        d = np.maximum(np.maximum(lo - p, p - hi), 0.0)
        return _rowdot(d, d)

    @staticmethod
    def _minmax_d2(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        """Squared MinMaxDist of p to tight boxes: every face of a tight box touches the
        contents, so some content point lies within this distance.  inf for empty boxes."""
        with np.errstate(invalid="ignore"):
            mid = 0.5 * (lo + hi)
            near = np.where(p <= mid, lo, hi) - p
            far = np.where(p >= mid, lo, hi) - p
            far2 = far * far
            cand = far2.sum(axis=1)[:, None] - far2 + near * near
            m = cand.min(axis=1)
        return np.where(np.isfinite(m), m, np.inf)

    def _slack(self, ub2: np.ndarray) -> np.ndarray:
        return (np.sqrt(ub2) * (1.0 + 1e-9) + self._abs_slack) ** 2

    def _beam_bound(self, p: np.ndarray, beam: int) -> np.ndarray:
        """Upper bound (squared): exact distance to the triangles of ``beam`` leaves reached
        by keeping, per point and level, the ``beam`` children nearest by box distance
        (ties by MinMaxDist).  Cheap (K x 2 beam boxes per level) and usually tight."""
        K = p.shape[0]
        nodes = np.zeros((K, 1), dtype=np.intp)
        for level in range(1, self._depth + 1):
            ch = (2 * nodes[:, :, None] + np.array([0, 1])).reshape(K, -1)
            lo, hi = self._box_lo[level][ch.reshape(-1)], self._box_hi[level][ch.reshape(-1)]
            pp = np.repeat(p, ch.shape[1], axis=0)
            d2 = self._box_d2(pp, lo, hi).reshape(K, -1)
            mm = self._minmax_d2(pp, lo, hi).reshape(K, -1)
            if ch.shape[1] > beam:
                o = _lexsort_rows(d2, mm)[:, :beam]
                ch = np.take_along_axis(ch, o, axis=1)
            nodes = ch
        ub2 = np.full(K, np.inf)
        pidx = np.repeat(np.arange(K), nodes.shape[1])
        self._leaf_exact(p, pidx, nodes.reshape(-1), ub2, prune=False)
        return ub2

    def _query_chunk(self, p: np.ndarray, max_pairs: int) -> Optional[np.ndarray]:
        K = p.shape[0]
        ub2 = self._beam_bound(p, 1)
        pidx = np.arange(K)
        node = np.zeros(K, dtype=np.intp)
        d2 = np.zeros(K)
        for level in range(self._depth + 1):  # pidx stays sorted throughout
            lo, hi = self._box_lo[level][node], self._box_hi[level][node]
            pp = p[pidx]
            d2 = self._box_d2(pp, lo, hi)
            sel = d2 <= self._slack(ub2)[pidx]
            pidx, node, d2 = pidx[sel], node[sel], d2[sel]
            if level < self._depth:
                if 2 * pidx.size > max_pairs and K > 1:
                    return None  # frontier too large: the caller splits the block
                pidx = np.repeat(pidx, 2)
                node = (2 * np.repeat(node, 2)) + np.tile(np.array([0, 1], dtype=np.intp), node.size)
        if pidx.size * self._leaf_tris.shape[1] > 4 * max_pairs and K > 1:
            return None
        # Leaves best-first: the r-th nearest leaf of every point in round r, pruning the
        # rest with the tightened bound after each round; what is left after a few rounds
        # is evaluated at once.
        o = np.lexsort((d2, pidx))
        pidx, node, d2 = pidx[o], node[o], d2[o]
        first = np.flatnonzero(np.concatenate([[True], pidx[1:] != pidx[:-1]])) if pidx.size else pidx
        counts = np.diff(np.concatenate([first, [pidx.size]]))
        rank = np.arange(pidx.size) - np.repeat(first, counts)
        alive = np.ones(pidx.size, dtype=bool)
        for r in range(4):
            sel = alive & (rank == r)
            if not np.any(sel):
                break
            self._leaf_exact(p, pidx[sel], node[sel], ub2, prune=r > 0)
            alive &= ~sel
            alive &= d2 <= self._slack(ub2)[pidx]
        else:
            self._leaf_exact(p, pidx[alive], node[alive], ub2, prune=True)
        return np.sqrt(ub2)

    def _leaf_exact(self, p: np.ndarray, pidx: np.ndarray, leaf: np.ndarray, ub2: np.ndarray, prune: bool) -> None:
        """ub2[k] = min(ub2[k], exact d^2 to the triangles of the leaves paired with k)."""
        if pidx.size == 0:
            return
        tris = self._leaf_tris[leaf]
        pr = np.repeat(pidx, tris.shape[1])
        tr = tris.reshape(-1)
        ok = tr >= 0
        pr, tr = pr[ok], tr[ok]
        if prune:
            box = self._tri_box[tr]
            ok = self._box_d2(p[pr], box[:, :3], box[:, 3:]) <= self._slack(ub2)[pr]
            pr, tr = pr[ok], tr[ok]
        if pr.size:
            _segment_min(ub2, pr, self._pair_d2(p[pr], tr))

    def distance(self, points: np.ndarray, chunk: int = 8192, max_pairs: int = 1 << 21) -> np.ndarray:
        """Exact distance (m) from every point to the nearest triangle.

        Args:
            points: (N, 3) float32/float64.  Rows with NaN/Inf get distance NaN.
            chunk: points processed together (memory / speed trade-off).
            max_pairs: cap on (point, node) pairs held at once; a block exceeding it (points
                far from the mesh see many nodes) is split in two and retried.

        Returns:
            (N,) float64 distances.
        """
        p = np.asarray(points)
        if p.dtype not in _FLOATS:
            raise TypeError(f"points: expected a float32 or float64 array, got dtype {p.dtype}")
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"points: expected shape (N, 3), got {p.shape}")
        p = p.astype(np.float64)
        out = np.full(p.shape[0], np.nan)
        finite = np.flatnonzero(np.all(np.isfinite(p), axis=1))
        todo = [(s, min(s + chunk, finite.size)) for s in range(0, finite.size, chunk)]
        while todo:
            s0, s1 = todo.pop()
            ids = finite[s0:s1]
            r = self._query_chunk(p[ids], max_pairs)
            if r is None:
                mid = (s0 + s1) // 2
                todo.extend([(s0, mid), (mid, s1)])
                continue
            out[ids] = r
        return out

    __call__ = distance


def _group_minmax(lo: np.ndarray, hi: np.ndarray, group: np.ndarray, x: np.ndarray) -> None:
    """Per-group coordinate min / max of rows x (group sorted ascending), in place."""
    first = np.flatnonzero(np.concatenate([[True], group[1:] != group[:-1]]))
    g = group[first]
    lo[g] = np.minimum.reduceat(x, first, axis=0)
    hi[g] = np.maximum.reduceat(x, first, axis=0)


def _lexsort_rows(primary: np.ndarray, secondary: np.ndarray) -> np.ndarray:
    """Per row, the column order sorting by ``primary`` then ``secondary`` (small rows)."""
    o = np.argsort(secondary, axis=1, kind="stable")
    o2 = np.argsort(np.take_along_axis(primary, o, axis=1), axis=1, kind="stable")
    return np.take_along_axis(o, o2, axis=1)


def _rowdot(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Row-wise dot products of (M, 3) arrays (also strided column views)."""
    return x[:, 0] * y[:, 0] + x[:, 1] * y[:, 1] + x[:, 2] * y[:, 2]


def _segment_min(best: np.ndarray, idx: np.ndarray, vals: np.ndarray) -> None:
    """best[k] = min(best[k], min vals[idx == k]) for sorted or unsorted idx (in place)."""
    if np.any(np.diff(idx) < 0):
        o = np.argsort(idx, kind="stable")
        idx, vals = idx[o], vals[o]
    starts = np.flatnonzero(np.concatenate([[True], idx[1:] != idx[:-1]]))
    mins = np.minimum.reduceat(vals, starts)
    k = idx[starts]
    best[k] = np.minimum(best[k], mins)


def point_to_mesh_distance(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Exact Euclidean distance (m) from each point to a triangle mesh (its surface).

    Args:
        points: (N, 3) float32/float64, in the mesh's frame.  Rows with NaN/Inf are not
            an error: their distance is NaN.
        vertices: (V, 3) float32/float64.
        faces: (F, 3) integer vertex indices in [0, V).

    Returns:
        (N,) float64 distances, unsigned (no inside / outside notion).

    See :class:`MeshDistanceIndex` (to reuse the index over several clouds) for the method
    and the errors raised.
    """
    return MeshDistanceIndex(vertices, faces).distance(points)


@dataclass
class MeshDistanceStats:
    """Cloud-to-mesh distance summary (m) over the finite points.

    ``count`` points were measured; ``dropped`` rows had NaN/Inf coordinates and were left out.
    """

    mean: float
    median: float
    p95: float
    max: float
    rmse: float
    count: int
    dropped: int = 0

    def as_dict(self) -> Dict[str, Any]:
        return {k: getattr(self, k) for k in ("mean", "median", "p95", "max", "rmse", "count", "dropped")}


def mesh_distance_stats(points: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> MeshDistanceStats:
    """Statistics of :func:`point_to_mesh_distance` (m); non-finite point rows are dropped.

    ``p95`` is the 95th percentile (linear interpolation, ``numpy.percentile``).

    Raises:
        ValueError: no finite point (besides the input errors of point_to_mesh_distance).
    """
    d = point_to_mesh_distance(points, vertices, faces)
    ok = np.isfinite(d)
    if not np.any(ok):
        raise ValueError("mesh_distance_stats: no finite point to measure")
    e = d[ok]
    return MeshDistanceStats(mean=float(e.mean()), median=float(np.median(e)), p95=float(np.percentile(e, 95)),
                             max=float(e.max()), rmse=float(np.sqrt(np.mean(e * e))), count=int(e.size),
                             dropped=int(d.size - e.size))


# --------------------------------------------------------------------------------------
# Report helper
# --------------------------------------------------------------------------------------

def evaluate_reconstruction(estimate: TrajectoryLike, reference: TrajectoryLike, *, associate: bool = False,
                            max_difference: float = 0.02, offset: float = 0.0, with_scale: bool = False,
                            rpe_delta: float = 1, rpe_delta_unit: str = "frames", rpe_all_pairs: bool = True,
                            points: Optional[np.ndarray] = None,
                            mesh: Optional[Tuple[np.ndarray, np.ndarray]] = None) -> Dict[str, Any]:
    """ATE and RPE (and optionally cloud-to-mesh distances) as a JSON-ready dict.

    The defaults are the TUM benchmark's: ATE after rigid alignment, RPE over every pair
    (i, i + 1 frame).  ``points`` (reconstructed cloud, in the mesh's frame) and ``mesh``
    ``(vertices, faces)`` add a ``"cloud_to_mesh_m"`` entry.  All lengths are in metres,
    angles in degrees.  Keys: ``poses``, ``ate`` (:meth:`AteResult.as_dict`), ``rpe``
    (:meth:`RpeResult.as_dict`), optionally ``cloud_to_mesh_m``.
    """
    est = _as_trajectory(estimate, "estimate")
    ref = _as_trajectory(reference, "reference")
    if associate:
        est, ref = _associate(est, ref, max_difference=max_difference, offset=offset)
    ate = absolute_trajectory_error(est, ref, with_scale=with_scale)
    rpe = relative_pose_error(est, ref, delta=rpe_delta, delta_unit=rpe_delta_unit, all_pairs=rpe_all_pairs)
    out: Dict[str, Any] = {"poses": len(est), "ate": ate.as_dict(), "rpe": rpe.as_dict()}
    if (points is None) != (mesh is None):
        raise ValueError("pass both points and mesh=(vertices, faces) for the cloud-to-mesh distance, or neither")
    if points is not None and mesh is not None:
        out["cloud_to_mesh_m"] = mesh_distance_stats(points, mesh[0], mesh[1]).as_dict()
    return out

"""Camera trajectories: timestamped poses ``T_world_camera`` (camera -> world, metres; seconds) in the TUM, KITTI and
EuRoC text formats and ``evo``'s types, interpolated.  The TUM RGB-D format has one pose per line,
``timestamp tx ty tz qx qy qz qw``: the camera centre and the unit quaternion (Hamilton, scalar last) of its
orientation in the world frame.  :func:`associate_timestamps` is the package's one rule for pairing timestamp streams.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, List, Optional, Sequence, Tuple, Union

import numpy as np

from scanalign import _core
from scanalign.common.arrays import as_transform
from scanalign.io import atomic_open

__all__ = ["Trajectory", "quaternion_from_matrix", "matrix_from_quaternion", "pose_from_tum", "read_tum_trajectory",
           "write_tum_trajectory", "associate_timestamps", "TumFormatError", "read_tum_rows", "time_order"]

PathLike = Union[str, "os.PathLike[str]"]


#: Unit quaternions (..., 4) (qx, qy, qz, qw), qw >= 0, of rotation matrices (..., 3, 3).
quaternion_from_matrix = _core.evaluation.quaternions_from_rotations
#: Rotation matrices (..., 3, 3) of quaternions (..., 4) (qx, qy, qz, qw), normalised first.
matrix_from_quaternion = _core.evaluation.rotations_from_quaternions


def pose_from_tum(values: np.ndarray) -> np.ndarray:
    """4x4 poses (..., 4, 4) from TUM rows (..., 7) = (tx, ty, tz, qx, qy, qz, qw)."""
    v = np.asarray(values, dtype=np.float64)
    if v.shape[-1] != 7:
        raise ValueError(f"expected (..., 7) rows tx ty tz qx qy qz qw, got {v.shape}")
    T = np.tile(np.eye(4), v.shape[:-1] + (1, 1))
    T[..., :3, :3] = matrix_from_quaternion(v[..., 3:])
    T[..., :3, 3] = v[..., :3]
    return T


@dataclass
class Trajectory:
    """Timestamped camera poses: ``timestamps`` (N,) float64 seconds, non-decreasing, and ``poses`` (N, 4, 4) float64
    ``T_world_camera`` (camera -> world, metres)."""

    timestamps: np.ndarray
    poses: np.ndarray

    def __post_init__(self) -> None:
        self.timestamps = np.asarray(self.timestamps, dtype=np.float64).reshape(-1)
        self.poses = np.asarray(self.poses, dtype=np.float64)
        if self.poses.ndim != 3 or self.poses.shape[1:] != (4, 4):
            raise ValueError(f"poses: expected shape (N, 4, 4), got {self.poses.shape}")
        if self.poses.shape[0] != self.timestamps.shape[0]:
            raise ValueError(f"{self.timestamps.shape[0]} timestamps for {self.poses.shape[0]} poses")
        if not (np.all(np.isfinite(self.poses)) and np.all(np.isfinite(self.timestamps))):
            raise ValueError("trajectory has non-finite timestamps or poses")

    def __len__(self) -> int:
        return int(self.timestamps.shape[0])

    def __getitem__(self, index: Union[int, slice, np.ndarray]) -> "Trajectory":
        idx = np.atleast_1d(np.arange(len(self))[index])
        return Trajectory(self.timestamps[idx], self.poses[idx])

    @property
    def positions(self) -> np.ndarray:
        """(N, 3) camera centres in the world frame (m)."""
        return self.poses[:, :3, 3]

    @property
    def rotations(self) -> np.ndarray:
        """(N, 3, 3) camera orientations in the world frame."""
        return self.poses[:, :3, :3]

    def path_length(self) -> float:
        """Length of the polyline through the camera centres (m)."""
        return float(np.linalg.norm(np.diff(self.positions, axis=0), axis=1).sum()) if len(self) > 1 else 0.0

    def transformed(self, T_new_world: np.ndarray) -> "Trajectory":
        """The same trajectory in another world frame: poses ``T_new_world @ T`` (ValueError unless a finite 4x4)."""
        return Trajectory(self.timestamps.copy(), as_transform(T_new_world, "T_new_world") @ self.poses)

    def to_tum_rows(self) -> np.ndarray:
        """(N, 8) rows ``timestamp tx ty tz qx qy qz qw``."""
        return np.column_stack([self.timestamps, self.positions, quaternion_from_matrix(self.rotations)])

    @classmethod
    def from_tum_rows(cls, rows: np.ndarray) -> "Trajectory":
        """From rows ``timestamp tx ty tz qx qy qz qw`` (:meth:`to_tum_rows`)."""
        rows = np.asarray(rows, dtype=np.float64).reshape(-1, 8)
        return cls(rows[:, 0], pose_from_tum(rows[:, 1:]))

    @classmethod
    def read_tum(cls, path: PathLike) -> "Trajectory":
        """Reads a TUM trajectory file (``timestamp tx ty tz qx qy qz qw`` per line, in file order:
        :meth:`interpolate` refuses one that is not time-sorted).  TumFormatError (a ValueError)
        names the file and line without 8 finite numbers or with a zero quaternion."""
        return cls.from_tum_rows(read_tum_rows(path, 8, "8 values (timestamp tx ty tz qx qy qz qw)")[0])

    def write_tum(self, path: PathLike, header: Optional[str] = None) -> None:
        """:func:`write_tum_trajectory`."""
        write_tum_trajectory(path, self, header)

    def write_kitti(self, path: PathLike, times_path: Optional[PathLike] = None) -> None:
        """Writes the KITTI odometry format: per pose the first three rows of ``T_world_camera``, 12 numbers row-major
        (full double precision).  KITTI keeps no timestamps in it: they go to ``times_path`` (one time in seconds per
        line, KITTI's ``times.txt``) when given."""
        with atomic_open(path, "w", encoding="utf-8") as f:
            f.writelines(" ".join(f"{v:.17g}" for v in T[:3].ravel()) + "\n" for T in self.poses)
        if times_path is not None:
            with atomic_open(times_path, "w", encoding="utf-8") as f:
                f.writelines(f"{t:.17g}\n" for t in self.timestamps)

    @classmethod
    def read_kitti(cls, path: PathLike, times_path: Optional[PathLike] = None) -> "Trajectory":
        """Reads a KITTI pose file (12 numbers per line, see :meth:`write_kitti`); timestamps from ``times_path`` (one
        per line), else the frame numbers 0, 1, 2, ...  TumFormatError (a ValueError) names the file and line without
        12 finite numbers, or a times file with another number of lines."""
        values, _, _ = read_tum_rows(path, 12, "12 values (a 3x4 pose, row-major)")
        times = np.arange(len(values), dtype=np.float64)
        if times_path is not None:
            times = read_tum_rows(times_path, 1, "1 value (a time in seconds)")[0].reshape(-1)
            if len(times) != len(values):
                raise TumFormatError(f"{len(times)} times for {len(values)} poses in {os.fspath(path)}", times_path)
        poses = np.tile(np.eye(4), (len(values), 1, 1))
        poses[:, :3] = values.reshape(-1, 3, 4)
        return cls(times, poses)

    def write_euroc(self, path: PathLike) -> None:
        """Writes the EuRoC MAV ground-truth CSV: integer nanoseconds, then the position and Hamilton quaternion
        (scalar first) of the camera in the world frame."""
        whole = np.floor(self.timestamps)
        ns = [int(a) * 10**9 + int(round(b)) for a, b in zip(whole, (self.timestamps - whole) * 1e9)]
        rows = np.c_[self.positions, quaternion_from_matrix(self.rotations)[:, [3, 0, 1, 2]]]  # w x y z
        with atomic_open(path, "w", encoding="utf-8") as f:
            f.write("#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []\n")
            f.writelines(f"{t}," + ",".join(f"{v:.17g}" for v in row) + "\n" for t, row in zip(ns, rows))

    @classmethod
    def read_euroc(cls, path: PathLike) -> "Trajectory":
        """Reads a EuRoC MAV pose CSV (``vicon0/data.csv``: 8 columns, or the 17 of
        ``state_groundtruth_estimate0/data.csv``, whose velocities and biases are ignored): nanosecond timestamps,
        position, quaternion ``w x y z``.  TumFormatError (a ValueError) names the file and line of a malformed line."""
        ns, values = [], []
        for n, line in enumerate(Path(path).read_text(encoding="utf-8").splitlines(), 1):
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            parts = line.split(",")
            try:
                ns.append(int(parts[0]))
                row = [float(v) for v in parts[1:8]]
            except ValueError:
                row = []
            if len(row) != 7 or not all(map(math.isfinite, row)) or not any(row[3:]):
                raise TumFormatError(f"expected timestamp [ns], 3 position and 4 quaternion values (w x y z), got "
                                     f"{line.strip()!r}", path, n)
            values.append(row)
        values = np.array(values, dtype=np.float64).reshape(-1, 7)
        t = np.array([a // 10**9 + (a % 10**9) * 1e-9 for a in ns], dtype=np.float64)
        return cls(t, pose_from_tum(values[:, [0, 1, 2, 4, 5, 6, 3]]))

    def to_evo(self) -> Any:
        """This trajectory as an ``evo.core.trajectory.PoseTrajectory3D`` (poses and timestamps
        copied). ImportError when evo is not installed (``pip install evo``)."""
        try:
            from evo.core.trajectory import PoseTrajectory3D
        except ImportError as e:
            raise ImportError("Trajectory.to_evo needs the optional package 'evo': pip install evo") from e
        return PoseTrajectory3D(poses_se3=list(self.poses.copy()), timestamps=self.timestamps.copy())

    @classmethod
    def from_evo(cls, trajectory: Any) -> "Trajectory":
        """A Trajectory of an evo ``PoseTrajectory3D`` (its timestamps) or ``PosePath3D`` (frame
        numbers 0, 1, 2, ... as timestamps)."""
        poses = np.array(trajectory.poses_se3, dtype=np.float64).reshape(-1, 4, 4)
        times = getattr(trajectory, "timestamps", None)
        return cls(np.array(np.arange(len(poses)) if times is None else times, dtype=np.float64), poses)

    def interpolate(self, timestamps: Sequence[float], max_gap: float = np.inf) -> "Trajectory":
        """Poses at ``timestamps`` (s, within the trajectory's span): linear in position, spherical-linear in rotation.
        ValueError: a query outside the span, or between poses more than ``max_gap`` s apart (a gap in a ground truth
        is not papered over); timestamps that decrease (sort them first); a NaN or negative ``max_gap``."""
        t = np.asarray(timestamps, dtype=np.float64).reshape(-1)
        if len(self) == 0:
            raise ValueError("cannot interpolate an empty trajectory")
        ts = self.timestamps
        if np.any(np.diff(ts) < 0) or not max_gap >= 0:  # the search below needs time-sorted poses
            raise ValueError(f"interpolate needs non-decreasing timestamps and max_gap >= 0 s, got max_gap {max_gap}")
        if np.any(t < ts[0] - 1e-9) or np.any(t > ts[-1] + 1e-9):
            raise ValueError(f"query times outside the trajectory's span [{ts[0]}, {ts[-1]}]")
        hi = np.minimum(np.searchsorted(ts, t, side="left"), len(ts) - 1)
        lo = np.where(np.isclose(ts[hi], t, rtol=0, atol=1e-9), hi, np.maximum(hi - 1, 0))
        gap = ts[hi] - ts[lo]
        if np.any(gap > max_gap):
            raise ValueError(f"a query falls in a gap of {gap.max():.3f} s > max_gap {max_gap} s")
        with np.errstate(invalid="ignore", divide="ignore"):
            a = np.where(gap > 0, (t - ts[lo]) / gap, 0.0)
        return Trajectory(t, _core.evaluation.interpolate_poses(self.poses[lo], self.poses[hi], a))


class TumFormatError(ValueError):
    """A file does not follow the TUM RGB-D benchmark's formats: ``path`` is the offending file (or folder) or None,
    ``line`` the 1-based line number in it where applicable, else None."""

    def __init__(self, message: str, path: Optional[PathLike] = None, line: Optional[int] = None) -> None:
        where = "" if path is None else f"{os.fspath(path)}:{line}: " if line is not None else f"{os.fspath(path)}: "
        super().__init__(where + message)
        self.path, self.line = (None if path is None else os.fspath(path)), line


def read_tum_rows(path: PathLike, fields: int, expected: str) -> Tuple[np.ndarray, List[str], np.ndarray]:
    """The TUM benchmark's text files, one rule for all (its ``associate.py``'s): ``#`` starts a comment, blank lines
    are skipped, commas and tabs separate fields.  Every data line has ``fields`` fields: numbers, but the last is a
    name when ``expected`` starts with "'timestamp filename'".  Returns (values (N, k) float64, those names (else
    empty), 1-based line numbers (N,)).  TumFormatError, naming the file and line: not UTF-8 text, a line with another
    number of fields, a value that is not a finite number, a zero quaternion (8 fields)."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise TumFormatError(f"not a UTF-8 text file ({e})", path) from None
    named = expected.startswith("'timestamp filename'")
    values, names, lines = [], [], []
    for lineno, raw in enumerate(text.splitlines(), 1):
        parts = raw.split("#", 1)[0].replace(",", " ").split()
        if not parts:
            continue
        if len(parts) != fields:
            raise TumFormatError(f"expected {expected}, got {raw.strip()!r}", path, lineno)
        if named:
            names.append(parts.pop())
        try:
            row = [float(p) for p in parts]
        except ValueError:
            raise TumFormatError(f"not a number in {raw.strip()!r}", path, lineno) from None
        if not all(map(math.isfinite, row)):
            raise TumFormatError(f"a value is not finite in {raw.strip()!r}", path, lineno)
        if fields == 8 and not any(row[4:]):  # a trajectory row whose qx qy qz qw are all 0: no rotation
            raise TumFormatError(f"the quaternion qx qy qz qw is zero in {raw.strip()!r}", path, lineno)
        values.append(row)
        lines.append(lineno)
    return np.array(values).reshape(-1, fields - named), names, np.array(lines, dtype=np.int64)


def time_order(timestamps: np.ndarray, path: PathLike, lines: np.ndarray) -> np.ndarray:
    """The stable order sorting ``timestamps`` (recorders sometimes flush out of order); TumFormatError naming both
    lines of a timestamp that appears twice."""
    order = np.argsort(timestamps, kind="stable")
    dup = np.flatnonzero(np.diff(timestamps[order]) == 0)
    if dup.size:
        a, b = order[dup[0]], order[dup[0] + 1]
        raise TumFormatError(f"timestamp {timestamps[a]:.6f} appears twice (lines {lines[a]} and {lines[b]})",
                             path, int(lines[b]))
    return order


#: Reads a TUM trajectory file (:meth:`Trajectory.read_tum`).
read_tum_trajectory = Trajectory.read_tum


def write_tum_trajectory(path: PathLike, trajectory: Trajectory, header: Optional[str] = None) -> None:
    """Writes a trajectory in the TUM format: timestamps to the microsecond, poses in full double precision;
    ``header`` lines become ``#`` comments."""
    with atomic_open(path, "w", encoding="utf-8") as f:
        f.writelines(f"# {line}\n" for line in (header or "").splitlines())
        f.write("# timestamp tx ty tz qx qy qz qw\n")
        f.writelines(f"{r[0]:.6f} " + " ".join(f"{v:.17g}" for v in r[1:]) + "\n" for r in trajectory.to_tum_rows())


#: Pairs two timestamp streams one-to-one, closest pairs first (the package's one rule).
associate_timestamps = _core.evaluation.associate_timestamps

"""Serial 6R robots: forward kinematics and analytic inverse kinematics with conformal
geometric algebra (thesis Paper 1, Ch. 5.3; spec §4).

A :class:`Robot` is a standard Denavit-Hartenberg (DH) table with joint limits and two
fixed transforms. Frames and units (metres and radians everywhere):

- DH frame i is attached to link i; frame 0 is the DH base frame, frame 6 the flange.
  ``T_{i-1,i} = Rot_z(theta_i) Trans_z(d_i) Trans_x(a_i) Rot_x(alpha_i)`` (P1 (1)) with
  ``theta_i = q_i + theta_offset_i``, where ``q`` are the joint values the controller shows.
- ``T_base_dh0`` places DH frame 0 in the user's robot base frame and ``T_flange_tool``
  places the tool centre point in the flange frame, so
  ``T_base_tool(q) = T_base_dh0 @ T_01 @ ... @ T_56 @ T_flange_tool`` (P1 (3)).
  ``T_base_tool`` maps tool coordinates into the robot base frame.

Inverse kinematics is solved in closed form for two arm layouts (``Robot.geometry``):
``"spherical_wrist"`` (KUKA KR6 R900 sixx "Agilus" and arms of the same layout: shoulder
offset a1, elbow offset a3, spherical wrist) and ``"universal_robots"`` (three parallel
axes and an offset wrist). The joint points of the arm are intersections of CGA spheres and
planes (point pairs); an imaginary point pair (Q^2 < 0) reports the configuration as
``"unreachable"`` instead of returning wrong angles.

Every pose has up to 8 solutions, stored at a fixed index
``4*(shoulder<0) + 2*(elbow<0) + (wrist<0)`` (:meth:`IKSolutions.index`). The labels are
geometric:

- ``shoulder`` +1 ("front"): the wrist centre (KUKA ``P_w``; UR ``P_c``, the projection of
  ``P5`` onto the arm plane) lies on the side of the first joint axis that the upper arm
  points to at theta2 = 0, ``f = sign(a2) x1`` (x1: DH x axis of link 1; the +x1 side for the
  KUKA, the -x1 side for UR arms, whose a2 < 0); -1 ("back").
- ``elbow`` +1 ("up"): the elbow point ``P2`` lies above the line from the shoulder point
  ``P1`` to the wrist point (KUKA ``P_w``, UR ``P3``), seen in the arm plane with the arm
  reaching forward (towards the wrist centre); -1 ("down").
- ``wrist`` +1 ("no flip"): ``sin(theta5) > 0`` (DH angle); -1 ("flip").

Singular poses are solved with a documented free angle (``q_free``): KUKA shoulder
(wrist centre on the first axis) ``q1 = q_free[0]`` ("back": ``+ pi``); KUKA wrist
(``a_e`` parallel to ``z3``) ``q4 = q_free[3]`` ("flip": ``+ pi``); UR wrist
(``a_e`` parallel to ``z1``) ``q6 = q_free[5]`` ("flip": ``+ pi``), or the nearest q6 for
which the elbow still reaches (q6 moves the UR wrist points). At the elbow singularity (arm
stretched or folded) the two elbow labels give the same angles; at the UR shoulder
singularity (``P_c`` on the first axis) the solutions with shoulder and elbow labels both
flipped coincide. :attr:`IKSolutions.singular` names which applied, per solution (a pose
singular for one configuration is usually regular for the others).

Statuses: ``"ok"`` (reaches the pose, inside the limits), ``"outside_limits"`` (reaches the
pose, but some joint has no 2*pi multiple inside its limits), ``"unreachable"`` (a point
pair of the construction is imaginary; ``q`` is NaN), ``"invalid_input"`` (batch only: a
non-finite or non-rigid pose).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, Tuple

import numpy as np

from . import _core, se3

__all__ = [
    "Robot",
    "IKSolutions",
    "IKSolution",
    "IKBatch",
    "JointTrajectory",
    "STATUS_NAMES",
    "SINGULAR_NAMES",
    "STEP_NAMES",
    "CONFIGS",
    "BUILTIN_ROBOTS",
    "config_index",
    "kuka_kr6_r900_sixx",
    "ur3",
    "ur5",
    "ur10",
    "ur3e",
    "ur5e",
    "ur10e",
    "ur5_thesis",
]

_K = _core.kinematics

#: Status names by code (C++ ``IKStatus``): 0 ok, 1 outside_limits, 2 unreachable, 3 invalid_input.
STATUS_NAMES: Tuple[str, ...] = ("ok", "outside_limits", "unreachable", "invalid_input")
#: Singularity names by bit (C++ ``SingularBits``): 1 shoulder, 2 elbow, 4 wrist.
SINGULAR_NAMES: Tuple[str, ...] = ("shoulder", "elbow", "wrist")
#: Names of the failed construction step by code (C++ ``IKStep``): 0 none, 1 shoulder, 2 elbow.
STEP_NAMES: Tuple[str, ...] = ("", "shoulder", "elbow")
#: Names accepted by :meth:`Robot.by_name` ("agilus" is an alias of "kr6_r900_sixx").
BUILTIN_ROBOTS: Tuple[str, ...] = ("kr6_r900_sixx", "agilus", "ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e",
                                   "ur5_thesis")

_GEOMETRY = {"Unsupported": "unsupported", "SphericalWrist": "spherical_wrist",
             "UniversalRobots": "universal_robots"}

#: (8, 3) int8: the configuration (shoulder, elbow, wrist) stored at each solution index.
CONFIGS = np.array([[-1 if k & 4 else 1, -1 if k & 2 else 1, -1 if k & 1 else 1] for k in range(8)], dtype=np.int8)
CONFIGS.setflags(write=False)

_REACH_TOL = float(_K.DEFAULT_REACH_TOLERANCE)     # C++ IKOptions::reach_tolerance default
_SING_TOL = float(_K.DEFAULT_SINGULAR_TOLERANCE)   # C++ IKOptions::singular_tolerance default


def config_index(shoulder: int, elbow: int, wrist: int) -> int:
    """The fixed solution index ``4*(shoulder<0) + 2*(elbow<0) + (wrist<0)`` of a
    configuration (each label +1 or -1)."""
    for name, v in (("shoulder", shoulder), ("elbow", elbow), ("wrist", wrist)):
        if v not in (1, -1):
            raise ValueError(f"{name}: expected +1 or -1, got {v!r}")
    return 4 * (shoulder < 0) + 2 * (elbow < 0) + (wrist < 0)


# ----------------------------------------------------------------------------- validation

def _real(x: object, name: str) -> np.ndarray:
    """x as a float64 array; TypeError unless it holds real numbers (float or integer)."""
    a = np.asarray(x)
    if a.dtype.kind not in "iuf":
        raise TypeError(f"{name}: expected real numbers (a float or integer array), got dtype {a.dtype}")
    return np.ascontiguousarray(a, dtype=np.float64)


def _vector6(x: object, name: str, *, nonnegative: bool = False) -> np.ndarray:
    a = _real(x, name)
    if a.shape != (6,):
        raise ValueError(f"{name}: expected shape (6,), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: non-finite values")
    if nonnegative and np.any(a < 0):
        raise ValueError(f"{name}: values must be >= 0")
    return a


def _joints(q: object, name: str = "q") -> np.ndarray:
    """(6,) or (N, 6) finite joint values, float64."""
    a = _real(q, name)
    if a.ndim not in (1, 2) or a.shape[-1] != 6:
        raise ValueError(f"{name}: expected shape (6,) or (N, 6), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: non-finite joint values")
    return a


def _pose(T: object, name: str) -> np.ndarray:
    """One rigid 4x4 transform, float64; ValueError / TypeError naming the argument."""
    m = _real(T, name)
    if m.shape != (4, 4):
        raise ValueError(f"{name}: expected a 4x4 homogeneous transform, got shape {m.shape}")
    why = se3.rigid_problem(m)
    if why:
        raise ValueError(f"{name}: not a rigid transform: {why}")
    return m


def _poses(T: object, name: str, *, check_each: bool) -> np.ndarray:
    """(N, 4, 4) float64 poses; with check_each every pose must be rigid (ValueError naming
    the index), else bad poses are left to the C++ solver (status "invalid_input")."""
    m = _real(T, name)
    if m.ndim != 3 or m.shape[1:] != (4, 4):
        raise ValueError(f"{name}: expected an (N, 4, 4) array of poses, got shape {m.shape}")
    if check_each:
        for i in range(m.shape[0]):
            why = se3.rigid_problem(m[i])
            if why:
                raise ValueError(f"{name}[{i}]: not a rigid transform: {why}")
    return m


def _readonly(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


def _singular_names(bits: int) -> Tuple[str, ...]:
    return tuple(n for i, n in enumerate(SINGULAR_NAMES) if int(bits) >> i & 1)


# Lookup tables: results are built from the C++ codes without per-element numpy work
# (single-pose calls are dominated by Python overhead, not by the ~2 µs solve).
_SINGULAR_TABLE = tuple(_singular_names(b) for b in range(8))


def _pose_fast(T: object, name: str) -> np.ndarray:
    """A 4x4 float64 array for a single-pose call. Rigidity is checked by the C++ solver
    (status "invalid_input"); :func:`_explain_invalid` then says why."""
    m = T if isinstance(T, np.ndarray) and T.dtype == np.float64 and T.flags.c_contiguous else _real(T, name)
    if m.shape != (4, 4):
        raise ValueError(f"{name}: expected a 4x4 homogeneous transform, got shape {m.shape}")
    return m


def _explain_invalid(T: np.ndarray, name: str) -> None:
    """Raises the ValueError for a pose the C++ solver rejected as invalid."""
    why = se3.rigid_problem(T) or "rejected by the solver"
    raise ValueError(f"{name}: not a rigid transform: {why}")


# ----------------------------------------------------------------------------- results

@dataclass(frozen=True)
class IKSolutions:
    """All inverse-kinematics solutions of one pose (:meth:`Robot.ik`).

    Row k holds the configuration ``CONFIGS[k]``, i.e. ``k = 4*(shoulder<0) +
    2*(elbow<0) + (wrist<0)`` (:meth:`index`), whatever the pose.

    Attributes:
        q: (8, 6) joint values, rad. Each joint is the 2*pi multiple inside its limits that
            is nearest 0 (``respect_limits=True``) or wrapped to (-pi, pi]; NaN rows where
            the configuration is unreachable.
        status: 8 statuses from ``"ok"``, ``"outside_limits"``, ``"unreachable"``,
            ``"invalid_input"``.
        config: (8, 3) int8 labels (shoulder, elbow, wrist), each +1 or -1.
        singular: 8 tuples of the singularities that applied (``"shoulder"``, ``"elbow"``,
            ``"wrist"``); empty for a regular solution.
        unreachable_step: 8 strings: ``""``, or the construction step whose point pair is
            imaginary (``"shoulder"``: UR horizon, the wrist point within d4 of the first
            axis; ``"elbow"``: the wrist too far from or too close to the shoulder).

    ``len(solutions)`` is the number of ``"ok"`` rows (so an empty result is falsy).
    """

    q: np.ndarray
    status: Tuple[str, ...]
    config: np.ndarray
    singular: Tuple[Tuple[str, ...], ...]
    unreachable_step: Tuple[str, ...]

    @property
    def ok(self) -> np.ndarray:
        """(8,) bool: rows with status ``"ok"``."""
        return np.array([s == "ok" for s in self.status], dtype=bool)

    def __len__(self) -> int:
        return int(np.count_nonzero(self.ok))

    def valid_q(self) -> np.ndarray:
        """(K, 6) joint values of the ``"ok"`` rows, in index order, rad."""
        return self.q[self.ok].copy()

    def distinct(self, tol: float = 1e-9) -> np.ndarray:
        """(M, 6) ``"ok"`` rows with duplicates removed: two rows are equal when every joint
        differs by a multiple of 2*pi within ``tol`` rad (e.g. both elbow labels at the elbow
        singularity). The first row of each group is kept."""
        out: list = []
        for row in self.q[self.ok]:
            if not any(np.max(np.abs(_wrap(row - r))) <= tol for r in out):
                out.append(row)
        return np.array(out, dtype=np.float64).reshape(-1, 6)

    @staticmethod
    def index(shoulder: int, elbow: int, wrist: int) -> int:
        """Row of the configuration (shoulder, elbow, wrist): see :func:`config_index`."""
        return config_index(shoulder, elbow, wrist)

    def __repr__(self) -> str:
        rows = ", ".join(f"{tuple(int(c) for c in self.config[k])}: {self.status[k]}" for k in range(8))
        return f"IKSolutions({len(self)} ok; {rows})"


@dataclass(frozen=True)
class IKSolution:
    """One inverse-kinematics solution (:meth:`Robot.ik_closest`).

    Attributes:
        q: (6,) joint values, rad (NaN unless a solution with status ``"ok"`` exists).
        status: ``"ok"``, or why no solution exists: ``"outside_limits"``,
            ``"unreachable"``, ``"invalid_input"``.
        config: (3,) int8 labels (shoulder, elbow, wrist).
        singular: the singularities that applied (names, see :class:`IKSolutions`).
        ok: ``status == "ok"``.
        unreachable_step: ``""``, ``"shoulder"`` or ``"elbow"`` (see :class:`IKSolutions`).
    """

    q: np.ndarray
    status: str
    config: np.ndarray
    singular: Tuple[str, ...]
    ok: bool
    unreachable_step: str = ""


@dataclass(frozen=True)
class IKBatch:
    """Inverse kinematics of N poses (:meth:`Robot.ik_batch`), as arrays.

    Attributes:
        q: (N, 8, 6) joint values, rad; ``q[i, k]`` has configuration ``CONFIGS[k]``; NaN
            where not reached.
        status: (N, 8) uint8 status codes, indices into :data:`STATUS_NAMES`
            (0 ok, 1 outside_limits, 2 unreachable, 3 invalid_input).
        singular: (N, 8) uint8 singularity bits (1 shoulder, 2 elbow, 4 wrist).
        unreachable_step: (N, 8) uint8 (0 none, 1 shoulder, 2 elbow).
    """

    q: np.ndarray
    status: np.ndarray
    singular: np.ndarray
    unreachable_step: np.ndarray

    @property
    def ok(self) -> np.ndarray:
        """(N, 8) bool: status ``"ok"``."""
        return self.status == 0

    @property
    def count_ok(self) -> np.ndarray:
        """(N,) number of ``"ok"`` solutions per pose."""
        return np.count_nonzero(self.ok, axis=1)

    def status_names(self) -> np.ndarray:
        """(N, 8) array of status names (str)."""
        return np.asarray(STATUS_NAMES)[self.status]

    def __len__(self) -> int:
        return int(self.q.shape[0])

    def solutions(self, i: int) -> IKSolutions:
        """The solutions of pose i as an :class:`IKSolutions`."""
        return IKSolutions(
            q=_readonly(self.q[i].copy()),
            status=tuple(STATUS_NAMES[s] for s in self.status[i]),
            config=CONFIGS,
            singular=tuple(_singular_names(b) for b in self.singular[i]),
            unreachable_step=tuple(STEP_NAMES[s] for s in self.unreachable_step[i]),
        )


@dataclass(frozen=True)
class JointTrajectory:
    """Joint values along a pose sequence (:meth:`Robot.ik_trajectory`).

    Attributes:
        q: (N, 6) joint values, rad; NaN rows where no ``"ok"`` solution exists.
        status: N statuses (``"ok"``, ``"outside_limits"``, ``"unreachable"``, ...).
    """

    q: np.ndarray
    status: Tuple[str, ...]

    @property
    def ok(self) -> np.ndarray:
        """(N,) bool: steps with status ``"ok"``."""
        return np.array([s == "ok" for s in self.status], dtype=bool)

    def __len__(self) -> int:
        return int(self.q.shape[0])


def _wrap(x: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(x) + np.pi) % (2 * np.pi) - np.pi


_CONFIGS_RO = CONFIGS  # read-only; identical for every pose (solution k has configuration k)


def _solution(d: dict) -> IKSolution:
    status = STATUS_NAMES[d["status"]]
    return IKSolution(q=_readonly(np.asarray(d["q"], dtype=np.float64)), status=status,
                      config=_readonly(np.array(d["config"], dtype=np.int8)),
                      singular=_SINGULAR_TABLE[d["singular"]], ok=status == "ok",
                      unreachable_step=STEP_NAMES[d["step"]])


_INVALID = 3  # IKStatus::InvalidInput
_ZEROS6 = _readonly(np.zeros(6))
_ONES6 = _readonly(np.ones(6))


# ----------------------------------------------------------------------------- robot

class Robot:
    """A serial 6R arm: DH table (metres, radians), joint limits, base and tool transforms.

    Create one with :meth:`from_dh`, :meth:`by_name` or the module functions
    (:func:`kuka_kr6_r900_sixx`, :func:`ur5`, ...). A value object: :meth:`with_tool` and
    :meth:`with_base` return modified copies.
    """

    __slots__ = ("_r", "_geometry")

    def __init__(self, core: "_K.Robot") -> None:
        """Wraps a ``scanalign._core.kinematics.Robot`` (use the constructors above)."""
        if not isinstance(core, _K.Robot):
            raise TypeError("Robot(core): expected a scanalign._core.kinematics.Robot; "
                            "use Robot.from_dh or Robot.by_name")
        self._r = core
        self._geometry = _GEOMETRY[core.geometry().name]  # the wrapped table is never mutated

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_dh(cls, a: object, alpha: object, d: object, theta_offset: object = None, limits: object = None,
                name: str = "custom", T_base_dh0: object = None, T_flange_tool: object = None) -> "Robot":
        """A robot from its standard DH table.

        Args:
            a: (6,) link lengths a_i along x_i, metres (may be negative, as in UR's tables).
            alpha: (6,) link twists about x_i, rad.
            d: (6,) link offsets d_i along z_{i-1}, metres.
            theta_offset: (6,) DH ``theta_i = q_i + theta_offset_i``, rad; default zeros.
            limits: (6, 2) ``[q_min, q_max]`` per joint, rad (``-inf`` / ``inf`` allowed);
                default ``[-pi, pi]`` for every joint (no restriction).
            name: a label.
            T_base_dh0: 4x4 rigid transform, DH frame 0 -> robot base frame; default identity.
            T_flange_tool: 4x4 rigid transform, tool -> flange (DH frame 6); default identity.

        Raises:
            TypeError: non-numeric arrays. ValueError: wrong shapes, non-finite DH values,
            NaN limits or ``q_min > q_max``, non-rigid transforms.
        """
        cols = []
        for nm, v in (("a", a), ("alpha", alpha), ("d", d),
                      ("theta_offset", np.zeros(6) if theta_offset is None else theta_offset)):
            cols.append(_vector6(v, nm))
        if limits is None:
            lim = np.tile([-np.pi, np.pi], (6, 1))
        else:
            lim = _real(limits, "limits")
            if lim.shape != (6, 2):
                raise ValueError(f"limits: expected shape (6, 2), got {lim.shape}")
            if np.any(np.isnan(lim)) or np.any(lim[:, 0] > lim[:, 1]):
                raise ValueError("limits: expected [q_min, q_max] rows with q_min <= q_max (no NaN)")
        r = _K.Robot()
        r.name = str(name)
        r.dh = np.stack(cols, axis=1)
        r.limits = np.ascontiguousarray(lim)
        r.T_base_dh0 = np.eye(4) if T_base_dh0 is None else _pose(T_base_dh0, "T_base_dh0")
        r.T_flange_tool = np.eye(4) if T_flange_tool is None else _pose(T_flange_tool, "T_flange_tool")
        return cls(r)

    @classmethod
    def by_name(cls, name: str) -> "Robot":
        """A built-in robot: one of :data:`BUILTIN_ROBOTS` ("kr6_r900_sixx" / "agilus",
        "ur3", "ur5", "ur10", "ur3e", "ur5e", "ur10e", "ur5_thesis")."""
        if name not in BUILTIN_ROBOTS:
            raise ValueError(f"unknown robot {name!r}; built-in robots: {', '.join(BUILTIN_ROBOTS)}")
        return cls(_K.Robot.by_name(name))

    def _copy(self) -> "_K.Robot":
        r = _K.Robot()
        r.name = self._r.name
        r.dh = self._r.dh
        r.limits = self._r.limits
        r.T_base_dh0 = self._r.T_base_dh0
        r.T_flange_tool = self._r.T_flange_tool
        return r

    def with_tool(self, T_flange_tool: object) -> "Robot":
        """A copy with the tool centre point at ``T_flange_tool`` (4x4 rigid, tool -> flange)."""
        r = self._copy()
        r.T_flange_tool = _pose(T_flange_tool, "T_flange_tool")
        return Robot(r)

    def with_base(self, T_base_dh0: object) -> "Robot":
        """A copy with DH frame 0 placed at ``T_base_dh0`` (4x4 rigid, DH frame 0 -> base)."""
        r = self._copy()
        r.T_base_dh0 = _pose(T_base_dh0, "T_base_dh0")
        return Robot(r)

    # ------------------------------------------------------------------ properties
    @property
    def name(self) -> str:
        return self._r.name

    @property
    def dh(self) -> np.ndarray:
        """(6, 4) DH table, one row per joint: ``[a (m), alpha (rad), d (m), theta_offset (rad)]``."""
        return _readonly(np.array(self._r.dh, dtype=np.float64))

    @property
    def a(self) -> np.ndarray:
        """(6,) link lengths, metres."""
        return _readonly(self.dh[:, 0].copy())

    @property
    def alpha(self) -> np.ndarray:
        """(6,) link twists, rad."""
        return _readonly(self.dh[:, 1].copy())

    @property
    def d(self) -> np.ndarray:
        """(6,) link offsets, metres."""
        return _readonly(self.dh[:, 2].copy())

    @property
    def theta_offset(self) -> np.ndarray:
        """(6,) DH angle offsets, ``theta = q + theta_offset``, rad."""
        return _readonly(self.dh[:, 3].copy())

    @property
    def limits(self) -> np.ndarray:
        """(6, 2) joint limits ``[q_min, q_max]``, rad."""
        return _readonly(np.array(self._r.limits, dtype=np.float64))

    @property
    def T_base_dh0(self) -> np.ndarray:
        """4x4: DH frame 0 -> robot base frame."""
        return _readonly(np.array(self._r.T_base_dh0, dtype=np.float64))

    @property
    def T_flange_tool(self) -> np.ndarray:
        """4x4: tool -> flange (DH frame 6)."""
        return _readonly(np.array(self._r.T_flange_tool, dtype=np.float64))

    @property
    def geometry(self) -> str:
        """Which analytic solver applies: ``"spherical_wrist"`` (KUKA layout),
        ``"universal_robots"`` or ``"unsupported"`` (forward kinematics only)."""
        return self._geometry

    def __repr__(self) -> str:
        extra = ""
        if not np.array_equal(self.T_base_dh0, np.eye(4)):
            extra += ", T_base_dh0=<set>"
        if not np.array_equal(self.T_flange_tool, np.eye(4)):
            extra += ", T_flange_tool=<set>"
        return f"Robot(name={self.name!r}, geometry={self.geometry!r}{extra})"

    # ------------------------------------------------------------------ forward kinematics
    def fk(self, q: object, *, num_threads: int = 0) -> np.ndarray:
        """Forward kinematics ``T_base_tool(q)`` (P1 (3)).

        Args:
            q: (6,) joint values, rad, or (N, 6) for N configurations (batched in C++,
                parallel with ``num_threads``, 0 = all cores).

        Returns:
            (4, 4) or (N, 4, 4) ``T_base_tool``: tool -> robot base, metres.
        """
        if type(q) is np.ndarray and q.shape == (6,) and q.dtype == np.float64:
            return self._r.forward(q)  # hot path; the binding rejects non-finite values
        a = _joints(q)
        if a.ndim == 1:
            return np.asarray(self._r.forward(a))
        return np.asarray(self._r.forward_batch(a, int(num_threads)))

    def fk_flange(self, q: object) -> np.ndarray:
        """``T_base_flange(q)`` (4, 4): like :meth:`fk` without the tool transform; q (6,) rad."""
        return np.asarray(self._r.forward_flange(_vector6(q, "q")))

    def joint_frames(self, q: object) -> np.ndarray:
        """(7, 4, 4) ``T_dh0_i`` for i = 0..6 in DH frame 0 (``[0]`` identity, ``[6]`` the
        flange; without ``T_base_dh0`` and the tool); q (6,) rad."""
        return np.asarray(self._r.joint_frames(_vector6(q, "q")))

    def within_limits(self, q: object, tol: float = 0.0) -> "bool | np.ndarray":
        """Whether every joint lies in ``[q_min - tol, q_max + tol]`` (rad): a bool for
        q (6,), an (N,) bool array for q (N, 6)."""
        a = _joints(q)
        lim = self.limits
        inside = np.all((a >= lim[:, 0] - tol) & (a <= lim[:, 1] + tol), axis=-1)
        return bool(inside) if a.ndim == 1 else inside

    # ------------------------------------------------------------------ inverse kinematics
    def _require_ik(self) -> None:
        if self.geometry == "unsupported":
            raise ValueError(
                f"robot {self.name!r}: analytic IK covers two DH layouts only: 'spherical_wrist' "
                "(KUKA type: alpha = (-pi/2, 0, -pi/2, pi/2, -pi/2, 0), d2 = d3 = d5 = 0, "
                "a4 = a5 = a6 = 0, a2 > 0, d4 > 0) and 'universal_robots' (alpha = (pi/2, 0, 0, pi/2, "
                "-pi/2, 0), a1 = a4 = a5 = a6 = 0, d2 = d3 = 0, a2, a3 != 0, d4, d5 > 0); "
                "this DH table is neither (forward kinematics still works)")

    def ik(self, T_base_tool: object, q_free: object = None, respect_limits: bool = True, *,
           reach_tolerance: float = _REACH_TOL, singular_tolerance: float = _SING_TOL) -> IKSolutions:
        """All (up to 8) inverse-kinematics solutions of a tool pose.

        Args:
            T_base_tool: 4x4 rigid transform, tool -> robot base (metres).
            q_free: (6,) free angles used at singularities, rad (``q_free[0]`` KUKA shoulder,
                ``q_free[3]`` KUKA wrist, ``q_free[5]`` UR wrist); default zeros.
            respect_limits: report solutions with no 2*pi multiple inside the limits as
                ``"outside_limits"`` (True), or ignore the limits and wrap to (-pi, pi].
            reach_tolerance: a point pair whose normalised discriminant h^2/r^2 is
                ``>= -reach_tolerance`` counts as real (``<= reach_tolerance``: tangent).
            singular_tolerance: sine of the axis angle below which a wrist / KUKA shoulder
                counts as singular.

        Returns:
            :class:`IKSolutions`.

        Raises:
            TypeError / ValueError: bad arguments (shape, dtype, non-finite, non-rigid pose);
            ValueError: a robot whose geometry is ``"unsupported"``.
        """
        self._require_ik()
        T = _pose_fast(T_base_tool, "T_base_tool")
        qf = _ZEROS6 if q_free is None else _vector6(q_free, "q_free")
        q, codes, overall = _K.ik_tuple(self._r, T, qf, float(reach_tolerance), float(singular_tolerance),
                                        bool(respect_limits))
        if overall == _INVALID:
            _explain_invalid(T, "T_base_tool")
        q.setflags(write=False)
        c = codes.tolist()
        return IKSolutions(q=q, status=tuple(STATUS_NAMES[x[0]] for x in c), config=_CONFIGS_RO,
                           singular=tuple(_SINGULAR_TABLE[x[1]] for x in c),
                           unreachable_step=tuple(STEP_NAMES[x[2]] for x in c))

    def ik_closest(self, T_base_tool: object, q_current: object, weights: object = None,
                   respect_limits: bool = True, *, reach_tolerance: float = _REACH_TOL,
                   singular_tolerance: float = _SING_TOL) -> IKSolution:
        """The solution nearest to ``q_current`` in ``sum_i w_i (q_i - q_current_i)^2``, over
        every ``"ok"`` solution and every 2*pi multiple of each joint inside the limits (so
        a joint with +-2*pi limits stays near ``q_current`` instead of being wrapped).
        Singular free angles are taken from ``q_current``.

        Args:
            T_base_tool: 4x4 rigid transform, tool -> robot base (metres).
            q_current: (6,) current joints, rad.
            weights: (6,) non-negative joint weights; default ones.
            respect_limits, reach_tolerance, singular_tolerance: as in :meth:`ik`.

        Returns:
            :class:`IKSolution`; when no solution is ``"ok"``, its status says why
            (``"outside_limits"`` or ``"unreachable"``) and q is NaN.
        """
        self._require_ik()
        T = _pose_fast(T_base_tool, "T_base_tool")
        qc = _vector6(q_current, "q_current")
        w = _ONES6 if weights is None else _vector6(weights, "weights", nonnegative=True)
        d = _K.ik_closest(self._r, T, qc, w, float(reach_tolerance), float(singular_tolerance), bool(respect_limits))
        if d["status"] == _INVALID:
            _explain_invalid(T, "T_base_tool")
        return _solution(d)

    def ik_batch(self, T_base_tool: object, q_free: object = None, respect_limits: bool = True,
                 num_threads: int = 0, *, reach_tolerance: float = _REACH_TOL,
                 singular_tolerance: float = _SING_TOL) -> IKBatch:
        """:meth:`ik` for N poses in one C++ call (parallel over poses).

        Args:
            T_base_tool: (N, 4, 4) tool -> robot base transforms (metres). A non-finite or
                non-rigid pose does not raise: its 8 solutions get status ``"invalid_input"``.
            q_free, respect_limits, reach_tolerance, singular_tolerance: as in :meth:`ik`.
            num_threads: OpenMP threads, 0 = all cores, 1 = serial.

        Returns:
            :class:`IKBatch`.
        """
        self._require_ik()
        T = _poses(T_base_tool, "T_base_tool", check_each=False)
        qf = np.zeros(6) if q_free is None else _vector6(q_free, "q_free")
        d = _K.ik_batch(robot=self._r, poses=T, q_free=qf, reach_tolerance=float(reach_tolerance),
                        singular_tolerance=float(singular_tolerance), respect_limits=bool(respect_limits),
                        num_threads=int(num_threads))
        return IKBatch(q=np.asarray(d["q"]), status=np.asarray(d["status"]), singular=np.asarray(d["singular"]),
                       unreachable_step=np.asarray(d["step"]))

    def ik_trajectory(self, T_base_tool: object, q_start: object, weights: object = None,
                      respect_limits: bool = True, *, reach_tolerance: float = _REACH_TOL,
                      singular_tolerance: float = _SING_TOL) -> JointTrajectory:
        """Joint values along a sequence of poses: each step takes the solution closest
        (:meth:`ik_closest`) to the previous step's joints, the first to ``q_start``. A step
        without an ``"ok"`` solution gets a NaN row and its status; the next step starts
        again from the last good joints.

        Args:
            T_base_tool: (N, 4, 4) rigid tool -> robot base transforms (metres).
            q_start: (6,) joints before the first pose, rad.
            weights: (6,) non-negative joint weights; default ones.

        Returns:
            :class:`JointTrajectory`.
        """
        self._require_ik()
        T = _poses(T_base_tool, "T_base_tool", check_each=True)
        qs = _vector6(q_start, "q_start")
        w = np.ones(6) if weights is None else _vector6(weights, "weights", nonnegative=True)
        d = _K.ik_trajectory(robot=self._r, poses=T, q_start=qs, weights=w, reach_tolerance=float(reach_tolerance),
                             singular_tolerance=float(singular_tolerance), respect_limits=bool(respect_limits))
        return JointTrajectory(q=np.asarray(d["q"]), status=tuple(STATUS_NAMES[int(s)] for s in d["status"]))

    def ik_construction(self, T_base_tool: object, shoulder: int = 1, elbow: int = 1, wrist: int = 1,
                        q_free: object = None) -> Dict[str, object]:
        """The intermediate CGA construction of one configuration (for inspection, plots and
        tests against an independent CGA implementation).

        Returns:
            dict with ``"points"`` (name -> (3,) point in DH frame 0, metres; KUKA: ``p_e``,
            ``P_w``, ``P1``, ``P2``, ``P_wx``; UR: ``p_e``, ``P5``, ``P_c``, ``P4``, ``P3``,
            ``P2``, ``P1``), ``"shoulder_discriminant"`` (UR horizon) and
            ``"elbow_discriminant"`` (normalised h^2/r^2 of the point pairs: negative means
            imaginary, Q^2 < 0; NaN when not computed), ``"solution"`` (:class:`IKSolution`,
            limits respected) and ``"config"`` ((shoulder, elbow, wrist)).
        """
        config_index(shoulder, elbow, wrist)
        self._require_ik()
        T = _pose(T_base_tool, "T_base_tool")
        qf = np.zeros(6) if q_free is None else _vector6(q_free, "q_free")
        d = _K.ik_construction(robot=self._r, T=T, shoulder=int(shoulder), elbow=int(elbow), wrist=int(wrist),
                               q_free=qf, reach_tolerance=_REACH_TOL, singular_tolerance=_SING_TOL)
        return {
            "points": {str(k): np.asarray(v, dtype=np.float64) for k, v in d["points"].items()},
            "shoulder_discriminant": float(d["shoulder_discriminant"]),
            "elbow_discriminant": float(d["elbow_discriminant"]),
            "solution": _solution(d["solution"]),
            "config": (int(shoulder), int(elbow), int(wrist)),
        }


# ----------------------------------------------------------------------------- built-ins

def kuka_kr6_r900_sixx() -> Robot:
    """KUKA KR6 R900 sixx ("Agilus"): the thesis authors' DH table (spec §4.1), q = KUKA's
    axis values A1..A6; home q = (0, -pi/2, pi/2, 0, 0, 0) puts the flange at
    (0.525, 0, 0.890) m pointing along +x. Limits from KUKA's data sheet."""
    return Robot.by_name("kr6_r900_sixx")


def ur3() -> Robot:
    """Universal Robots UR3 (CB series), UR's published DH table, limits +-2*pi."""
    return Robot.by_name("ur3")


def ur5() -> Robot:
    """Universal Robots UR5 (CB series), UR's published DH table, limits +-2*pi."""
    return Robot.by_name("ur5")


def ur10() -> Robot:
    """Universal Robots UR10 (CB series), UR's published DH table, limits +-2*pi."""
    return Robot.by_name("ur10")


def ur3e() -> Robot:
    """Universal Robots UR3e, UR's published DH table, limits +-2*pi."""
    return Robot.by_name("ur3e")


def ur5e() -> Robot:
    """Universal Robots UR5e, UR's published DH table, limits +-2*pi."""
    return Robot.by_name("ur5e")


def ur10e() -> Robot:
    """Universal Robots UR10e, UR's published DH table, limits +-2*pi."""
    return Robot.by_name("ur10e")


def ur5_thesis() -> Robot:
    """The UR5 with the numbers printed in the thesis (Table 2), for reproducing spec
    claim 23: q = 0 puts the flange at (-0.81743, -0.19145, -0.00545) m."""
    return Robot.by_name("ur5_thesis")
